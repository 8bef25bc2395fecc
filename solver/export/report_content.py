"""Content of the tolerance report: the pipeline's results as one JSON-ready document.

Units: lengths in mm, angles in rad (stated in the document's ``units`` field).

The renderers (:mod:`hyperstat.cad_plugin.report`: HTML with inline images, Markdown) only lay out
this document, so ``report.json``, ``report.md`` and ``report.html`` say the same thing.
Every defect parameter gets one *tolerance class*:

* ``forced``: forced to zero by the over-constraint: an assembly condition, held by
  manufacturing (or the machine assembles only by deforming);
* ``coupled``: free only together with others (a relation holds);
* ``compensable``: free and influential, and a position calibration identifies it (or
  the combination that absorbs it): its tolerance can be loose if the machine is calibrated;
* ``accuracy-critical``: free and influential but invisible to a position calibration
  (it moves the tool's orientation only, or is swamped): its tolerance sets the accuracy;
* ``non-influent``: moves nothing at the tool: the loosest tolerance;
* ``gauge``: a naming redundancy of the formalism (no physical meaning).
"""

from __future__ import annotations

import numpy as np

__all__ = ["TOLERANCE_CLASSES", "tolerance_classes", "report_document", "relation_mathml", "identifiable_by_design"]

TOLERANCE_CLASSES = {
    "forced": "forced by over-constraint (assembly condition: manufacturing must hold it)",
    "coupled": "coupled with others through a relation",
    "compensable": "compensable by calibration (identified from tracker positions)",
    "accuracy-critical": "accuracy-critical (influential, not identifiable from positions)",
    "non-influent": "non-influent (moves nothing at the tool)",
    "gauge": "gauge (naming redundancy, no physical meaning)",
}


def tolerance_classes(analysis, identifiable: set) -> dict:
    """Tolerance class of every defect parameter (see the module docstring).

    Parameters
    ----------
    analysis : StationarityResult
        The stationarity analysis.
    identifiable : set of str
        Defects a position calibration sees (base parameters and those absorbed in a
        combination).
    """
    out = {}
    for p in analysis.parameters:
        if p.verdict in ("gauge", "forced"):
            out[p.name] = p.verdict
        elif p.verdict == "coupled" and p.name not in identifiable:
            out[p.name] = "coupled"
        elif not p.influential:
            out[p.name] = "non-influent"
        elif p.name in identifiable:
            out[p.name] = "compensable"
        else:
            out[p.name] = "accuracy-critical"
    return out


def relation_mathml(relation) -> str:
    """A relation as presentation MathML (sympy), e.g. ``dK21 - dK23 = 0``."""
    import sympy

    terms = []
    for name, coefficient in relation.terms.items():
        c = sympy.nsimplify(coefficient, rational=True, tolerance=1e-9)
        symbol = sympy.Symbol(name)
        terms.append(c * symbol)
    expr = sympy.Eq(sympy.Add(*terms), 0)
    return sympy.printing.mathml(expr, printer="presentation")


