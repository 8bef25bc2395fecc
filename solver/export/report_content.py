"""Content of the tolerance report: the pipeline's results as one JSON-ready document.

Units: lengths in mm, angles in rad (stated in the document's ``units`` field).

The renderers (:mod:`hyperstat.cad_plugin.report`: HTML with inline images, Markdown) only lay out
this document, so ``report.json``, ``report.md`` and ``report.html`` say the same thing.
The tolerances, their classes, values and reasons come from one place,
:mod:`hyperstat.solver.tolerances.classification` (with the values of
:mod:`hyperstat.solver.tolerances.values`): ``assembly``, ``accuracy-critical``,
``compensable``, ``non-influent`` (:data:`~hyperstat.solver.tolerances.classification.CLASSES`);
normalisation components are not tolerances and appear in an appendix.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from hyperstat.solver.tolerances.classification import CLASS_MEANING, CLASSES

__all__ = ["TOLERANCE_CLASSES", "report_document", "relation_mathml", "terms_mathml", "source_hash"]

#: class -> meaning, in the order of the report (the classification's vocabulary)
TOLERANCE_CLASSES = {c: CLASS_MEANING[c] for c in CLASSES}


def source_hash(provenance: dict) -> str | None:
    """SHA-256 of the source file named in ``provenance`` (None when it cannot be read).

    >>> source_hash({"source": "/no/such/file"}) is None
    True
    """
    try:
        return hashlib.sha256(Path(provenance.get("source", "")).read_bytes()).hexdigest()
    except OSError:
        return None


def relation_mathml(relation) -> str:
    """A relation as presentation MathML (sympy), e.g. ``dK21 - dK23 = 0``."""
    return terms_mathml(relation.terms)


def terms_mathml(coefficients: dict) -> str:
    """``sum c_i x_i = 0`` as presentation MathML, e.g. ``dc2 + dc3 = 0``.

    Coefficients print as integers or fractions when they are (to 1e-9), else with six digits.

    >>> terms_mathml({"dc2": 1.0, "dc3": 1.0})
    '<math display="block"><mrow><mi>dc2</mi><mo>+</mo><mi>dc3</mi><mo>=</mo><mn>0</mn></mrow></math>'
    >>> terms_mathml({"dI2": 1.0, "dI6": -0.8})
    '<math display="block"><mrow><mi>dI2</mi><mo>&#8722;</mo><mfrac><mn>4</mn><mn>5</mn></mfrac><mo>&#8290;</mo><mi>dI6</mi><mo>=</mo><mn>0</mn></mrow></math>'
    """
    from fractions import Fraction
    from html import escape

    parts = []
    for k, (name, c) in enumerate(coefficients.items()):
        c = float(c)
        if k == 0:
            if c < 0:
                parts.append("<mo>&#8722;</mo>")
        else:
            parts.append("<mo>&#8722;</mo>" if c < 0 else "<mo>+</mo>")
        mag = abs(c)
        if abs(mag - 1.0) > 1e-12:
            frac = Fraction(mag).limit_denominator(1000)
            if abs(float(frac) - mag) < 1e-9 * max(1.0, mag):
                num = f"<mn>{frac.numerator}</mn>" if frac.denominator == 1 else \
                    f"<mfrac><mn>{frac.numerator}</mn><mn>{frac.denominator}</mn></mfrac>"
            else:
                num = f"<mn>{mag:.6g}</mn>"
            parts.append(num + "<mo>&#8290;</mo>")
        parts.append(f"<mi>{escape(name)}</mi>")
    return '<math display="block"><mrow>' + "".join(parts) + "<mo>=</mo><mn>0</mn></mrow></math>"


def report_document(mechanism, provenance: dict, analysis, checks=None, hypotheses=None, identification=None,
                    diagnosis=None, tolerances=None, accuracy: dict | None = None, montecarlo: dict | None = None) -> dict:
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
    identification : IdentificationResult or dict, optional
        A dict: the report's JSON of it, as a cached report kept it.
    diagnosis : Diagnosis or dict, optional
        A dict: the report's JSON of it (``_diagnosis_summary``), as a cached report kept it.
    tolerances : Classification, optional
        The tolerances (:func:`hyperstat.solver.tolerances.classification.classify`, values filled by
        :func:`hyperstat.solver.tolerances.values.assign_values`); classified here with
        defaults when omitted.
    accuracy : dict, optional
        Accuracy coefficients (``hyperstat accuracy`` JSON).
    montecarlo : dict, optional
        Monte Carlo summary with every tolerance at its value.
    """
    if tolerances is None:
        from hyperstat.solver.tolerances.classification import classify

        tolerances = classify(mechanism, analysis)
    tol = tolerances.to_dict()
    counts = tol["counts"]
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
            entry = tol["parameters"][p.name]
            # one class per parameter (tolerances.parameters'), shown as its verdict too: never the analysis' words
            row = {"name": p.name, "component": p.component, "unit": p.unit, "verdict": entry["class"],
                   "influential": p.influential, "class": entry["class"], "tolerance_id": entry["tolerance_id"],
                   "tolerance_ids": list(entry.get("tolerance_ids") or []),
                   "equivalent": entry.get("equivalent"), "reason": p.reason}
            if p.name in checks_by:
                c = checks_by[p.name]
                row["check"] = {"confirmed": c.confirmed, "residual_mm": c.residual}
            rows.append(row)
        joints.append({"element": element, "type": jt, "role": role, "parameters": rows})
    decl = tol["declaration"]
    spec = tol["allocation"].get("spec") or decl["spec"]
    assembly = []
    for it in tol["items"]:
        if it["class"] == "assembly":
            assembly.append({"id": it["id"], "statement": it["statement"], "mathml": terms_mathml(it["terms"]),
                             "value": it["value"], "unit": it["unit"], "why": it["why"],
                             "value_source": it["value_source"], "feature": it["feature"],
                             "limiting": it["evidence"].get("assemblability", {}).get("limiting", []),
                             "analysis_only_value": it["evidence"].get("assemblability", {}).get("reference_value"),
                             "worst_in": it["evidence"].get("assemblability", {}).get("worst_in"),
                             "where": it["evidence"].get("assemblability", {}).get("where"),
                             "drawing_value": it.get("drawing_value"), "drawing": list(it.get("drawing") or [])})
    alloc = tol.get("allocation") or {}
    worst_cases = [{"allocation": key, "coefficient": name, "max": w["max"], "sampled_max": w["sampled_max"],
                    "optimiser_tolerance": w["optimiser_tolerance"], "location": w["location"], "where": w["where"],
                    "evidence": w["evidence"]}
                   for key in ("calibrated", "uncalibrated") if alloc.get(key)
                   for name, w in alloc[key].get("worst_cases", {}).items()]
    checked = dict(tol.get("checked") or {})
    if alloc.get("assembly_configurations"):
        checked["assembly"] = dict(alloc["assembly_configurations"])
    doc = {
        "units": {"length": "mm", "angle": "rad"},
        "mechanism": mechanism.name,
        "description": mechanism.description,
        "source": provenance,
        "title": {"mechanism": mechanism.name, "description": mechanism.description,
                  "template": provenance.get("source"), "kind": provenance.get("kind"),
                  "parameters": provenance.get("parameters", {}), "source_sha256": source_hash(provenance),
                  "task": list(tol["task"]), "measurements": decl["measurements"], "spec": spec},
        "summary": {
            "parameters": len(analysis.parameters),
            "mobility": analysis.mobility,
            "overconstraint": analysis.overconstraint,
            "rank": analysis.rank,
            "singular_value_gap": analysis.gap,
            "verdicts": analysis.to_dict()["counts"],
            "tolerance_classes": counts,
            "tolerances": len(tol["items"]),
            "normalisation_components": len(tol["appendix"]["normalisation"]),
            "verified": None if checks is None else {"confirmed": sum(c.confirmed for c in checks),
                                                     "total": len(checks)},
        },
        "tolerance_class_meaning": dict(TOLERANCE_CLASSES),
        "tolerances": tol,
        "assembly_conditions": assembly,
        "worst_cases": worst_cases,
        "checked": checked,
        "joints": joints,
        "forced": [p.name for p in analysis.parameters if p.verdict == "forced"],
        "relations": [{"id": a["id"], "text": a["statement"], "terms": it["terms"], "mathml": a["mathml"]}
                      for a, it in zip(assembly, [i for i in tol["items"] if i["class"] == "assembly"])
                      if it["kind"] == "relation"],
        "hypotheses": None if hypotheses is None else [h.to_dict() for h in hypotheses],
        "accuracy": accuracy,
        "montecarlo": montecarlo,
        "calibration": tol["calibration"],
        "identification": _report_identification(identification),
        "diagnosis": _diagnosis_summary(diagnosis),
    }
    doc.update(_part_drawings(tolerances, alloc))
    return doc


def _part_drawings(tolerances, alloc: dict) -> dict:
    """``drawings``, ``assembly_requirements`` and ``whole_drawing`` of ``docs/drawing-format.md``."""
    from hyperstat.solver.tolerances.whole_drawing import whole_drawing_summary

    drawn = getattr(tolerances, "drawings", None) or {}
    return {"drawings": list(drawn.get("drawings") or []),
            "assembly_requirements": list(drawn.get("assembly_requirements") or []),
            "whole_drawing": whole_drawing_summary(alloc.get("whole_drawing") or {}, tolerances)}


def _report_identification(identification) -> dict | None:
    """The report's JSON of an identification (without its correlations); a dict is taken as that JSON (cached)."""
    if identification is None or isinstance(identification, dict):
        return identification
    return {k: v for k, v in identification.to_dict().items() if k != "correlations"}


def _diagnosis_summary(diag) -> dict | None:
    """The report's JSON of a diagnosis; a dict is taken as that JSON (cached)."""
    if diag is None or isinstance(diag, dict):
        return diag
    d = diag.to_dict()
    where = dict(d["where"])
    where["spectra"] = [{k: v for k, v in s.items() if k not in ("periods_mm", "power")} for s in where["spectra"]]
    d["where"] = where
    return d
