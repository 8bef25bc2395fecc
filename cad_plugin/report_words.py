"""What the printed report says in words: title block, glossary, values, significance, where, contributors.

Units: lengths in mm, angles in rad (the report's units); residuals and noise printed in µm.

The HTML (:mod:`hyperstat.cad_plugin.report_html`) and Markdown
(:mod:`hyperstat.cad_plugin.report_markdown`) renderers lay out the same sentences from here,
so both say the same thing.  Printed tolerance values are rounded to the safe side (down: a
tolerance printed larger than computed would let a part out of spec pass).
"""

from __future__ import annotations

import math
import re

__all__ = ["number", "micro", "safe_round", "tolerance_value", "calibrated_value", "um", "significance", "SIGNIFICANCE",
           "coefficient_words", "glossary", "title_rows", "where_words", "contributor_groups", "spec_text",
           "values_note", "frames_of", "display_path", "bounds_lines", "limit_lines", "calibration_words",
           "other_warnings", "practical_size_rows", "CAMPAIGN_WARNING"]

#: significance marks of an estimate (|estimate| / its standard deviation), strongest first
SIGNIFICANCE = (("**", 3.0, "significant: the estimate is at least 3 standard deviations from zero"),
                ("*", 2.0, "marginal: between 2 and 3 standard deviations from zero"),
                ("n.s.", 0.0, "not significant: within 2 standard deviations of zero (zero is plausible)"))


def micro(text: str) -> str:
    """Free text from the JSON with its micro-units spelled as units: ``um`` -> ``µm``, ``urad`` -> ``µrad``.

    >>> micro("clearance 0 to 10 um, i.e. +-5 um; 2 um and 20 urad; a drum")
    'clearance 0 to 10 µm, i.e. +-5 µm; 2 µm and 20 µrad; a drum'
    """
    text = re.sub(r"\bum\b", "\u00b5m", text)
    return re.sub(r"(\d)\s?urad\b", "\\1 \u00b5rad", text)


def safe_round(value: float, digits: int = 3) -> float:
    """``value`` rounded towards zero to ``digits`` significant digits (a tolerance printed never exceeds it).

    >>> safe_round(0.040893), safe_round(1.35e-5), safe_round(0.0)
    (0.0408, 1.35e-05, 0.0)
    """
    if value == 0 or not math.isfinite(value):
        return value
    scale = 10.0 ** (digits - 1 - math.floor(math.log10(abs(value))))
    return math.floor(abs(value) * scale * (1 + 1e-12)) / scale * (1 if value > 0 else -1)


def _g(value: float) -> str:
    return f"{safe_round(value):.3g}"


def tolerance_value(item: dict, key: str = "value") -> str:
    """``"± 0.0408 mm"`` (the safe-side value of ``item[key]``), ``"-"`` when there is none.

    >>> tolerance_value({"value": 0.040893, "unit": "mm"})
    '± 0.0408 mm'
    """
    v = item.get(key)
    return "-" if v is None else f"± {_g(float(v))} {item.get('unit', '')}".rstrip()


def calibrated_value(item: dict) -> str:
    """The with-calibration value of a compensable tolerance and what limits it, or ``"-"``.

    >>> calibrated_value({"value_with_calibration": 0.12, "unit": "mm", "value_with_calibration_limit": "actuator stroke"})
    '± 0.12 mm (actuator stroke)'
    """
    if item.get("value_with_calibration") is None:
        return "-"
    limit = item.get("value_with_calibration_limit")
    return tolerance_value(item, "value_with_calibration") + (f" ({limit})" if limit else "")


def number(value, spec: str, missing: str = "not finite") -> str:
    """``value`` formatted with ``spec``, or ``missing`` where the JSON holds no number (an infinity or a NaN
    becomes ``null`` in JSON: a worst case that diverged, an optimiser tolerance that is unknown).

    >>> number(0.123456, ".3g"), number(None, ".3g"), number(None, ".1g", "unknown")
    ('0.123', 'not finite', 'unknown')
    """
    return missing if value is None else format(value, spec)


def um(mm) -> str:
    """A length in mm printed in µm (one decimal), ``"-"`` for none.

    >>> um(0.0091)
    '9.1 µm'
    """
    return "-" if mm is None else f"{1000.0 * float(mm):.1f} µm"


def significance(estimate: float, std) -> str:
    """The mark of an estimate: ``**`` (>= 3 std from zero), ``*`` (2 to 3), ``n.s.`` (below 2), ``-`` (no std).

    >>> significance(-1.32, 1.46), significance(0.02, 0.0015), significance(0.5, 0.2), significance(1.0, None)
    ('n.s.', '**', '*', '-')
    """
    if std is None or not std > 0:
        return "-"
    z = abs(float(estimate)) / float(std)
    return next(mark for mark, threshold, _ in SIGNIFICANCE if z >= threshold)


