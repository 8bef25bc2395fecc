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
import tempfile
from pathlib import Path

from hyperstat.solver.atomic import all_or_nothing, dumps_json, write_bytes, write_text

__all__ = ["write_report", "skeleton_png", "render_html", "render_markdown", "SECTIONS"]

SECTIONS = ("summary", "skeleton", "assembly", "accuracy", "montecarlo", "calibration", "hypotheses", "identification",
            "diagnosis", "joints", "appendix")

CLASS_COLORS = {
    "assembly": "#c2007a",
    "accuracy-critical": "#c62828",
    "compensable": "#00838f",
    "non-influent": "#6d6d6d",
    "normalisation": "#9e9e9e",
}

CSS = """
body { font-family: "DejaVu Sans", Arial, sans-serif; font-size: 17px; color: #111; margin: 2em auto;
       max-width: 1200px; line-height: 1.35; }
h1 { font-size: 1.8em; border-bottom: 4px solid #111; margin: 0 0 .3em 0; }
h2 { font-size: 1.35em; margin-top: 1.4em; border-bottom: 2px solid #999; break-after: avoid; page-break-after: avoid; }
table { border-collapse: collapse; margin: .5em 0; } th, td { border: 1px solid #999; padding: .15em .4em;
       vertical-align: top; }
th { background: #eee; text-align: left; } td.num { text-align: right; font-variant-numeric: tabular-nums;
       white-space: nowrap; }
table.title td { border: none; padding: .05em .6em .05em 0; } table.title td:first-child { font-weight: bold; }
table.tol { font-size: .85em; width: 100%; } table.tol td.stmt { font-family: "DejaVu Sans Mono", monospace;
       max-width: 22em; overflow-wrap: anywhere; } table.tol td { padding: .05em .3em; }
.badge { display: inline-block; padding: 0 .4em; border-radius: .5em; color: white; font-weight: bold;
       white-space: nowrap; -webkit-print-color-adjust: exact; print-color-adjust: exact; }
.cards { display: flex; flex-wrap: wrap; gap: .6em; margin: .4em 0; } .card { border: 2px solid #111;
       border-radius: .4em; padding: .2em .7em; min-width: 8em; } .card b { font-size: 1.6em; display: block; }
.bar { display: inline-block; height: .8em; background: #00838f; -webkit-print-color-adjust: exact;
       print-color-adjust: exact; }
img { max-width: 100%; border: 1px solid #ccc; } .note { color: #333; font-size: .9em; }
@media print {
  @page { size: A4; margin: 12mm; }
  body { font-size: 9.5pt; max-width: none; margin: 0; }
  table.tol { font-size: 7.5pt; } h1 { font-size: 16pt; } h2 { font-size: 12pt; margin-top: .8em; }
  section#skeleton { break-before: page; page-break-before: always; }
  tr, img, .cards, p { break-inside: avoid; page-break-inside: avoid; }
  img { max-height: 150mm; }
}
"""


def _badge(cls: str) -> str:
    return f'<span class="badge" style="background:{CLASS_COLORS.get(cls, "#555")}">{html.escape(cls)}</span>'


def _img(png: bytes, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode()}">'


def _um(v) -> str:
    return "-" if v is None else f"{1000 * v:.1f}"


def _value(t: dict) -> str:
    return "-" if t.get("value") is None else f"± {t['value']:.3g} {t['unit']}"


def _pct(v) -> str:
    return "-" if v is None else f"{v:.1f}"


def _spec_text(spec: dict) -> str:
    parts = []
    if spec.get("position_mm") is not None:
        parts.append(f"position ± {spec['position_mm']:g} mm")
    if spec.get("orientation_rad") is not None:
        parts.append(f"orientation ± {spec['orientation_rad']:g} rad")
    return ", ".join(parts) or "none declared"


