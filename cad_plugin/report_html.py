"""The tolerance report as one self-contained HTML page, laid out like an engineering document.

Units: lengths in mm, angles in rad; residuals in µm.

Page 1: a title block (mechanism, template, parameters, source hash, hyperstat version, date,
revision), the counts per class and the tolerance table (both values of the compensable
tolerances, the feature control frames of the others).  Then the skeleton drawing (vector text:
its callouts print at 8 pt), the assembly conditions, accuracy and allocation, Monte Carlo,
calibration, identification, the sim-to-real gap, the design hypotheses, the defects per joint, a
glossary and the appendix.  Print rules for A4: a heading is kept with what follows it (never
alone at the foot of a page), table rows and figures are not split, table heads repeat.  Nothing
is loaded from the network: images are inline (SVG, PNG as base64).
"""

from __future__ import annotations

import base64
import html
import re

from hyperstat.cad_plugin.gdt import symbol_of, symbol_svg, zone_text
from hyperstat.cad_plugin.palette import CLASS_COLORS, CLASS_LABELS, tolerance_counts
from hyperstat.cad_plugin.report_words import (bounds_lines, calibrated_value, contributor_groups, frames_of, glossary,
                                               limit_lines, micro, number, other_warnings, significance, spec_text,
                                               title_rows, tolerance_value, um, values_note, where_words)

__all__ = ["render_html", "SECTIONS", "CSS"]

SECTIONS = ("summary", "skeleton", "assembly", "accuracy", "montecarlo", "calibration", "hypotheses", "identification",
            "diagnosis", "joints", "glossary", "appendix", "parts")

CSS = """
body { font-family: "DejaVu Sans", Arial, sans-serif; font-size: 17px; color: #111; margin: 2em auto;
       max-width: 1200px; line-height: 1.3; }
h1 { font-size: 1.6em; margin: 0 0 .2em 0; }
h2 { font-size: 1.3em; margin: 1.1em 0 .3em 0; border-bottom: 2px solid #999; break-after: avoid; page-break-after: avoid; }
h3 { font-size: 1.05em; margin: .6em 0 .2em 0; break-after: avoid; page-break-after: avoid; }
table { border-collapse: collapse; margin: .3em 0; } th, td { border: 1px solid #999; padding: .1em .35em;
       vertical-align: top; }
th { background: #eee; text-align: left; } thead { display: table-header-group; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
table.block { width: 100%; border: 2px solid #111; } table.block td { border: 1px solid #777; }
table.block td.k { font-weight: bold; white-space: nowrap; background: #f4f4f4; width: 1%; }
table.block td.hash { font-family: "DejaVu Sans Mono", monospace; font-size: .85em; }
table.block td.warn { color: #b00020; font-weight: bold; }
table.tol { font-size: .8em; width: 100%; } table.tol td.stmt { font-family: "DejaVu Sans Mono", monospace;
       overflow-wrap: anywhere; } table.tol td { padding: 0 .25em; } td.nw { white-space: nowrap; }
.badge { display: inline-block; padding: 0 .35em; border-radius: .4em; color: white; font-weight: bold;
       white-space: nowrap; -webkit-print-color-adjust: exact; print-color-adjust: exact; }
.cards { display: flex; flex-wrap: wrap; gap: .4em; margin: .3em 0; } .card { border: 2px solid #111;
       border-radius: .3em; padding: 0 .5em; } .card b { font-size: 1.3em; margin-right: .25em; }
.bar { display: inline-block; height: .7em; background: #00838f; -webkit-print-color-adjust: exact;
       print-color-adjust: exact; }
.fcf { display: inline-flex; border: 1px solid #111; vertical-align: middle; margin: 1px 0; white-space: nowrap; }
.fcf > span { border-left: 1px solid #111; padding: 0 .25em; line-height: 1.2; display: inline-flex; align-items: center; }
.fcf > span:first-child { border-left: none; } .req { white-space: normal; overflow-wrap: anywhere; } svg.gdt { display: block; }
img { max-width: 100%; } figure { margin: .3em 0; break-inside: avoid; page-break-inside: avoid; }
figure svg { max-width: 100%; height: auto; display: block; } .limit { font-size: .8em; color: #333; } td.num .limit { white-space: normal; }
ul.limits { font-size: .75em; columns: 2; column-gap: 1.2em; margin: .2em 0; padding-left: 1.2em; } ul.limits li { break-inside: avoid; } figcaption, .note { color: #333; font-size: .85em; }
.cols { display: flex; gap: 1em; align-items: flex-start; } .cols > * { flex: 1; }
dl.glossary { columns: 3; column-gap: 1.2em; font-size: .8em; } dl.glossary dt { font-weight: bold; break-after: avoid; }
dl.glossary dd { margin: 0 0 .25em 1em; break-inside: avoid; }
@media print {
  @page { size: A4; margin: 12mm; }
  body { font-size: 8.5pt; max-width: none; margin: 0; }
  table.tol { font-size: 7pt; } h1 { font-size: 14pt; } h2 { font-size: 11pt; margin-top: .6em; }
  h3 { font-size: 9pt; }
  tr, img, .cards, p, li, figure, .fcf { break-inside: avoid; page-break-inside: avoid; }
}
"""