_WHAT = {"delta": ("rotation of the platform", "rad"), "epsilon": ("displacement of the platform point", "mm")}
_CAUSE = {"fP": ("errors of the prismatic actuators", "mm"), "fR": ("errors of the revolute actuators", "rad"),
          "gP": ("geometric length defects (da, db, dc)", "mm"), "gR": ("geometric angle defects (dI, dJ, dK)", "rad")}


def coefficient_words(name: str) -> str:
    """An accuracy coefficient of paper 2 (eq. 18) in words.

    >>> coefficient_words("epsilon_gR")
    'largest displacement of the platform point (mm) per rad of geometric angle defects (dI, dJ, dK)'
    """
    m = re.fullmatch(r"(delta|epsilon)_([fg][PR])", name)
    if not m:
        return name
    (what, unit), (cause, per) = _WHAT[m.group(1)], _CAUSE[m.group(2)]
    return f"largest {what} ({unit}) per {per} of {cause}"


def spec_text(spec: dict) -> str:
    """``"position ± 0.05 mm, orientation ± 0.0002 rad"``."""
    parts = []
    if spec.get("position_mm") is not None:
        parts.append(f"position ± {spec['position_mm']:g} mm")
    if spec.get("orientation_rad") is not None:
        parts.append(f"orientation ± {spec['orientation_rad']:g} rad")
    return ", ".join(parts) or "none declared"


def display_path(path: str | None) -> str:
    """A source path as the report prints it: relative to the working folder when below it, else its name.

    >>> display_path("/nowhere/designs/my_3rrr.py")
    'my_3rrr.py'
    """
    import os
    from pathlib import Path

    if not path:
        return "-"
    p = Path(path)
    if not p.is_absolute():
        return p.as_posix()
    try:
        return p.resolve().relative_to(Path(os.getcwd()).resolve()).as_posix()
    except ValueError:
        return p.name


def title_rows(doc: dict) -> list[tuple[str, str]]:
    """The title block: (label, value) in the order printed."""
    title = doc["title"]
    params = ", ".join(f"{k} = {v:g}" if isinstance(v, (int, float)) else f"{k} = {v}"
                       for k, v in (title.get("parameters") or {}).items())
    meas = title.get("measurements") or {}
    targets = len(meas.get("targets_mm") or [])
    return [("mechanism", f"{title['mechanism']}: {title.get('description') or ''}".rstrip(": ")),
            (title.get("kind") or "source", str(title.get("template") or "-")),
            ("parameters", params or "-"),
            ("source SHA-256", title.get("source_sha256") or "-"),
            ("hyperstat", str(title.get("hyperstat_version") or "-")),
            ("date", str(title.get("date") or "-")),
            ("revision", str(title.get("revision") or "-")),
            ("task", ", ".join(title.get("task") or [])),
            ("spec", spec_text(title.get("spec") or {})),
            ("calibration", calibration_words(meas, (doc.get("tolerances") or {}).get("warnings") or [])),
            *practical_size_rows((doc.get("tolerances") or {}).get("warnings") or []),
            ("units", "lengths mm, angles rad, residuals µm; ± values are symmetric tolerances, rounded down")]


#: the classification's warning that the declared calibration campaign is not the one hyperstat's calibration runs
CAMPAIGN_WARNING = "CALIBRATION CAMPAIGN: "


def calibration_words(meas: dict, warnings: list) -> str:
    """The declared calibration campaign in a line, followed by the classification's warning when hyperstat's own
    calibration (identify, export-controller) fits what the declaration holds and that matters: the title block
    carries it whole, on page 1, and the warnings' lists leave it out (:func:`other_warnings`).

    >>> meas = {"kind": "positions", "targets_mm": [[0, 0, 0]], "noise_mm": 0.002, "frame": "registered",
    ...         "offsets": "known"}
    >>> calibration_words(meas, [])
    'positions of 1 target(s), noise 2.0 µm, tracker frame registered, target offsets known (declared)'
    >>> calibration_words(meas, ["CALIBRATION CAMPAIGN: identify fits them."])[-46:]
    'known (declared). WARNING: identify fits them.'
    """
    targets = len(meas.get("targets_mm") or [])
    text = f"{meas.get('kind', '-')} of {targets} target(s), noise {um(meas.get('noise_mm'))}"
    if meas.get("frame"):
        text += (f", tracker frame {meas['frame']}, target offsets "
                 f"{'known' if meas.get('offsets') == 'known' else 'identified'} (declared)")
    return text + "".join(f". WARNING: {w[len(CAMPAIGN_WARNING):]}" for w in warnings
                          if w.startswith(CAMPAIGN_WARNING))