def render_html(doc: dict, images: dict) -> str:
    """The report as one self-contained HTML page (page 1: title block, counts, tolerance table)."""
    s = doc["summary"]
    tol = doc["tolerances"]
    title = doc["title"]
    e = html.escape
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           f"<title>hyperstat tolerance report: {e(doc['mechanism'])}</title>", f"<style>{CSS}</style></head><body>",
           f"<h1>Tolerance report: {e(doc['mechanism'])}</h1>"]
    # page 1: title block, counts, tolerance table
    out.append('<section id="summary"><table class="title">')
    params = ", ".join(f"{k} = {v:g}" if isinstance(v, (int, float)) else f"{k} = {v}"
                       for k, v in (title.get("parameters") or {}).items())
    meas = title["measurements"]
    rows = [("mechanism", f"{title['mechanism']}: {title.get('description') or ''}"),
            (title.get("kind") or "source", f"{title.get('template')}" + (f" ({params})" if params else "")),
            ("source SHA-256", title.get("source_sha256") or "-"),
            ("task", ", ".join(title["task"])),
            ("spec", _spec_text(title["spec"])),
            ("calibration", f"{meas['kind']} of {len(meas['targets_mm'])} target(s), noise {meas['noise_mm']:g} mm"),
            ("units", "lengths mm, angles rad; ± values are symmetric tolerances")]
    for k, v in rows:
        out.append(f"<tr><td>{e(k)}</td><td>{e(str(v))}</td></tr>")
    out.append("</table><div class=\"cards\">")
    for cls, n in s["tolerance_classes"].items():
        out.append(f'<div class="card" style="border-color:{CLASS_COLORS[cls]}"><b>{n}</b>{e(cls)}</div>')
    out.append(f'<div class="card"><b>{s["parameters"]}</b>defect parameters</div>'
               f'<div class="card"><b>{s["overconstraint"]}</b>degree of over-constraint</div></div>')
    out.append(f"<p class=\"note\">{s['tolerances']} tolerances from {s['parameters']} defect parameters; "
               f"{s['normalisation_components']} normalisation components are not tolerances (appendix). "
               + " ".join(f"<b>{e(c)}</b>: {e(m)}." for c, m in doc["tolerance_class_meaning"].items()) + "</p>")
    out.append('<table class="tol" id="tolerance-table"><tr><th>id</th><th>feature</th><th>what it is</th>'
               "<th>statement</th><th>value</th><th>class</th><th>why</th><th>contr. %</th></tr>")
    for t in tol["items"]:
        out.append(f"<tr><td>{e(t['id'])}</td><td>{e(t['feature'])}</td><td>{e(t['words'])}</td>"
                   f"<td class=\"stmt\">{e(t['statement'])}</td><td class=\"num\">{e(_value(t))}</td>"
                   f"<td>{_badge(t['class'])}</td><td>{e(t['summary'])}</td><td class=\"num\">"
                   f"{_pct(t.get('contribution_percent'))}</td></tr>")
    out.append("</table>")
    gap = s["singular_value_gap"]
    out.append(f"<p class=\"note\">Constraint rank {s['rank']}, singular-value gap "
               f"{'none (full rank)' if gap is None or gap == float('inf') else f'{gap:.3g}'}"
               + (f"; {s['verified']['confirmed']} of {s['verified']['total']} verdicts confirmed by nonlinear "
                  f"re-assembly" if s["verified"] else "")
               + ". Contribution: share of the first-order task-error variance with every accuracy tolerance at "
               "its value, without calibration.</p></section>")
    # skeleton
    out.append('<section id="skeleton"><h2>Skeleton and tolerances</h2>')
    if "views" in images:
        out.append(_img(images["views"], "skeleton views, markers coloured by tolerance class, numbered callouts"))
    out.append('<p class="note">Each joint marker is coloured by the most severe class of its tolerances and labelled '
               "with the joint and its tolerance ids (iso view).</p></section>")
    # assembly conditions
    out.append('<section id="assembly"><h2>Assembly conditions</h2>')
    if doc["assembly_conditions"]:
        out.append("<table><tr><th>id</th><th>condition</th><th>value</th><th>feature</th><th>plays at their bound "
                   "with the largest effect</th></tr>")
        for a in doc["assembly_conditions"]:
            out.append(f"<tr><td>{e(a['id'])}</td><td>{a['mathml']}</td><td class=\"num\">{e(_value(a))}</td>"
                       f"<td>{e(a['feature'])}</td><td>{e(', '.join(a.get('limiting') or []) or '-')}</td></tr>")
        out.append("</table>")
        if doc["assembly_conditions"]:
            out.append(f"<p class=\"note\">Value: {e(doc['assembly_conditions'][0]['value_source'])}.</p>")
        red = tol.get("redundant", {})
        if red:
            out.append("<p>Redundant shifts shown with their equivalent (the same physical shift): "
                       + ", ".join(f"{e(g)} &equiv; {e(r['equivalent'])}" for g, r in red.items()) + ".</p>")
        out.append('<p class="note">Clearances: ' + "; ".join(
            f"{k}: radial {c['radial_mm']:g} mm, axial {c['axial_mm']:g} mm, tilt {c['tilt_rad']:g} rad "
            f"({e(c.get('source', ''))})" for k, c in tol["declaration"]["clearances"].items() if k in ("R", "P"))
            + ". Worst-case assemblability after Dantan &amp; Qureshi, Computer-Aided Design 41(1), 2009.</p>")
    else:
        out.append("<p>No assembly condition: the mechanism is not over-constrained.</p>")
    out.append("</section>")
    # accuracy
    out.append('<section id="accuracy"><h2>Accuracy and allocation</h2>')
    alloc = tol.get("allocation") or {}
    if alloc:
        out.append(f"<p>Spec {e(_spec_text(alloc.get('spec', {})))}; {e(alloc.get('method', ''))} "
                   f"({alloc.get('configurations', 0)} configurations).</p>")
        for key, label in (("calibrated", "accuracy-critical, after calibration"),
                           ("uncalibrated", "every influential tolerance, without calibration")):
            a = alloc.get(key)
            if not a:
                continue
            cells = [f"{k}: {('± %.3g %s' % (c['tolerance'], c['unit'])) if c['tolerance'] is not None else 'no limit'}"
                     f" ({len(c['parameters'])})" for k, c in a["classes"].items()]
            out.append(f"<p><b>{e(label)}</b>: " + e("; ".join(cells)) + "</p>")
    if doc.get("worst_cases"):
        out.append(_worst_cases_html(doc["worst_cases"]))
    if doc.get("checked"):
        out.append(f"<p class=\"note\">{e(_checked_text(doc['checked']))}</p>")
    acc = doc.get("accuracy")
    if acc and acc.get("coefficients"):
        out.append("<table><tr><th>coefficient (paper 2, eq. 18)</th><th>min</th><th>mean</th><th>max</th>"
                   "<th>unit</th></tr>")
        for name, v in acc["coefficients"].items():
            out.append(f"<tr><td>{e(name)}</td><td class=num>{v['min']:.4g}</td><td class=num>{v['mean']:.4g}</td>"
                       f"<td class=num>{v['max']:.4g}</td><td>{e(acc.get('units', {}).get(name, ''))}</td></tr>")
        out.append(f"</table><p class=\"note\">Over {acc.get('configurations')} workspace configurations "
                   f"({e(str(acc.get('geometric_errors', '')))}).</p>")
    for name in ("accuracy_map",):
        if name in images:
            out.append(_img(images[name], name))
    out.append("</section>")
    # Monte Carlo
    out.append('<section id="montecarlo"><h2>Monte Carlo</h2>')
    mc = doc.get("montecarlo")
    if mc:
        out.append(_montecarlo_html(mc))
    else:
        out.append("<p>Not run for this report.</p>")
    out.append("</section>")
    # calibration
    cal = doc.get("calibration") or {}
    out.append('<section id="calibration"><h2>Calibration</h2>')
    out.append(f"<p>Compensable tolerances assume a calibration from {e(str(cal.get('measurements', '-')))} "
               f"({cal.get('poses', '-')} poses, noise {cal.get('noise_mm', 0):g} mm). What it leaves on the task "
               f"(3&sigma;, worst configuration): position {_um(cal.get('position_mm'))} &micro;m, orientation "
               f"{cal.get('orientation_rad', 0):.2g} rad; the accuracy-critical allocation uses the spec less "
               "this residual. The part of a compensable tolerance's effect that calibration and the controller "
               f"leave (not identifiable or not cancellable) is at most {cal.get('non_identifiable_share_max', 0):.1e} "
               "of it.</p>")
    ident = doc["identification"]
    if ident:
        out.append(f"<p>Rank {ident['rank']} of {ident['unknowns']} unknowns, condition number "
                   f"{ident['condition_number']:.3g}.</p><table><tr><th></th><th>mean (&micro;m)</th>"
                   "<th>max (&micro;m)</th><th>RMS (&micro;m)</th></tr>")
        for key in ("identification", "validation"):
            v = ident.get(key)
            if v:
                out.append(f"<tr><td>{key}</td><td class=num>{_um(v['mean'])}</td><td class=num>{_um(v['max'])}</td>"
                           f"<td class=num>{_um(v['rms'])}</td></tr>")
        if ident.get("noise_rms"):
            out.append(f"<tr><td>noise floor</td><td></td><td></td><td class=num>{_um(ident['noise_rms'])}</td></tr>")
        out.append("</table>")
    else:
        out.append("<p class=\"note\">No measurements were given (run with <code>--data</code>).</p>")
    out.append("</section>")
    # hypotheses
    out.append('<section id="hypotheses"><h2>Design hypotheses</h2>')
    if doc["hypotheses"]:
        out.append("<table><tr><th>hypothesis</th><th>verdict</th><th>why</th></tr>")
        for h in doc["hypotheses"]:
            out.append(f"<tr><td>{e(h['id'])}</td><td>{e(h['verdict'])}</td><td>{e(h['reason'])}</td></tr>")
        out.append("</table>")
    else:
        out.append("<p class=\"note\">No hypothesis file was given.</p>")
    out.append("</section>")
    # identification details
    out.append('<section id="identification"><h2>Identification</h2>')
    if ident:
        out.append("<table><tr><th>parameter</th><th>unit</th><th>estimate</th><th>std</th></tr>")
        for p in ident["parameters"]:
            if p["identifiable"]:
                out.append(f"<tr><td>{e(p['name'])}</td><td>{e(p['unit'])}</td><td class=num>{p['estimate']:.6g}</td>"
                           f"<td class=num>{p['std']:.3g}</td></tr>")
        out.append("</table>")
    else:
        out.append("<p class=\"note\">No measurements were given.</p>")
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
        if diag.get("outcome"):
            out.append(f"<p>The answer: <b>{e(diag['outcome'])}</b>"
                       + (f": {e(diag['verdict'].get('evidence', ''))}" if diag.get("verdict") else "") + "</p>")
        for name in ("before_after.png", "residuals_vs_joints.png", "spectra_revolute.png"):
            if name in images:
                out.append(_img(images[name], name))
    else:
        out.append("<p class=\"note\">No measurements were given.</p>")
    out.append("</section>")
    # defects per joint
    out.append('<section id="joints"><h2>Defects per joint</h2><table class="tol"><tr><th>joint</th><th>type</th>'
               "<th>role</th><th>parameter</th><th>unit</th><th>stationarity</th><th>tolerance</th><th>class</th>"
               "<th>nonlinear check</th></tr>")
    for j in doc["joints"]:
        for k, p in enumerate(j["parameters"]):
            check = p.get("check")
            ctext = "-" if not check else ("confirmed" if check["confirmed"] else "NOT confirmed") + \
                f" ({check['residual_mm']:.2g} mm)"
            n = len(j["parameters"])
            head = (f"<td rowspan=\"{n}\">{e(j['element'])}</td><td rowspan=\"{n}\">{e(j['type'])}</td>"
                    f"<td rowspan=\"{n}\">{e(j['role'])}</td>") if k == 0 else ""
            tid = p["tolerance_id"] or "-"
            if p.get("equivalent"):
                tid += f" (&equiv; {e(p['equivalent'])})"
            out.append(f"<tr>{head}<td>{e(p['name'])}</td><td>{e(p['unit'])}</td><td>{e(p['verdict'])}</td>"
                       f"<td>{tid}</td><td>{_badge(p['class'])}</td><td>{e(ctext)}</td></tr>")
    out.append("</table></section>")
    # appendix
    out.append('<section id="appendix"><h2>Appendix: normalisation components (not tolerances)</h2>')
    normal = tol["appendix"]["normalisation"]
    if normal:
        out.append("<p>An axis carries three components for two directions of tilt; the component along the nominal "
                   "axis only normalises it (n &middot; dn = 0) and has no geometric meaning: "
                   + ", ".join(f"{e(a['name'])} (joint {e(a['element'])})" for a in normal) + ".</p>")
    else:
        out.append("<p>None.</p>")
    for w in tol.get("warnings", []):
        out.append(f"<p><b>warning</b>: {e(w)}</p>")
    out.append("</section></body></html>")
    return "\n".join(out) + "\n"