def _e(text) -> str:
    """Text from the JSON, escaped, its micro-units spelled µm / µrad."""
    return html.escape(micro(str(text)))


def _badge(cls: str) -> str:
    return (f'<span class="badge" style="background:{CLASS_COLORS.get(cls, "#555")}" '
            f'title="{_e(CLASS_LABELS.get(cls, cls))}">{_e(cls)}</span>')


def _image(image, alt: str) -> str:
    """An inline picture: SVG text as is, PNG bytes as base64."""
    if isinstance(image, str):
        return image
    return f'<img alt="{_e(alt)}" src="data:image/png;base64,{base64.b64encode(image).decode()}">'


def _fcf(callout: dict) -> str:
    """One feature control frame as boxes: symbol, zone (mm), datums; the callout's sentence as tooltip.

    A requirement met at assembly (no ISO 1101 symbol: it relates features of several parts) is words that wrap
    in their cell, not a frame: a frame does not wrap and ran over the next column of the printed table.
    """
    if not callout.get("symbol") and callout.get("characteristic") == "assembly requirement":
        return (f'<span class="req" title="{_e(callout.get("text", ""))}">assembly requirement '
                f'{_e(callout.get("frame_id", ""))}: ± {_e(zone_text(callout))} {_e(callout.get("unit") or "mm")}</span>')
    cells = [symbol_svg(symbol_of(callout), 11), _e(zone_text(callout))] + [_e(d) for d in callout.get("datums") or []]
    return (f'<span class="fcf" title="{_e(callout.get("text", ""))}">'
            + "".join(f"<span>{c}</span>" for c in cells) + "</span>")


def _head(section: str, title: str, first: str = "") -> str:
    """A section's opening (its heading stays on the page of what follows: ``break-after: avoid``)."""
    return f'<section id="{section}"><h2>{_e(title)}</h2>{first}'


def _table(headers: list[str], rows: list[list[str]], cls: str = "", numeric: set[int] = frozenset(),
           columns: dict[int, str] | None = None, ident: str = "", widths: list[int] | None = None) -> str:
    """A table with a repeated head; ``numeric`` columns right-aligned, ``columns`` extra cell classes,
    ``widths`` the columns' shares of the width in % (a fixed layout)."""
    columns = dict(columns or {})
    for i in numeric:
        columns[i] = (columns.get(i, "") + " num").strip()
    attr = f' id="{ident}"' if ident else ""
    cols = ""
    if widths:
        attr += ' style="table-layout: fixed"'
        cols = "<colgroup>" + "".join(f'<col style="width:{w}%">' for w in widths) + "</colgroup>"
    out = [f'<table class="{cls}"{attr}>{cols}<thead><tr>' + "".join(f"<th>{h}</th>" for h in headers)
           + "</tr></thead><tbody>"]
    for row in rows:
        out.append("<tr>" + "".join(f'<td class="{columns[i]}">{c}</td>' if i in columns else f"<td>{c}</td>"
                                    for i, c in enumerate(row)) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)