def report_document(mechanism, provenance: dict, analysis, checks=None, hypotheses=None, identification=None,
                    diagnosis=None, design_identifiable: set | None = None, accuracy: dict | None = None) -> dict:
    """The report as a JSON-ready dictionary (units: mm, rad).

    Parameters
    ----------
    mechanism, provenance : Mechanism, dict
        The model and where it came from.
    analysis : StationarityResult
        Stationarity analysis.
    checks : list of Check, optional
        Nonlinear verification of the verdicts.
    hypotheses : list of HypothesisVerdict, optional
    identification : IdentificationResult, optional
    diagnosis : Diagnosis, optional
    design_identifiable : set of str, optional
        Identifiable defects from a design Jacobian when no data are given.
    accuracy : dict, optional
        Accuracy coefficients and allocation (``hyperstat accuracy`` JSON).
    """
    if identification is not None:
        seen = {p["name"] for p in identification.parameters if p["identifiable"]}
        seen |= {u["name"] for u in identification.unidentifiable if u["combination"]}
    else:
        seen = set(design_identifiable or ())
    classes = tolerance_classes(analysis, seen)
    counts = {k: sum(1 for v in classes.values() if v == k) for k in TOLERANCE_CLASSES}
    checks_by = {c.subject: c for c in (checks or []) if c.kind in ("parameter", "gauge")}
    joints = []
    by_element: dict = {}
    for p in analysis.parameters:
        by_element.setdefault(p.element, []).append(p)
    kinds = {el.name: (getattr(el, "type", "F"), getattr(el, "role", "fixed")) for ch in mechanism.chains
             for el in ch.elements}
    for element, params in by_element.items():
        jt, role = kinds.get(element, ("F", "fixed"))
        rows = []
        for p in params:
            row = {"name": p.name, "component": p.component, "unit": p.unit, "verdict": p.verdict,
                   "influential": p.influential, "class": classes[p.name], "reason": p.reason}
            if p.name in checks_by:
                c = checks_by[p.name]
                row["check"] = {"confirmed": c.confirmed, "residual_mm": c.residual}
            rows.append(row)
        joints.append({"element": element, "type": jt, "role": role, "parameters": rows})
    doc = {
        "units": {"length": "mm", "angle": "rad"},
        "mechanism": mechanism.name,
        "source": provenance,
        "summary": {
            "parameters": len(analysis.parameters),
            "mobility": analysis.mobility,
            "overconstraint": analysis.overconstraint,
            "rank": analysis.rank,
            "singular_value_gap": analysis.gap,
            "verdicts": analysis.counts(),
            "tolerance_classes": counts,
            "verified": None if checks is None else {"confirmed": sum(c.confirmed for c in checks),
                                                     "total": len(checks)},
        },
        "tolerance_class_meaning": TOLERANCE_CLASSES,
        "joints": joints,
        "forced": [p.name for p in analysis.parameters if p.verdict == "forced"],
        "relations": [{"text": r.text, "terms": r.terms, "mathml": relation_mathml(r)} for r in analysis.relations],
        "hypotheses": None if hypotheses is None else [h.to_dict() for h in hypotheses],
        "accuracy": accuracy,
        "identification": None if identification is None else {
            k: v for k, v in identification.to_dict().items() if k != "correlations"},
        "diagnosis": None if diagnosis is None else _diagnosis_summary(diagnosis),
    }
    return doc


def _diagnosis_summary(diag) -> dict:
    d = diag.to_dict()
    where = dict(d["where"])
    where["spectra"] = [{k: v for k, v in s.items() if k not in ("periods_mm", "power")} for s in where["spectra"]]
    d["where"] = where
    return d


def identifiable_by_design(model, mechanism, poses: np.ndarray) -> set:
    """Defects a position calibration at ``poses`` would see (design Jacobian, nominal model)."""
    from hyperstat.solver.calibration.identify import _column_scale, base_parameters
    from hyperstat.solver.calibration.measurements import MeasurementSet
    from hyperstat.solver.calibration.virtual import default_tracker

    k = len(poses)
    data = MeasurementSet([str(i) for i in range(k)], [], poses, np.zeros((k, 3)))
    theta = model.initial(default_tracker(model.kin), np.array([12.0, -8.0, -25.0]))
    pred = model.predict(theta, data, jacobian=True)
    jac = pred.jacobian.reshape(-1, model.n) * _column_scale(model)
    preferred = [j for j, kind in enumerate(model.kinds) if kind in ("tracker", "target")]
    base, rank, _, visible = base_parameters(jac, preferred)
    seen = {model.names[j] for j in base if model.kinds[j] == "geometry"}
    # non-base columns that the base spans are seen in combination
    jb = jac[:, base]
    for j in range(model.n):
        if j in base or not visible[j] or model.kinds[j] != "geometry":
            continue
        coef, *_ = np.linalg.lstsq(jb, jac[:, j], rcond=None)
        if np.linalg.norm(jb @ coef - jac[:, j]) < 1e-6 * np.linalg.norm(jac[:, j]):
            seen.add(model.names[j])
    # coupled pivots follow their coordinates
    names, matrix = model.analysis.parameterization(mechanism, influential_only=True)
    index = mechanism.parameter_index
    for p in mechanism.parameters:
        col = matrix[index[p.name]]
        if p.name not in names and np.any(col) and all(names[i] in seen for i in np.nonzero(col)[0]):
            seen.add(p.name)
    return seen