def _worst_cases_html(rows: list) -> str:
    """Where each maximum the allocation divides by is reached, with the optimiser's tolerance."""
    e = html.escape
    out = ["<table><tr><th>allocation</th><th>coefficient (task rows)</th><th>worst case</th><th>sampled max</th>"
           "<th>optimiser tol.</th><th>where</th></tr>"]
    for w in rows:
        out.append(f"<tr><td>{e(w['allocation'])}</td><td>{e(w['coefficient'])}</td><td class=num>{w['max']:.6g}</td>"
                   f"<td class=num>{w['sampled_max']:.6g}</td><td class=num>{w['optimiser_tolerance']:.1g}"
                   f"{' (iteration limit)' if 'iteration limit' in w['evidence'] else ''}</td>"
                   f"<td>{e(w['where'])}</td></tr>")
    out.append("</table>")
    return "".join(out)


def _checked_text(c: dict) -> str:
    """Where the classes and the assembly values were checked, in one sentence."""
    of = c.get("of", {})
    parts = [f"Classes checked at {c.get('configurations')} configurations ("
             + ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in of.items()) + ")"]
    if c.get("worst_cases"):
        parts.append(f"and again with the {c['worst_cases']} accuracy worst cases "
                     + ("(same classes)" if c.get("worst_cases_agree") else "(a class changes there: see the warnings)"))
    if c.get("margin") is not None:
        parts.append(f"; smallest margin between a verdict's evidence and its threshold: a factor {c['margin']:.2g}")
    a = c.get("assembly")
    if a:
        parts.append(f". Assembly values: worst case over {a['total']} configurations ({a['analysis']} of the analysis, "
                     f"{a['workspace']} sampled in the declared workspace, {a['box_corners']} corners of its actuated box)")
    return " ".join(parts).replace(" ;", ";").replace(" .", ".") + "."