def _summary(doc: dict) -> str:
    s, tol = doc["summary"], doc["tolerances"]
    block = ['<table class="block">']
    short: list = []
    for k, v in title_rows(doc):  # short fields two to a row, long ones across the block
        if len(v) <= 48:
            short.append(f'<td class="k">{_e(k)}</td><td>{_e(v)}</td>')
            if len(short) == 2:
                block.append(f"<tr>{''.join(short)}</tr>")
                short = []
            continue
        cls = ' class="hash"' if "SHA" in k else ' class="warn"' if v.startswith("WARNING: ") else ""
        block.append(f'<tr><td class="k">{_e(k)}</td><td colspan="3"{cls}>{_e(v)}</td></tr>')
    if short:
        block.append(f"<tr>{short[0]}<td></td><td></td></tr>")
    block.append("</table>")
    cards = ['<div class="cards">']
    for cls, n in tolerance_counts({"counts": s["tolerance_classes"]}).items():
        cards.append(f'<div class="card" style="border-color:{CLASS_COLORS[cls]}"><b>{n}</b>{_e(cls)}</div>')
    cards.append(f'<div class="card"><b>{s["parameters"]}</b>defect parameters</div>'
                 f'<div class="card"><b>{s["overconstraint"]}</b>degree of over-constraint</div></div>')
    verified = s.get("verified")
    note = (f"<p class=\"note\">{s['tolerances']} tolerances from {s['parameters']} defect parameters "
            f"({s['normalisation_components']} normalisation components are not tolerances: appendix)"
            + (f"; {verified['confirmed']} of {verified['total']} classes confirmed by nonlinear re-assembly"
               if verified else "")
            + ". Values: without calibration, and with calibration for compensable tolerances; the drawing carries "
              "the feature control frames. Words and symbols: glossary.</p>")
    rows = []
    for t in tol["items"]:
        frames = " ".join(_fcf(c) for c in frames_of(t)) or (_e(tolerance_value(t, "drawing_value"))
                                                             if t.get("drawing_value") is not None else "")
        rows.append([_e(t["id"]), f"{_e(t['feature'])}: {_e(t['words'])}", _e(t["statement"]), _e(tolerance_value(t)),
                     _with_calibration(t), frames or "-", _badge(t["class"]),
                     "-" if t.get("contribution_percent") is None else f"{t['contribution_percent']:.1f}"])
    table = _table(["id", "feature: what it is", "statement", "without calibration", "with calibration", "drawing",
                    "class", "contr. %"], rows, "tol", {3, 4, 7}, {0: "nw", 2: "stmt", 6: "nw"}, "tolerance-table",
                   [4, 29, 16, 11, 11, 11, 13, 5])
    limits = [f"<li>{_e(line)}</li>" for line in limit_lines(tol["items"])]
    limits_html = ('<p class="note">What limits each value with calibration (the word in the table, in full):</p>'
                   f'<ul class="limits">{"".join(limits)}</ul>' if limits else "")
    return ('<section id="summary">' + "".join(block) + "".join(cards) + note + table
            + "<p class=\"note\">contr. %: share of the first-order task-error variance with every accuracy "
              "tolerance at its value, without calibration.</p>" + limits_html + "</section>")


def _with_calibration(item: dict) -> str:
    """The with-calibration value, the kind of limit that binds in small type below (in full under the table)."""
    if item.get("value_with_calibration") is None:
        return "-"
    limit = (item.get("value_with_calibration_limit") or "").split(":")[0].strip()
    return _e(tolerance_value(item, "value_with_calibration")) + (f'<br><span class="limit">{_e(limit)}</span>'
                                                                   if limit else "")


