"""The tolerance report: ``report.html`` (self-contained), ``report.md`` and ``report.json``.

Units: lengths in mm, angles in rad; residuals printed in um.

:func:`write_report` lays out the document of :func:`hyperstat.solver.export.report_content.report_document`:
the HTML inlines its images (base64 PNG: pyvista views of the skeleton with markers
coloured by verdict, residual plots) and its style, loads nothing from the network,
reads on a projector (large type, high contrast) and prints on A4 (print CSS, page
breaks between sections).  Constraint equations are MathML from sympy.  The same inputs
give byte-identical files: no timestamps, sorted JSON keys.
"""

from __future__ import annotations

import base64
import html
import json
import tempfile
from pathlib import Path

from hyperstat.solver.atomic import dumps_json, write_bytes, write_text
from hyperstat.solver.export.report_content import TOLERANCE_CLASSES

__all__ = ["write_report", "render_html", "render_markdown", "SECTIONS"]

SECTIONS = ("summary", "skeleton", "joints", "constraints", "hypotheses", "accuracy", "identification", "diagnosis")

CLASS_COLORS = {
    "forced": "#d1007a",
    "coupled": "#e67e00",
    "compensable": "#0097a7",
    "accuracy-critical": "#c62828",
    "non-influent": "#8a8a8a",
    "gauge": "#bdbdbd",
}

CSS = """
body { font-family: "DejaVu Sans", Arial, sans-serif; font-size: 18px; color: #111; margin: 2em auto;
       max-width: 1200px; line-height: 1.4; }
h1 { font-size: 2em; border-bottom: 4px solid #111; } h2 { font-size: 1.5em; margin-top: 1.6em;
       border-bottom: 2px solid #999; }
table { border-collapse: collapse; margin: .6em 0; } th, td { border: 1px solid #999; padding: .2em .5em; }
th { background: #eee; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
.badge { display: inline-block; padding: .05em .5em; border-radius: .6em; color: white; font-weight: bold; }
.cards { display: flex; flex-wrap: wrap; gap: .8em; } .card { border: 2px solid #111; border-radius: .4em;
       padding: .4em .8em; min-width: 9em; } .card b { font-size: 1.8em; display: block; }
img { max-width: 100%; border: 1px solid #ccc; } .note { color: #444; font-size: .9em; }
@media print {
  @page { size: A4; margin: 15mm; }
  body { font-size: 10pt; max-width: none; margin: 0; }
  h2 { page-break-before: always; } section#summary h2 { page-break-before: avoid; }
  table, img { page-break-inside: avoid; }
}
"""


def _badge(cls: str) -> str:
    return f'<span class="badge" style="background:{CLASS_COLORS.get(cls, "#555")}">{html.escape(cls)}</span>'


def _img(png: bytes, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode()}">'


def _um(v) -> str:
    return "-" if v is None else f"{1000 * v:.1f}"


