"""The tolerance report in Markdown: the HTML's content without its pictures.

Units: lengths in mm, angles in rad; residuals in µm.
"""

from __future__ import annotations

from hyperstat.cad_plugin.palette import tolerance_counts
from hyperstat.cad_plugin.report_words import (bounds_lines, calibrated_value, contributor_groups, frames_of, glossary,
                                               micro, number, other_warnings, significance, title_rows, tolerance_value,
                                               um, values_note, where_words)

__all__ = ["render_markdown", "checked_text"]


def checked_text(c: dict) -> str:
    """Where the classes and the assembly values were checked, in one sentence."""
    of = c.get("of", {})
    parts = [f"Classes checked at {c.get('configurations')} configurations ("
             + ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in of.items()) + ")"]
    if c.get("worst_cases"):
        parts.append(f"and again with the {c['worst_cases']} accuracy worst cases "
                     + ("(same classes)" if c.get("worst_cases_agree") else "(a class changes there: see the warnings)"))
    if c.get("margin") is not None:
        parts.append(f"; smallest margin between a class's evidence and its threshold: a factor {c['margin']:.2g}")
    a = c.get("assembly")
    if a:
        parts.append(f". Assembly values: worst case over {a['total']} configurations ({a['analysis']} of the analysis, "
                     f"{a['workspace']} sampled in the declared workspace, {a['box_corners']} corners of its actuated box)")
    return " ".join(parts).replace(" ;", ";").replace(" .", ".") + "."


def _frames(item: dict) -> str:
    """The feature control frames as text cells, or the drawing value."""
    frames = " ".join(c.get("frame") or "" for c in frames_of(item))
    return frames or (tolerance_value(item, "drawing_value") if item.get("drawing_value") is not None else "-")


def _row(*cells) -> str:
    """One Markdown table row; a ``|`` inside a cell (an ISO 1101 frame such as ``|⟂|0.1|A|``) is escaped as
    ``\\|``, so that the cell stays whole in every Markdown viewer.

    >>> print(_row("T1", "|⟂|0.1|A|", "assembly"))
    | T1 | \\|⟂\\|0.1\\|A\\| | assembly |
    """
    return "| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |"