def practical_size_rows(warnings: list) -> list[tuple[str, str]]:
    """The title block's row of the classification's warning that frames state zones below what any workshop holds
    (:data:`hyperstat.solver.tolerances.drawing.PRACTICAL_SIZE_WARNING`); none without it.

    >>> practical_size_rows(["PRACTICAL SIZE: 1 frame of 2 states a zone below 0.3 µm."])
    [('drawing', 'WARNING: 1 frame of 2 states a zone below 0.3 µm.')]
    >>> practical_size_rows(["the worst case was still rising"])
    []
    """
    from hyperstat.solver.tolerances.drawing import PRACTICAL_SIZE_WARNING

    return [("drawing", f"WARNING: {w[len(PRACTICAL_SIZE_WARNING):]}") for w in warnings
            if w.startswith(PRACTICAL_SIZE_WARNING)]


def other_warnings(warnings: list) -> list:
    """The classification's warnings but the calibration campaign's and the practical size's (the title block
    carries them)."""
    from hyperstat.solver.tolerances.drawing import PRACTICAL_SIZE_WARNING

    return [w for w in warnings if not w.startswith((CAMPAIGN_WARNING, PRACTICAL_SIZE_WARNING))]


def frames_of(item: dict) -> list[dict]:
    """The ISO 1101 callouts of a tolerance item (its ``drawing`` list; empty when the JSON has none)."""
    return [c for c in item.get("drawing") or [] if isinstance(c, dict)]


_ACTUATED = re.compile(r"actuated joint (\S+) at its (lower|upper) workspace bound")


def where_words(worst: dict, joint_types: dict) -> str:
    """Where a worst case lies, in words: the kind of place and the actuated joints with their units.

    >>> where_words({"location": "interior", "actuated": {"1": 1.2027}, "where": "interior at 1=1.20271"}, {"1": "R"})
    'inside the workspace: joint 1 = 1.203 rad'
    """
    location = {"interior": "inside the workspace", "boundary": "on the workspace boundary",
                "constant": "the same everywhere in the workspace", "edge": "on an edge of the workspace",
                "corner": "at a corner of the workspace"}.get(str(worst.get("location")), str(worst.get("location", "")))
    actuated = worst.get("actuated") or {}
    if not actuated:
        return location
    bounds = dict(_ACTUATED.findall(str(worst.get("where", ""))))
    parts = []
    for joint, value in actuated.items():
        unit = "mm" if joint_types.get(str(joint)) == "P" else "rad"
        text = f"joint {joint} = {float(value):.4g} {unit}"
        if joint in bounds:
            text += f" ({bounds[joint]} bound)"
        parts.append(text)
    return f"{location}: " + ", ".join(parts)


def contributor_groups(mc: dict, items: list, joint_types: dict, limit: int = 12) -> tuple[list, list]:
    """Monte Carlo contributors as tolerances (id, what it is) and the actuator errors, each group by share.

    Returns two lists of dicts (``label``, ``what``, ``position_share``, ``orientation_share``,
    ``tolerance``, ``unit``).
    """
    by_id = {t["id"]: t for t in items}
    tolerances, actuators = [], []
    for c in mc.get("contributors", []):
        key = str(c.get("parameter"))
        row = {"position_share": float(c.get("position_share") or 0.0),
               "orientation_share": float(c.get("orientation_share") or 0.0), "tolerance": c.get("tolerance")}
        if key in by_id:
            t = by_id[key]
            row.update(label=f"{key} {t['statement']}", what=f"{t.get('words', '')}, {t.get('feature', '')}".strip(", "),
                       unit=t.get("unit", ""))
            tolerances.append(row)
        else:
            unit = "mm" if joint_types.get(key) == "P" else "rad"
            row.update(label=f"actuator of joint {key}", what=f"actuation error of joint {key} ({unit})", unit=unit)
            actuators.append(row)
    def order(r):
        return -(r["position_share"] + r["orientation_share"])

    return sorted(tolerances, key=order)[:limit], sorted(actuators, key=order)