def _breakable(mathml: str) -> str:
    """A relation's MathML as inline pieces that a narrow cell can wrap between, before each top-level +, - and =.

    Only the relation's own row is split (a nested row, a fraction, stays whole); MathML that does not
    parse, or has no single top-level row, is returned as it is.

    >>> _breakable('<math display="block"><mrow><mi>a</mi><mo>+</mo><mi>b</mi></mrow></math>')
    '<math><mrow><mi>a</mi></mrow></math> <math><mrow><mo>+</mo><mi>b</mi></mrow></math>'
    >>> _breakable('<math><mrow><mi>a</mi><mo>=</mo><mrow><mo>-</mo><mn>2</mn></mrow></mrow></math>')
    '<math><mrow><mi>a</mi></mrow></math> <math><mrow><mo>=</mo><mrow><mo>-</mo><mn>2</mn></mrow></mrow></math>'
    """
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(mathml)
    except ET.ParseError:
        return mathml
    if root.tag != "math" or len(root) != 1 or root[0].tag != "mrow":
        return mathml
    groups: list = [[]]
    for child in root[0]:
        if child.tag == "mo" and (child.text or "").strip() in ("+", "-", "\u2212", "=") and groups[-1]:
            groups.append([])
        groups[-1].append(child)
    return " ".join("<math><mrow>" + "".join(ET.tostring(c, encoding="unicode") for c in g) + "</mrow></math>"
                    for g in groups)


def _skeleton(images: dict, parts: bool = False) -> str:
    out = [_head("skeleton", "Skeleton and tolerances")]
    if "views" in images:
        called = ("its tolerance ids (the feature control frames are on the part drawings, one page per part, at the "
                  "end)" if parts else "its tolerance ids and feature control frames")
        out.append(f"<figure>{_image(images['views'], 'skeleton views')}<figcaption>The template's links at home, "
                   "four orthographic views (none edge-on to a planar mechanism's plane). Each joint is coloured by "
                   f"the most severe class of its defects and called out once with {called}.</figcaption></figure>")
    out.append("</section>")
    return "".join(out)


def _assembly(doc: dict) -> str:
    tol = doc["tolerances"]
    items = {t["id"]: t for t in tol["items"]}
    conditions = doc["assembly_conditions"]
    if not conditions:
        return _head("assembly", "Assembly conditions", "<p>None: the mechanism is not over-constrained.</p>") + \
            "</section>"
    rows = []
    for a in conditions:
        frames = "<br>".join(_fcf(c) + f' <span class="limit">{_e(c.get("text", ""))}</span>'
                             for c in frames_of(items.get(a["id"], {})))
        rows.append([_e(a["id"]), _breakable(a["mathml"]), _e(tolerance_value(a)), _e(a["feature"]), frames or "-",
                     _e(", ".join(re.sub(r"^joint |\s*\(.*\)$", "", j) for j in a.get("limiting") or []) or "-")])
    out = [_head("assembly", "Assembly conditions", _table(["id", "condition", "value", "feature", "drawing (ISO 1101)",
                                                             "joints whose plays limit it most (clearances below)"], rows,
                                                            "tol", numeric={2}, columns={0: "nw"}, ident="assembly-table",
                                                            widths=[4, 30, 10, 11, 33, 12]))]
    out.append(f"<p class=\"note\">Value: {_e(conditions[0]['value_source'])}.</p>")
    red = tol.get("redundant", {})
    if red:
        from hyperstat.solver.tolerances.classification import redundant_text

        out.append("<p>Redundant shifts shown with their equivalent (the same physical shift, or the combination it "
                   "acts as along a skew axis): " + ", ".join(_e(redundant_text(g, r)) for g, r in red.items()) + ".</p>")
    whole = (doc.get("whole_drawing") or {}).get("statement")
    if whole:
        out.append(f"<p class=\"note\">The drawing as a whole: {_e(whole)}.</p>")
    clear = tol["declaration"].get("clearances", {})
    out.append('<p class="note">Clearances: ' + "; ".join(
        f"{k}: radial {c['radial_mm']:g} mm, axial {c['axial_mm']:g} mm, tilt {c['tilt_rad']:g} rad "
        f"({_e(c.get('source', ''))})" for k, c in clear.items() if k in ("R", "P"))
        + ". Worst-case assemblability after Dantan &amp; Qureshi, Computer-Aided Design 41(1), 2009.</p></section>")
    return "".join(out)