def render_markdown(doc: dict) -> str:
    """The same report in Markdown (images are left to the HTML)."""
    s, tol = doc["summary"], doc["tolerances"]
    lines = [f"# Tolerance report: {doc['mechanism']}", ""]
    lines += [f"* {k}: {v}" for k, v in title_rows(doc)]
    lines += ["", "## Summary", ""]
    lines += [f"* {cls}: {n}" for cls, n in tolerance_counts({"counts": s["tolerance_classes"]}).items()]
    lines += [f"* defect parameters: {s['parameters']}", f"* degree of over-constraint: {s['overconstraint']}",
              f"* normalisation components (not tolerances): {s['normalisation_components']}", "",
              "## Tolerances", "",
              "| id | feature | what it is | statement | without calibration | with calibration | drawing | class | "
              "contr. % |", "|---|---|---|---|---|---|---|---|---|"]
    for t in tol["items"]:
        pct = "-" if t.get("contribution_percent") is None else f"{t['contribution_percent']:.1f}"
        lines.append(_row(t["id"], t["feature"], t["words"], f"`{t['statement']}`", tolerance_value(t),
                          calibrated_value(t), _frames(t), t["class"], pct))
    if other_warnings(tol.get("warnings") or []):  # the calibration campaign's is in the title block
        lines += ["", "Warnings:", ""] + [f"* {w}" for w in other_warnings(tol["warnings"])]
    lines += ["", "## Assembly conditions", ""]
    items = {t["id"]: t for t in tol["items"]}
    lines += [f"* {a['id']}: {a['statement']} ({tolerance_value(a)})"
              + "".join(f"; {c.get('frame', '')} {c.get('text', '')}" for c in frames_of(items.get(a["id"], {})))
              for a in doc["assembly_conditions"]] or ["* none"]
    red = tol.get("redundant", {})
    if red:
        from hyperstat.solver.tolerances.classification import redundant_text

        lines += ["", "Redundant shifts: " + ", ".join(redundant_text(g, r) for g, r in red.items())]
    whole = (doc.get("whole_drawing") or {}).get("statement")
    if whole and doc["assembly_conditions"]:
        lines += ["", f"The drawing as a whole: {whole}."]
    types = {str(j["element"]): j.get("type", "") for j in doc.get("joints", [])}
    alloc = tol.get("allocation") or {}
    if doc.get("worst_cases"):
        lines += ["", "## Worst cases of the allocation (task components)", "",
                  "| allocation | coefficient | worst case | sampled max | optimiser tol. | where |", "|---|---|---|---|---|---|"]
        for w in doc["worst_cases"]:
            full = (alloc.get(w["allocation"]) or {}).get("worst_cases", {}).get(w["coefficient"], w)
            label = "after calibration" if w["allocation"] == "calibrated" else "without calibration"
            lines.append(_row(label, w["coefficient"], number(w["max"], ".4g"), number(w["sampled_max"], ".4g"),
                              number(w["optimiser_tolerance"], ".1g", "unknown")
                              + (" (iteration limit)" if "iteration limit" in w["evidence"] else ""),
                              where_words(full, types)))
    bounds = bounds_lines(tol["items"])
    if bounds:
        lines += ["", "Linear bounds of the task error with every tolerance at its value (the attainable worst case "
                      "over the sign patterns, and the triangle bound no machine need reach):", ""]
        lines += [f"- {line}" for line in bounds]
    note = values_note(doc)
    if note:
        lines += ["", note]
    if doc.get("checked"):
        lines += ["", checked_text(doc["checked"])]
    if doc.get("accuracy") and doc["accuracy"].get("coefficients"):
        units = doc["accuracy"].get("units", {})
        lines += ["", "## Accuracy coefficients (all components)", "", "| coefficient | min | mean | max | unit |",
                  "|---|---|---|---|---|"]
        lines += [_row(k, number(v["min"], ".4g"), number(v["mean"], ".4g"), number(v["max"], ".4g"), units.get(k, ""))
                  for k, v in doc["accuracy"]["coefficients"].items()]
    mc = doc.get("montecarlo")
    if mc:
        lines += ["", "## Monte Carlo", "", f"{mc['samples']} samples, every tolerance at its value."]
        for key in ("out_of_spec_position_percent", "out_of_spec_orientation_percent"):
            if mc.get(key) is not None:
                lines.append(f"* {key.replace('_', ' ')}: {mc[key]:.2f} %")
        tols, acts = contributor_groups(mc, tol["items"], types)
        for title, group in (("Contributors: tolerances", tols), ("Contributors: actuator errors", acts)):
            if group:
                lines += ["", f"### {title}", ""]
                lines += [f"* {r['label']} ({r['what']}): position {100 * r['position_share']:.1f} %, orientation "
                          f"{100 * r['orientation_share']:.1f} %" for r in group]
    cal = doc.get("calibration") or {}
    lines += ["", "## Calibration", "", f"residual after calibration (3 sigma): position {um(cal.get('position_mm'))}, "
              f"orientation {cal.get('orientation_rad', 0):.2g} rad; part of a compensable tolerance's effect left: "
              f"at most {cal.get('non_identifiable_share_max', 0):.1e}"]
    if doc["hypotheses"]:
        lines += ["", "## Design hypotheses", "", "| hypothesis | verdict | why |", "|---|---|---|"]
        lines += [_row(h["id"], h["verdict"], h["reason"]) for h in doc["hypotheses"]]
    if doc["identification"]:
        i = doc["identification"]
        lines += ["", "## Identification", "", f"rank {i['rank']} of {i['unknowns']}, condition number "
                  f"{i['condition_number']:.3g}", ""]
        for key in ("identification", "validation"):
            if i.get(key):
                lines.append(f"* {key}: mean {um(i[key]['mean'])}, max {um(i[key]['max'])}, RMS {um(i[key]['rms'])}")
        lines += ["", "| parameter | unit | estimate | std | sig. |", "|---|---|---|---|---|"]
        lines += [_row(p["name"], p["unit"], f"{p['estimate']:.4g}", number(p["std"], ".2g", "-"),
                       significance(p["estimate"], p["std"])) for p in i["parameters"] if p["identifiable"]]
    if doc["diagnosis"]:
        d = doc["diagnosis"]
        lines += ["", "## Sim-to-real gap", "", f"gap significant: {d['gap_significant']}; selected: "
                  f"{', '.join(d['selected']) or 'none'}; answer: {d.get('outcome', '-')}"
                  + (f" (confidence {d['confidence']})" if d.get("confidence") else ""),
                  *(["", d["verdict"]["evidence"]] if (d.get("verdict") or {}).get("evidence") else []), "",
                  "| candidate effect | CV RMS (µm) | ΔBIC vs rigid |", "|---|---|---|"]
        lines += [_row(r["effect"], um(r["cv_rms"]).replace(" µm", ""), number(r["criterion"], ".1f", "-"))
                  for r in d["ranking"]]
    lines += ["", "## Defects per joint", "", "| joint | parameter | unit | tolerance | class |", "|---|---|---|---|---|"]
    for j in doc["joints"]:
        for p in j["parameters"]:
            lines.append(_row(j["element"], p["name"], p["unit"], p["tolerance_id"] or "-", p["class"]))
    lines += ["", "## Glossary", ""] + [f"* **{k}**: {v}" for k, v in glossary(doc)]
    lines += ["", "## Appendix: normalisation components (not tolerances)", ""]
    lines += [f"* {a['name']} (joint {a['element']})" for a in tol["appendix"]["normalisation"]] or ["* none"]
    from hyperstat.cad_plugin.report_parts import parts_markdown

    lines += parts_markdown(doc)
    return micro("\n".join(lines) + "\n")