def values_note(doc: dict) -> str:
    """Why the same coefficient can show two maxima (task-restricted allocation against the full coefficient)."""
    coefficients = (doc.get("accuracy") or {}).get("coefficients") or {}
    task = ", ".join((doc.get("title") or {}).get("task") or [])
    pairs = []
    for w in doc.get("worst_cases") or []:
        full = coefficients.get(w["coefficient"])
        if full and full["max"] is not None and w["max"] is not None and \
                abs(full["max"] - w["max"]) > 1e-3 * max(abs(full["max"]), 1e-12):
            pairs.append(f"{w['coefficient']} {w['max']:.3g} (task) and {full['max']:.3g} (all components)")
    if not pairs:
        return ""
    return ("The allocation's coefficients are restricted to the task's components (" + task + ") and maximised over "
            "the declared workspace; the table of coefficients takes every component of the platform's motion over "
            "the accuracy sample: hence " + "; ".join(sorted(set(pairs))) + ".")


def glossary(doc: dict) -> list[tuple[str, str]]:
    """Every coefficient, abbreviation and mark the report uses, in words (term, meaning)."""
    meaning = dict(doc.get("tolerance_class_meaning") or {})
    rows = [("Tn", "the n-th tolerance of the table on page 1; the skeleton picture calls the joints out with these "
                   "ids")]
    rows += [(cls, text) for cls, text in meaning.items()]
    rows += [("redundant", "a shift along a joint's own axis that is the same physical shift as the next joint's: "
                           "shown merged with its equivalent (\u2261), never as harmless"),
             ("normalisation", "the component of an axis change along the nominal axis: keeps the axis a unit vector, "
                               "no geometric meaning (appendix)"),
             ("dI, dJ, dK", "tilt of a joint axis: changes of the x, y, z components of its direction (rad); the "
                            "number after the letters is the joint (paper 1, Fig. 1)"),
             ("da, db, dc", "shift of a joint's axis point along x, y, z of the previous frame (mm)"),
             ("statement", "the combination of defect parameters a tolerance bounds; an assembly condition is a "
                           "relation that must stay zero"),
             ("without calibration", "the value that keeps the spec on a machine that is not calibrated"),
             ("with calibration", "compensable tolerances: the largest defect that calibration from the declared "
                                  "measurements and the controller's compensation still keep within the spec, and "
                                  "what limits it"),
             ("drawing value", "the value the drawing carries: with calibration when the template declares one"),
             ("feature control frame", "the ISO 1101 box: characteristic symbol, zone width in mm (\u2300 for a "
                                        "cylindrical zone) and datums in order of precedence"),
             ("datum", "the reference feature (a joint axis) a geometric tolerance is measured from, named by a "
                       "letter")]
    for name in ("delta_fP", "delta_fR", "delta_gP", "delta_gR", "epsilon_fP", "epsilon_fR", "epsilon_gP",
                 "epsilon_gR"):
        rows.append((name, coefficient_words(name) + "; the largest gain over every combination of errors of unit "
                           "size (largest singular value, paper 2 eq. 18)"))
    rows += [("worst case", "the largest value over the declared workspace, found by an optimiser from the best "
                            "samples; 'sampled max' is the largest of the samples alone"),
             ("optimiser tol.", "how far the optimiser's maximum may still be below the true one"),
             ("3\u03c3", "three standard deviations: what the measurement noise leaves at most in 99.7 % of cases"),
             ("RMS", "root mean square of the residuals (the typical size of an error)"),
             ("rank, singular-value gap", "number of independent constraints on the defects, and the ratio between "
                                          "the last kept and the first dropped singular value (large: a clear-cut "
                                          "rank)"),
             ("condition number", "how much measurement noise is amplified in the identified parameters")]
    rows += [(mark, words) for mark, _, words in SIGNIFICANCE]
    if doc.get("diagnosis"):
        rows += [("gap test", "chi-squared test of the residuals against the measurement noise: a p-value below the "
                              "threshold says the rigid model misses something"),
                 ("p-value", "probability of residuals at least this large if the model and the noise were right"),
                 ("CV RMS", "RMS error on data left out of the fit (blocked cross-validation): lower is better"),
                 ("\u0394BIC", "Bayesian information criterion relative to the rigid model: fit quality penalised "
                               "by the number of added parameters; negative is better than the rigid model"),
                 ("structure test", "F-test of a harmonic error against the residual spectrum, per joint and "
                                    "frequency")]
    if doc.get("montecarlo"):
        rows += [("out of spec", "share of the Monte Carlo samples whose task error exceeds the spec"),
                 ("linear worst case", "every tolerance at its extreme in the worst direction (triangle inequality): "
                                       "a bound the samples never exceed")]
    return rows


def _ids(items: list) -> str:
    """``"T16-T19, T22"``: the items' tolerance ids, consecutive ids as ranges."""
    from hyperstat.cad_plugin.palette import callout_text

    return callout_text("", [t["id"] for t in items]).lstrip(": ")