def _joint_types(doc: dict) -> dict:
    return {str(j["element"]): j.get("type", "") for j in doc.get("joints", [])}


def _accuracy(doc: dict, images: dict) -> str:
    tol = doc["tolerances"]
    alloc = tol.get("allocation") or {}
    parts = []
    if alloc:
        parts.append(f"<p>Spec {_e(spec_text(alloc.get('spec', {})))}; {_e(alloc.get('method', ''))} "
                     f"({alloc.get('configurations', 0)} configurations).</p>")
        for key, label in (("calibrated", "accuracy-critical, after calibration"),
                           ("uncalibrated", "every influential tolerance, without calibration")):
            a = alloc.get(key)
            if a:
                cells = [f"{k}: {tolerance_value({'value': c['tolerance'], 'unit': c['unit']}) if c['tolerance'] is not None else 'no limit'}"
                         f" ({len(c['parameters'])} parameters)" for k, c in a["classes"].items()]
                parts.append(f"<p><b>{_e(label)}</b>: " + _e("; ".join(cells)) + "</p>")
    bounds = bounds_lines(tol["items"])
    if bounds:
        parts.append("<p>Linear bounds of the task error with every tolerance at its value (the attainable worst "
                     "case over the sign patterns, and the triangle bound no machine need reach):</p><ul>"
                     + "".join(f"<li>{_e(line)}</li>" for line in bounds) + "</ul>")
    out = [_head("accuracy", "Accuracy and allocation", "".join(parts[:1]))] + parts[1:]
    types = _joint_types(doc)
    if doc.get("worst_cases"):
        rows = []
        for w in doc["worst_cases"]:
            full = (alloc.get(w["allocation"]) or {}).get("worst_cases", {}).get(w["coefficient"], w)
            tol_text = number(w["optimiser_tolerance"], ".1g", "unknown") + (
                " (iteration limit)" if "iteration limit" in w["evidence"] else "")
            rows.append([_e("after calibration" if w["allocation"] == "calibrated" else "without calibration"),
                         _e(w["coefficient"]), number(w["max"], ".4g"), number(w["sampled_max"], ".4g"), _e(tol_text),
                         _e(where_words(full, types))])
        out.append('<h3>Worst cases the allocation divides by (task components)</h3>'
                   + _table(["allocation", "coefficient", "worst case", "sampled max", "optimiser tol.", "where"], rows,
                            "tol", numeric={2, 3, 4}))
    note = values_note(doc)
    if note:
        out.append(f'<p class="note">{_e(note)}</p>')
    if doc.get("checked"):
        from hyperstat.cad_plugin.report_markdown import checked_text

        out.append(f"<p class=\"note\">{_e(checked_text(doc['checked']))}</p>")
    acc = doc.get("accuracy")
    if acc and acc.get("coefficients"):
        from hyperstat.cad_plugin.report_words import coefficient_words

        rows = [[_e(name), _e(coefficient_words(name)), number(v["min"], ".4g"), number(v["mean"], ".4g"),
                 number(v["max"], ".4g"),
                 _e(acc.get("units", {}).get(name, ""))] for name, v in acc["coefficients"].items()]
        out.append('<h3>Accuracy coefficients (paper 2, eq. 18), all components</h3>'
                   + _table(["coefficient", "what it measures", "min", "mean", "max", "unit"], rows,
                            numeric={2, 3, 4})
                   + f"<p class=\"note\">Over {acc.get('configurations')} workspace configurations "
                     f"({_e(str(acc.get('geometric_errors', '')))}).</p>")
    if "accuracy_map" in images:
        out.append(f"<figure>{_image(images['accuracy_map'], 'accuracy map')}</figure>")
    out.append("</section>")
    return "".join(out)