def _montecarlo_html(mc: dict) -> str:
    e = html.escape
    out = [f"<p>{mc['samples']} samples through the nonlinear model, every accuracy-critical and compensable "
           f"tolerance drawn within ± its value ({e(mc.get('distribution', 'uniform'))}), errors on the task "
           f"components ({e(', '.join(mc.get('task', [])))}); {mc.get('not_assembled', 0)} did not assemble. "
           "Assembly conditions are not drawn: violating one deforms the structure.</p>"
           "<table><tr><th></th><th>mean</th><th>p99</th>"
           "<th>max</th><th>linear worst case</th><th>out of spec, as built</th><th>out of spec, calibrated</th></tr>"]
    cal = mc.get("calibrated") or {}
    for key, unit, spec_key in (("position_mm", "mm", "out_of_spec_position_percent"),
                                ("orientation_rad", "rad", "out_of_spec_orientation_percent")):
        v = mc.get(key)
        if not v:
            continue
        bound = mc.get("linear_worst_case", {}).get(key)
        oos = mc.get(spec_key)
        oos_cal = cal.get(spec_key)
        out.append(f"<tr><td>{key.split('_')[0]} error ({unit})</td><td class=num>{v['mean']:.3g}</td>"
                   f"<td class=num>{v['p99']:.3g}</td><td class=num>{v['max']:.3g}</td>"
                   f"<td class=num>{'-' if bound is None else f'{bound:.3g}'}</td>"
                   f"<td class=num>{'-' if oos is None else f'{oos:.2f} %'}</td>"
                   f"<td class=num>{'-' if oos_cal is None else f'{oos_cal:.2f} %'}</td></tr>")
    out.append("</table><table><tr><th>contributor</th><th>share of the position variance</th>"
               "<th>share of the orientation variance</th></tr>")
    for c in mc.get("contributors", [])[:10]:
        out.append(f"<tr><td>{e(c.get('label', c['parameter']))}</td>"
                   f"<td><span class=\"bar\" style=\"width:{3 * 100 * c['position_share']:.0f}px\"></span> "
                   f"{100 * c['position_share']:.1f} %</td>"
                   f"<td><span class=\"bar\" style=\"width:{3 * 100 * c['orientation_share']:.0f}px\"></span> "
                   f"{100 * c['orientation_share']:.1f} %</td></tr>")
    out.append("</table>")
    return "".join(out)


