"""Verdict classes and their colours, read from a ``hyperstat analyze --json`` output.

Units: the analysis is in mm and rad; nothing here depends on them.

Pure Python (no FreeCAD import) so that the project's tests can check that these
colours and this classification stay identical to :data:`cad_plugin.assembly.VERDICT_COLORS`
and :func:`cad_plugin.assembly.element_verdicts`: FreeCAD runs its own Python and cannot
import the project's package, so the table is repeated here and guarded by a test.
"""

from __future__ import annotations

__all__ = ["VERDICT_COLORS", "VERDICT_ORDER", "VERDICT_TEXT", "TOLERANCE_CLASSES", "parameter_class", "tolerance_class",
           "element_verdicts", "verdict_counts"]

#: the tolerance classes of the analysis JSON (``tolerances.parameters[name]["class"]``, one vocabulary for the
#: whole project, hyperstat.solver.tolerances.classification.CLASSES); "normalisation" is not a tolerance
TOLERANCE_CLASSES = ("assembly", "accuracy-critical", "compensable", "non-influent", "normalisation")

#: colour per verdict class (RGB in 0..1), the same as cad_plugin/assembly.py
VERDICT_COLORS: dict[str, tuple[float, float, float]] = {
    "forced": (0.85, 0.1, 0.6),  # magenta
    "coupled": (1.0, 0.55, 0.0),  # orange
    "free-influential": (0.0, 0.7, 0.8),  # cyan
    "free-non-influent": (0.55, 0.55, 0.55),  # grey
    "none": (0.95, 0.95, 0.95),  # no defect / gauge only
}
#: most severe first: an element takes the most severe class of its parameters
VERDICT_ORDER = ["forced", "coupled", "free-influential", "free-non-influent", "none"]
VERDICT_TEXT = {
    "forced": "forced to zero by the over-constraint",
    "coupled": "coupled with other defects (see the relations)",
    "free-influential": "free and influential (calibration can see it)",
    "free-non-influent": "free and non-influent (no effect on the tool pose)",
    "none": "gauge only (no geometric meaning)",
}


def parameter_class(parameter: dict) -> str:
    """Verdict class of one parameter entry of an analysis JSON (a normalisation component or a redundant shift,
    ``gauge`` in older files, maps to ``none``)."""
    verdict = parameter.get("verdict")
    if verdict in ("gauge", "normalisation", "redundant"):
        return "none"
    if verdict == "free":
        return "free-influential" if parameter.get("influential") else "free-non-influent"
    if verdict in ("forced", "coupled"):
        return verdict
    raise ValueError(f"analysis parameter '{parameter.get('name')}': unknown verdict '{verdict}'.")


def element_verdicts(analysis: dict | None) -> dict[str, str]:
    """Verdict class per element (joint or fixed transform): the most severe of its parameters."""
    out: dict[str, str] = {}
    for p in (analysis or {}).get("parameters", []):
        cls = parameter_class(p)
        element = p["element"]
        if element not in out or VERDICT_ORDER.index(cls) < VERDICT_ORDER.index(out[element]):
            out[element] = cls
    return out


def verdict_counts(analysis: dict) -> dict[str, int]:
    """Number of parameters per verdict class."""
    counts = dict.fromkeys(VERDICT_ORDER, 0)
    for p in analysis.get("parameters", []):
        counts[parameter_class(p)] += 1
    return counts


def tolerance_class(analysis: dict | None, parameter: dict) -> str:
    """The class to show for a parameter: its tolerance class when the analysis JSON has one
    (``tolerances.parameters[name]["class"]``, e.g. "assembly", "compensable"), else its verdict class.

    >>> tolerance_class({"tolerances": {"parameters": {"a": {"class": "compensable"}}}}, {"name": "a"})
    'compensable'
    >>> tolerance_class({}, {"name": "a", "verdict": "forced"})
    'forced'
    """
    table = ((analysis or {}).get("tolerances") or {}).get("parameters") or {}
    entry = table.get(parameter.get("name")) if isinstance(table, dict) else None
    if isinstance(entry, dict) and entry.get("class"):
        return str(entry["class"])
    return parameter_class(parameter)