def _montecarlo(doc: dict) -> str:
    mc = doc.get("montecarlo")
    if not mc:
        return _head("montecarlo", "Monte Carlo", "<p>Not run for this report.</p>") + "</section>"
    cal_words = (mc.get("calibrated") or {}).get("method") or (mc.get("calibrated") or {}).get("note") or ""
    intro = (f"<p>{mc['samples']} samples through the nonlinear model, every accuracy-critical and compensable "
             f"tolerance drawn within ± its drawing value ({_e(mc.get('distribution', 'uniform'))}: parts made to the "
             f"drawing), errors on the task components ({_e(', '.join(mc.get('task', [])))}); "
             f"{mc.get('not_assembled', 0)} did not assemble. Assembly conditions are not drawn: violating one deforms "
             f"the structure. Calibrated: {_e(cal_words)}.</p>")
    cal = mc.get("calibrated") or {}
    rows = []
    for key, unit, spec_key in (("position_mm", "mm", "out_of_spec_position_percent"),
                                ("orientation_rad", "rad", "out_of_spec_orientation_percent")):
        v = mc.get(key)
        if not v:
            continue
        bound = (mc.get("linear_worst_case") or {}).get(key)
        oos, oos_cal = mc.get(spec_key), cal.get(spec_key)
        rows.append([f"{key.split('_')[0]} error ({unit})", f"{v['mean']:.3g}", f"{v['p99']:.3g}", f"{v['max']:.3g}",
                     "-" if bound is None else f"{bound:.3g}", "-" if oos is None else f"{oos:.2f} %",
                     "-" if oos_cal is None else f"{oos_cal:.2f} %"])
    out = [_head("montecarlo", "Monte Carlo", intro + _table(["", "mean", "p99", "max", "linear worst case",
                                                               "out of spec, as built", "out of spec, calibrated"],
                                                              rows, numeric={1, 2, 3, 4, 5, 6}))]
    tols, acts = contributor_groups(mc, doc["tolerances"]["items"], _joint_types(doc))

    def share_rows(group):
        return [[_e(r["label"]), _e(r["what"]),
                 f"<span class=\"bar\" style=\"width:{2 * 100 * r['position_share']:.0f}px\"></span> "
                 f"{100 * r['position_share']:.1f} %",
                 f"<span class=\"bar\" style=\"width:{2 * 100 * r['orientation_share']:.0f}px\"></span> "
                 f"{100 * r['orientation_share']:.1f} %"] for r in group]

    headers = ["contributor", "what it is", "share of the position variance", "share of the orientation variance"]
    out.append('<h3>Contributors: tolerances</h3>' + _table(headers, share_rows(tols)))
    if acts:
        undrawn = all(not r["tolerance"] for r in acts)
        out.append('<h3>Contributors: actuator errors</h3>' + _table(headers, share_rows(acts))
                   + ("<p class=\"note\">No actuator tolerance is declared: the actuators were not drawn (0 %).</p>"
                      if undrawn else ""))
    out.append("</section>")
    return "".join(out)


def _calibration(doc: dict) -> str:
    cal = doc.get("calibration") or {}
    text = (f"<p>Compensable tolerances assume a calibration from {_e(str(cal.get('measurements', '-')))} "
            f"({cal.get('poses', '-')} poses, noise {um(cal.get('noise_mm'))}). What it leaves on the task "
            f"(3&sigma;, worst configuration): position {um(cal.get('position_mm'))}, orientation "
            f"{cal.get('orientation_rad', 0):.2g} rad; the accuracy-critical allocation uses the spec less "
            "this residual. The part of a compensable tolerance's effect that calibration and the controller "
            f"leave (not identifiable or not cancellable) is at most {cal.get('non_identifiable_share_max', 0):.1e} "
            "of it.</p>")
    ident = doc["identification"]
    if ident:
        rows = [[key, um(ident[key]["mean"]), um(ident[key]["max"]), um(ident[key]["rms"])]
                for key in ("identification", "validation") if ident.get(key)]
        if ident.get("noise_rms"):
            rows.append(["noise floor", "", "", um(ident["noise_rms"])])
        text += (f"<p>Rank {ident['rank']} of {ident['unknowns']} unknowns, condition number "
                 f"{ident['condition_number']:.3g}.</p>" + _table(["residuals", "mean", "max", "RMS"], rows,
                                                                   numeric={1, 2, 3}))
    else:
        text += "<p class=\"note\">No measurements were given (run with <code>--data</code>).</p>"
    return _head("calibration", "Calibration", text) + "</section>"