def _grouped(items: list, key) -> list:
    """``[(key value, items)]`` in the order of first appearance, items with an equal key together."""
    groups: dict = {}
    for t in items:
        groups.setdefault(key(t), []).append(t)
    return list(groups.items())


def bounds_lines(items: list) -> list[str]:
    """One line per distinct pair of linear bounds, with the tolerances that share it (their ids as ranges).

    >>> b = {"attainable_linear_worst_case": 0.036, "triangle_bound": 0.0463, "unit": "mm"}
    >>> bounds_lines([{"id": "T16", "bounds": b}, {"id": "T17", "bounds": b}, {"id": "T20", "bounds": None}])
    ['T16-T17: attainable linear worst case 0.036 mm, triangle bound 0.0463 mm']
    """
    def key(t):
        b = t["bounds"]
        return (f"{b['attainable_linear_worst_case']:.3g}", f"{b['triangle_bound']:.3g}", b.get("unit", "mm"))

    return [f"{_ids(group)}: attainable linear worst case {a} {u}, triangle bound {tri} {u}"
            for (a, tri, u), group in _grouped([t for t in items if t.get("bounds")], key)]


#: how a limit of the values together (solver/tolerances/calibrated_together.py) quotes each value's single limit
_ALONE = " (alone: "


def _together_parts(text: str) -> tuple[str, str | None]:
    """``(what the values together cost, the value's single limit)`` of a "workspace loss together" limit; ``(text,
    None)`` for any other."""
    if text.startswith("workspace loss together:") and _ALONE in text and text.endswith(")"):
        head, alone = text.split(_ALONE, 1)
        return head, alone[:-1]
    return text, None


def limit_lines(items: list) -> list[str]:
    """What limits each value with calibration, in full, one line per distinct text with its tolerances' ids.

    The values scaled together share what the budget cost (one line), followed by each value's single limit (one
    line per distinct text): the shared words are not repeated for every tolerance.

    >>> limit_lines([{"id": "T3", "value_with_calibration": 0.3, "value_with_calibration_limit": "noise: a"},
    ...              {"id": "T4", "value_with_calibration": 0.2, "value_with_calibration_limit": "noise: a"}])
    ['T3-T4: noise: a']
    >>> together = "workspace loss together: scaled by 0.5 (alone: {}, workspace loss: stroke)"
    >>> item = lambda tid, v, alone: {"id": tid, "value_with_calibration": v,
    ...                               "value_with_calibration_limit": together.format(alone)}
    >>> for line in limit_lines([item("T7", 0.04, "0.08 mm"), item("T9", 0.04, "0.08 mm"), item("T8", 0.36, "0.72 mm")]):
    ...     print(line)
    T7-T9: workspace loss together: scaled by 0.5; alone, each:
    T7, T9: 0.08 mm, workspace loss: stroke
    T8: 0.72 mm, workspace loss: stroke
    """
    use = [t for t in items if t.get("value_with_calibration") is not None and t.get("value_with_calibration_limit")]
    lines = []
    for head, group in _grouped(use, lambda t: _together_parts(t["value_with_calibration_limit"])[0]):
        if _together_parts(group[0]["value_with_calibration_limit"])[1] is None:
            lines.append(f"{_ids(group)}: {head}")
            continue
        lines.append(f"{_ids(group)}: {head}; alone, each:")
        seen: set = set()
        for alone, same in _grouped(group, lambda t: _together_parts(t["value_with_calibration_limit"])[1]):
            lines.append(f"{_ids(same)}: {_once(alone, seen)}")
    return lines


#: where a limit's words say which workspace-loss budget it is and how to change it (solver/tolerances/calibrated.py)
_BUDGET_SOURCE = re.compile(r" \((declared|the default, assumed); TOLERANCING workspace_loss or --workspace-loss\)")


def _once(text: str, seen: set) -> str:
    """``text`` without the budget's source words when an earlier line gave the same ones (``seen`` holds them).

    >>> seen = set()
    >>> w = "held to 0.3 mm, the workspace-loss budget, 0.1 % (declared; TOLERANCING workspace_loss or --workspace-loss) of"
    >>> _once(w, seen) == w, _once(w, seen)
    (True, 'held to 0.3 mm, the workspace-loss budget, 0.1 % of')
    """
    found = _BUDGET_SOURCE.search(text)
    if not found:
        return text
    if found.group(0) in seen:
        return _BUDGET_SOURCE.sub("", text)
    seen.add(found.group(0))
    return text