def render_markdown(doc: dict) -> str:
    """The same report in Markdown (images are left to the HTML)."""
    s = doc["summary"]
    tol = doc["tolerances"]
    title = doc["title"]
    lines = [f"# Tolerance report: {doc['mechanism']}", "",
             f"* mechanism: {title['mechanism']}: {title.get('description') or ''}",
             f"* {title.get('kind') or 'source'}: {title.get('template')}",
             f"* source SHA-256: {title.get('source_sha256') or '-'}",
             f"* task: {', '.join(title['task'])}", f"* spec: {_spec_text(title['spec'])}",
             "* units: lengths mm, angles rad", "", "## Summary", ""]
    lines += [f"* {cls}: {n}" for cls, n in s["tolerance_classes"].items()]
    lines += [f"* defect parameters: {s['parameters']}", f"* degree of over-constraint: {s['overconstraint']}",
              f"* normalisation components (not tolerances): {s['normalisation_components']}", "",
              "## Tolerances", "", "| id | feature | what it is | statement | value | class | why | contr. % |",
              "|---|---|---|---|---|---|---|---|"]
    for t in tol["items"]:
        lines.append(f"| {t['id']} | {t['feature']} | {t['words']} | `{t['statement']}` | {_value(t)} | {t['class']} | "
                     f"{t['summary']} | {_pct(t.get('contribution_percent'))} |")
    if tol.get("warnings"):
        lines += ["", "Warnings:", ""] + [f"* {w}" for w in tol["warnings"]]
    lines += ["", "## Assembly conditions", ""]
    lines += [f"* {a['id']}: {a['statement']} ({_value(a)})" for a in doc["assembly_conditions"]] or ["* none"]
    red = tol.get("redundant", {})
    if red:
        lines += ["", "Redundant shifts: " + ", ".join(f"{g} ≡ {r['equivalent']}" for g, r in red.items())]
    if doc.get("worst_cases"):
        lines += ["", "## Worst cases of the allocation", "",
                  "| allocation | coefficient | worst case | sampled max | optimiser tol. | where |", "|---|---|---|---|---|---|"]
        lines += [f"| {w['allocation']} | {w['coefficient']} | {w['max']:.6g} | {w['sampled_max']:.6g} | "
                  f"{w['optimiser_tolerance']:.1g}{' (iteration limit)' if 'iteration limit' in w['evidence'] else ''} | "
                  f"{w['where']} |" for w in doc["worst_cases"]]
    if doc.get("checked"):
        lines += ["", _checked_text(doc["checked"])]
    if doc.get("accuracy") and doc["accuracy"].get("coefficients"):
        lines += ["", "## Accuracy coefficients", "", "| coefficient | min | mean | max |", "|---|---|---|---|"]
        lines += [f"| {k} | {v['min']:.4g} | {v['mean']:.4g} | {v['max']:.4g} |"
                  for k, v in doc["accuracy"]["coefficients"].items()]
    mc = doc.get("montecarlo")
    if mc:
        lines += ["", "## Monte Carlo", "", f"{mc['samples']} samples, every tolerance at its value."]
        for key in ("out_of_spec_position_percent", "out_of_spec_orientation_percent"):
            if mc.get(key) is not None:
                lines.append(f"* {key.replace('_', ' ')}: {mc[key]:.2f} %")
        lines += [f"* {c.get('label', c['parameter'])}: position {100 * c['position_share']:.1f} %, orientation "
                  f"{100 * c['orientation_share']:.1f} %" for c in mc.get("contributors", [])[:10]]
    cal = doc.get("calibration") or {}
    lines += ["", "## Calibration", "", f"residual after calibration (3 sigma): position {_um(cal.get('position_mm'))} um, "
              f"orientation {cal.get('orientation_rad', 0):.2g} rad; part of a compensable tolerance's effect left: "
              f"at most {cal.get('non_identifiable_share_max', 0):.1e}"]
    if doc["hypotheses"]:
        lines += ["", "## Design hypotheses", "", "| hypothesis | verdict |", "|---|---|"]
        lines += [f"| {h['id']} | {h['verdict']} |" for h in doc["hypotheses"]]
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
    lines += ["", "## Defects per joint", "", "| joint | parameter | unit | stationarity | tolerance | class |",
              "|---|---|---|---|---|---|"]
    for j in doc["joints"]:
        for p in j["parameters"]:
            lines.append(f"| {j['element']} | {p['name']} | {p['unit']} | {p['verdict']} | {p['tolerance_id'] or '-'} | "
                         f"{p['class']} |")
    lines += ["", "## Appendix: normalisation components (not tolerances)", ""]
    lines += [f"* {a['name']} (joint {a['element']})" for a in tol["appendix"]["normalisation"]] or ["* none"]
    return "\n".join(lines) + "\n"


def skeleton_png(mechanism, analysis_json: dict | None = None) -> bytes:
    """PNG bytes of the report's skeleton views (four views, markers coloured by tolerance class)."""
    from hyperstat.cad_plugin.view import render_png

    with tempfile.TemporaryDirectory() as tmp:
        return render_png(mechanism, Path(tmp) / "views.png", analysis_json, window_size=(1400, 1050)).read_bytes()


def write_report(doc: dict, out_dir: str | Path, mechanism=None, analysis_json: dict | None = None,
                 images: dict | None = None) -> list[Path]:
    """Render the views and write ``report.html``, ``report.md`` and ``report.json`` atomically into ``out_dir``."""
    out_dir = Path(out_dir)
    images = dict(images or {})
    if mechanism is not None and "views" not in images:
        images["views"] = skeleton_png(mechanism, analysis_json)
    with all_or_nothing():  # every file of the report or none
        written = [write_text(out_dir / "report.json", dumps_json(doc)),
                   write_text(out_dir / "report.md", render_markdown(doc)),
                   write_text(out_dir / "report.html", render_html(doc, images))]
        if "views" in images:
            written.append(write_bytes(out_dir / "skeleton_views.png", images["views"]))
    return written