def _hypotheses(doc: dict) -> str:
    hyps = doc["hypotheses"]
    if not hyps:
        return _head("hypotheses", "Design hypotheses", "<p class=\"note\">No hypothesis file was given.</p>") + \
            "</section>"
    rows = [[_e(h["id"]), _e(h["verdict"]), _e(h["reason"])] for h in hyps]
    return _head("hypotheses", "Design hypotheses", _table(["hypothesis", "verdict", "why"], rows, "tol")) + "</section>"


def _estimates_table(params: list) -> str:
    rows = [[_e(p["name"]), _e(p.get("unit", "")), f"{p['estimate']:.4g}",
             "-" if p.get("std") is None else f"{p['std']:.2g}", _e(significance(p["estimate"], p.get("std")))]
            for p in params]
    return _table(["parameter", "unit", "estimate", "std", "sig."], rows, numeric={2, 3})


def _identification(doc: dict) -> str:
    ident = doc["identification"]
    if not ident:
        return _head("identification", "Identification", "<p class=\"note\">No measurements were given.</p>") + \
            "</section>"
    params = [p for p in ident["parameters"] if p["identifiable"]]
    half = (len(params) + 1) // 2
    first = (f"<p>{len(params)} identified parameters (estimate, 1 standard deviation, significance mark: see the "
             "glossary).</p>")
    body = f'<div class="cols">{_estimates_table(params[:half])}{_estimates_table(params[half:])}</div>'
    unseen = ident.get("unidentifiable") or []
    note = (f"<p class=\"note\">Not identifiable alone, held at their prior: {_e(', '.join(u['name'] for u in unseen))}."
            "</p>" if unseen else "")
    return _head("identification", "Identification", first) + body + note + "</section>"


def _diagnosis(doc: dict, images: dict) -> str:
    diag = doc["diagnosis"]
    if not diag:
        return _head("diagnosis", "Sim-to-real gap", "<p class=\"note\">No measurements were given.</p>") + \
            "</section>"
    test = diag.get("gap_test") or {}
    p_val = (test.get("validation") or test.get("identification") or {}).get("p_value")
    verdict = "a significant gap" if diag["gap_significant"] else "no significant gap"
    first = (f"<p>Gap test (chi-squared of the residuals against the noise): <b>{verdict}</b>"
             + (f" (p = {p_val:.2g}, threshold {test.get('threshold', 0):g})" if p_val is not None else "")
             + f"; selected effects: {_e(', '.join(diag['selected']) or 'none')}.</p>")
    if diag.get("outcome"):
        first += (f"<p>The answer: <b>{_e(diag['outcome'])}</b>"
                  + (f" (confidence <b>{_e(diag['confidence'])}</b>)" if diag.get("confidence") else "")
                  + (f": {_e(diag['verdict'].get('evidence', ''))}" if diag.get("verdict") else "") + ".</p>")
    rows = [[_e(r["effect"]), _e(r.get("defect") or ""), um(r["cv_rms"]).replace(" µm", ""), f"{r['criterion']:.1f}",
             _e(r.get("note", ""))] for r in diag["ranking"]]
    out = [_head("diagnosis", "Sim-to-real gap", first),
           _table(["candidate effect", "defect", "CV RMS (µm)", "\u0394BIC vs rigid", "note"], rows, numeric={2, 3})]
    b, a = diag["validation_before"], diag["validation_after"]
    if b:
        out.append(f"<p>Validation RMS before {um(b['rms'])}" + (f", after {um(a['rms'])}" if a else "") + ".</p>")
    effects = diag.get("effect_parameters") or []
    if effects:
        out.append('<h3>Effect parameters</h3>' + _estimates_table(effects))
    for name in ("before_after", "residuals_vs_joints", "spectra_revolute"):
        for key in (name, f"{name}.png", f"{name}.svg"):
            if key in images:
                out.append(f"<figure>{_image(images[key], name)}</figure>")
                break
    out.append("</section>")
    return "".join(out)