def render_html(doc: dict, images: dict) -> str:
    """The report as one self-contained HTML page."""
    s = doc["summary"]
    e = html.escape
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           f"<title>hyperstat tolerance report: {e(doc['mechanism'])}</title>", f"<style>{CSS}</style></head><body>",
           f"<h1>Tolerance report: {e(doc['mechanism'])}</h1>",
           f"<p class=\"note\">Source: {e(str(doc['source'].get('source', '')))} ({e(str(doc['source'].get('kind', '')))})."
           " Lengths in mm, angles in rad, residuals in &micro;m.</p>"]
    # summary
    out.append('<section id="summary"><h2>Summary</h2><div class="cards">')
    out.append(f'<div class="card"><b>{s["parameters"]}</b>defect parameters</div>')
    out.append(f'<div class="card"><b>{s["mobility"]}</b>mobility</div>')
    out.append(f'<div class="card"><b>{s["overconstraint"]}</b>degree of over-constraint</div>')
    for cls, n in s["tolerance_classes"].items():
        out.append(f'<div class="card" style="border-color:{CLASS_COLORS[cls]}"><b>{n}</b>{e(cls)}</div>')
    out.append("</div><table><tr><th>class</th><th>meaning</th><th>parameters</th></tr>")
    for cls, meaning in TOLERANCE_CLASSES.items():
        names = [p["name"] for j in doc["joints"] for p in j["parameters"] if p["class"] == cls]
        out.append(f"<tr><td>{_badge(cls)}</td><td>{e(meaning)}</td><td>{e(', '.join(names)) or '-'}</td></tr>")
    out.append("</table>")
    gap = s["singular_value_gap"]
    out.append(f"<p>Constraint rank {s['rank']}, singular-value gap "
               f"{'none (full rank)' if gap is None or gap == float('inf') else f'{gap:.3g}'}"
               + (f"; {s['verified']['confirmed']} of {s['verified']['total']} verdicts confirmed by nonlinear "
                  f"re-assembly" if s["verified"] else "") + ".</p></section>")
    # skeleton
    out.append('<section id="skeleton"><h2>Skeleton and verdicts</h2>')
    if "views" in images:
        out.append(_img(images["views"], "skeleton views coloured by verdict"))
    out.append('<p class="note">Markers: magenta forced, orange coupled, cyan free and influential, grey free and '
               "non-influent, white gauge only.</p></section>")
    # joints
    out.append('<section id="joints"><h2>Defects per joint</h2><table><tr><th>joint</th><th>type</th><th>role</th>'
               "<th>parameter</th><th>unit</th><th>verdict</th><th>class</th><th>nonlinear check</th></tr>")
    for j in doc["joints"]:
        for k, p in enumerate(j["parameters"]):
            check = p.get("check")
            ctext = "-" if not check else ("confirmed" if check["confirmed"] else "NOT confirmed") + \
                f" ({check['residual_mm']:.2g} mm)"
            head = (f"<td rowspan=\"{len(j['parameters'])}\">{e(j['element'])}</td><td rowspan=\"{len(j['parameters'])}\">"
                    f"{e(j['type'])}</td><td rowspan=\"{len(j['parameters'])}\">{e(j['role'])}</td>") if k == 0 else ""
            out.append(f"<tr>{head}<td>{e(p['name'])}</td><td>{e(p['unit'])}</td><td>{e(p['verdict'])}</td>"
                       f"<td>{_badge(p['class'])}</td><td>{e(ctext)}</td></tr>")
    out.append("</table></section>")
    # constraints
    out.append('<section id="constraints"><h2>Constraint equations</h2>')
    if doc["forced"]:
        out.append("<p>Forced to zero: " + ", ".join(f"<math><mi>{e(n)}</mi><mo>=</mo><mn>0</mn></math>"
                                                     for n in doc["forced"]) + "</p>")
    else:
        out.append("<p>No defect is forced: the mechanism is not over-constrained.</p>")
    for r in doc["relations"]:
        out.append(f"<p>{r['mathml']}</p>")
    out.append("</section>")
    # hypotheses
    out.append('<section id="hypotheses"><h2>Design hypotheses</h2>')
    if doc["hypotheses"]:
        out.append("<table><tr><th>hypothesis</th><th>verdict</th><th>why</th></tr>")
        for h in doc["hypotheses"]:
            out.append(f"<tr><td>{e(h['id'])}</td><td>{e(h['verdict'])}</td><td>{e(h['reason'])}</td></tr>")
        out.append("</table>")
    else:
        out.append("<p>No hypothesis file was given.</p>")
    out.append("</section>")
    # accuracy
    out.append('<section id="accuracy"><h2>Accuracy and tolerances</h2>')
    acc = doc.get("accuracy")
    if acc:
        coeffs = acc.get("coefficients", {})
        if coeffs:
            out.append("<table><tr><th>coefficient</th><th>min</th><th>mean</th><th>max</th></tr>")
            for name, v in coeffs.items():
                out.append(f"<tr><td>{e(name)}</td><td class=num>{v['min']:.4g}</td><td class=num>{v['mean']:.4g}</td>"
                           f"<td class=num>{v['max']:.4g}</td></tr>")
            out.append("</table>")
        alloc = acc.get("allocation")
        if alloc:
            out.append("<pre>" + e(json.dumps(alloc, indent=1, sort_keys=True)[:4000]) + "</pre>")
        for name in ("accuracy_map", "contributors"):
            if name in images:
                out.append(_img(images[name], name))
    else:
        out.append("<p>Accuracy coefficients were not computed for this report.</p>")
    out.append("</section>")
    # identification
    out.append('<section id="identification"><h2>Identification</h2>')
    ident = doc["identification"]
    if ident:
        out.append(f"<p>Rank {ident['rank']} of {ident['unknowns']} unknowns, condition number "
                   f"{ident['condition_number']:.3g}.</p><table><tr><th></th><th>mean</th><th>max</th><th>RMS</th></tr>")
        for key in ("identification", "validation"):
            v = ident.get(key)
            if v:
                out.append(f"<tr><td>{key}</td><td class=num>{_um(v['mean'])}</td><td class=num>{_um(v['max'])}</td>"
                           f"<td class=num>{_um(v['rms'])}</td></tr>")
        if ident.get("noise_rms"):
            out.append(f"<tr><td>noise floor</td><td></td><td></td><td class=num>{_um(ident['noise_rms'])}</td></tr>")
        out.append("</table><table><tr><th>parameter</th><th>unit</th><th>estimate</th><th>std</th></tr>")
        for p in ident["parameters"]:
            if p["identifiable"]:
                out.append(f"<tr><td>{e(p['name'])}</td><td>{e(p['unit'])}</td><td class=num>{p['estimate']:.6g}</td>"
                           f"<td class=num>{p['std']:.3g}</td></tr>")
        out.append("</table>")
    else:
        out.append("<p>No measurements were given (run with <code>--data</code>).</p>")
    out.append("</section>")
    # diagnosis
    out.append('<section id="diagnosis"><h2>Sim-to-real gap</h2>')
    diag = doc["diagnosis"]
    if diag:
        verdict = "significant gap" if diag["gap_significant"] else "no significant gap"
        out.append(f"<p><b>{verdict}</b>; selected effects: {e(', '.join(diag['selected']) or 'none')}.</p>")
        out.append("<table><tr><th>effect</th><th>CV RMS (&micro;m)</th><th>&Delta;BIC</th><th>note</th></tr>")
        for r in diag["ranking"]:
            out.append(f"<tr><td>{e(r['effect'])}</td><td class=num>{_um(r['cv_rms'])}</td>"
                       f"<td class=num>{r['criterion']:.1f}</td><td>{e(r.get('note', ''))}</td></tr>")
        out.append("</table>")
        b, a = diag["validation_before"], diag["validation_after"]
        if b:
            out.append(f"<p>Validation RMS before {_um(b['rms'])} &micro;m"
                       + (f", after {_um(a['rms'])} &micro;m" if a else "") + ".</p>")
        for name in ("before_after.png", "residuals_vs_joints.png"):
            if name in images:
                out.append(_img(images[name], name))
    else:
        out.append("<p>No measurements were given.</p>")
    out.append("</section></body></html>")
    return "\n".join(out) + "\n"