def _joints(doc: dict) -> str:
    rows = []
    for j in doc["joints"]:
        chips = []
        for p in j["parameters"]:
            tid = p["tolerance_id"] or ""
            if p.get("equivalent"):
                tid += f" &equiv; {_e(p['equivalent'])}"
            chips.append(f'<span class="badge" style="background:{CLASS_COLORS.get(p["class"], "#555")}" '
                         f'title="{_e(p["class"])}">{_e(p["name"])}</span>' + (f" {tid}" if tid else ""))
        checks = [p["check"] for p in j["parameters"] if p.get("check")]
        bad = [c for c in checks if not c["confirmed"]]
        check = "-" if not checks else (f"{len(checks) - len(bad)} of {len(checks)} confirmed"
                                        + (f", largest residual {max(c['residual_mm'] for c in checks):.1g} mm"))
        rows.append([_e(j["element"]), _e(f"{j['type']}, {j['role']}"), " ".join(chips), _e(check)])
    legend = " ".join(_badge(c) for c in CLASS_COLORS)
    return (_head("joints", "Defects per joint", f"<p class=\"note\">Each defect parameter in the colour of its class "
                                                 f"({legend}) with its tolerance id.</p>")
            + _table(["joint", "type, role", "defect parameters", "nonlinear check"], rows, "tol") + "</section>")


def _glossary(doc: dict) -> str:
    items = "".join(f"<dt>{_e(k)}</dt><dd>{_e(v)}</dd>" for k, v in glossary(doc))
    return _head("glossary", "Glossary", "") + f'<dl class="glossary">{items}</dl></section>'


def _appendix(doc: dict) -> str:
    tol = doc["tolerances"]
    normal = tol["appendix"]["normalisation"]
    text = ("<p>An axis carries three components for two directions of tilt; the component along the nominal "
            "axis only normalises it (n &middot; dn = 0) and has no geometric meaning: "
            + ", ".join(f"{_e(a['name'])} (joint {_e(a['element'])})" for a in normal) + ".</p>") if normal else \
        "<p>None.</p>"
    out = [_head("appendix", "Appendix: normalisation components (not tolerances)", text)]
    for w in other_warnings(tol.get("warnings", [])):  # the calibration campaign's is in the title block, page 1
        out.append(f"<p><b>warning</b>: {_e(w)}</p>")
    out.append("</section>")
    return "".join(out)


def render_html(doc: dict, images: dict) -> str:
    """The report as one self-contained HTML page (page 1: title block, counts, tolerance table).

    ``images`` maps names to SVG text or PNG bytes: ``views`` (the skeleton drawing), the
    diagnosis plots, ``accuracy_map``; ``parts`` the part drawings' pages
    (:func:`hyperstat.cad_plugin.report_parts.part_pages`), one A4 page each after the appendix.
    """
    from hyperstat.cad_plugin.report_parts import PARTS_CSS, parts_html

    head = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
            f"<title>hyperstat tolerance report: {_e(doc['mechanism'])}</title>",
            f"<style>{CSS}{PARTS_CSS}</style></head><body>",
            f"<h1>Tolerance report: {_e(doc['mechanism'])}</h1>"]
    parts = bool(doc.get("drawings"))
    body = [_summary(doc), _skeleton(images, parts), _assembly(doc), _accuracy(doc, images), _montecarlo(doc),
            _calibration(doc), _hypotheses(doc), _identification(doc), _diagnosis(doc, images), _joints(doc),
            _glossary(doc), _appendix(doc), parts_html(doc, images.get("parts"))]
    return "\n".join(head + body + ["</body></html>"]) + "\n"