def render_markdown(doc: dict) -> str:
    """The same report in Markdown (images are left to the HTML)."""
    s = doc["summary"]
    lines = [f"# Tolerance report: {doc['mechanism']}", "", "Lengths in mm, angles in rad, residuals in um.", "",
             "## Summary", "", f"* defect parameters: {s['parameters']}", f"* mobility: {s['mobility']}",
             f"* degree of over-constraint: {s['overconstraint']}", f"* constraint rank: {s['rank']}"]
    lines += [f"* {cls}: {n}" for cls, n in s["tolerance_classes"].items()]
    lines += ["", "## Defects per joint", "", "| joint | parameter | unit | verdict | class |", "|---|---|---|---|---|"]
    for j in doc["joints"]:
        for p in j["parameters"]:
            lines.append(f"| {j['element']} | {p['name']} | {p['unit']} | {p['verdict']} | {p['class']} |")
    lines += ["", "## Constraint equations", ""]
    lines += [f"* {n} = 0" for n in doc["forced"]] + [f"* {r['text']}" for r in doc["relations"]]
    if doc["hypotheses"]:
        lines += ["", "## Design hypotheses", "", "| hypothesis | verdict |", "|---|---|"]
        lines += [f"| {h['id']} | {h['verdict']} |" for h in doc["hypotheses"]]
    if doc.get("accuracy") and doc["accuracy"].get("coefficients"):
        lines += ["", "## Accuracy coefficients", "", "| coefficient | min | mean | max |", "|---|---|---|---|"]
        lines += [f"| {k} | {v['min']:.4g} | {v['mean']:.4g} | {v['max']:.4g} |"
                  for k, v in doc["accuracy"]["coefficients"].items()]
    if doc["identification"]:
        i = doc["identification"]
        lines += ["", "## Identification", "", f"rank {i['rank']} of {i['unknowns']}, condition number "
                  f"{i['condition_number']:.3g}", ""]
        for key in ("identification", "validation"):
            if i.get(key):
                lines.append(f"* {key}: mean {_um(i[key]['mean'])} um, max {_um(i[key]['max'])} um, "
                             f"RMS {_um(i[key]['rms'])} um")
    if doc["diagnosis"]:
        d = doc["diagnosis"]
        lines += ["", "## Sim-to-real gap", "", f"gap significant: {d['gap_significant']}; selected: "
                  f"{', '.join(d['selected']) or 'none'}", "", "| effect | CV RMS (um) | dBIC |", "|---|---|---|"]
        lines += [f"| {r['effect']} | {_um(r['cv_rms'])} | {r['criterion']:.1f} |" for r in d["ranking"]]
    return "\n".join(lines) + "\n"


def write_report(doc: dict, out_dir: str | Path, mechanism=None, analysis_json: dict | None = None,
                 images: dict | None = None) -> list[Path]:
    """Render the views and write ``report.html``, ``report.md`` and ``report.json`` atomically into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    images = dict(images or {})
    if mechanism is not None and "views" not in images:
        from hyperstat.cad_plugin.view import render_png

        with tempfile.TemporaryDirectory() as tmp:
            path = render_png(mechanism, Path(tmp) / "views.png", analysis_json, window_size=(1400, 1050))
            images["views"] = path.read_bytes()
    written = [write_text(out_dir / "report.json", dumps_json(doc)),
               write_text(out_dir / "report.md", render_markdown(doc)),
               write_text(out_dir / "report.html", render_html(doc, images))]
    if "views" in images:
        written.append(write_bytes(out_dir / "skeleton_views.png", images["views"]))
    return written
