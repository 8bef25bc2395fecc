"""Headless scenario run by ``freecadcmd`` (not by pytest): insert, analyse, save, reopen.

Units: lengths in mm, angles in rad.

Environment: ``HYPERSTAT_SCENARIO_TEMPLATE`` (a shipped template's name, or a template file's path) and
``HYPERSTAT_SCENARIO_OUT`` (a folder).  Writes ``OUT/result.json`` with the state of
the skeleton after the analysis and again after saving, closing and reopening the
document; exits 0, or 1 with the traceback in ``result.json`` (``freecadcmd`` would
otherwise run a failing script twice and exit 0).
"""

import json
import os
import shutil
import sys
import time
import traceback

TEMPLATE = os.environ["HYPERSTAT_SCENARIO_TEMPLATE"]
OUT = os.environ["HYPERSTAT_SCENARIO_OUT"]


def state(sk):
    """What the test compares: proxy, parameters, stored results, marker poses, class spheres and callouts."""
    import hyperstat_freecad as hs

    markers = {node: list(part.getGlobalPlacement().toMatrix().A) for node, part in hs.markers(sk).items()}
    spheres = {}
    for element, sphere in hs.class_spheres(sk).items():
        parent = [p for p in sphere.InList if getattr(p, "HyperstatRole", "") == "marker"]
        spheres[element] = {
            "class": sphere.HyperstatClass,
            "color": list(sphere.HyperstatColor)[:3],
            "marker": parent[0].HyperstatNode if parent else None,
            "center": list(sphere.getGlobalPlacement().Base),
            "radius": sphere.Shape.BoundBox.XLength / 2,
        }
    return {
        "proxy": type(sk.Proxy).__name__,
        "proxy_module": type(sk.Proxy).__module__,
        "proxy_state": sk.Proxy.__getstate__(),
        "type_id": sk.TypeId,
        "status": sk.Status,
        "mechanism": sk.Mechanism,
        "summary": sk.Summary,
        "parameters": hs.current_parameters(sk),
        "expressions": dict(sk.ExpressionEngine),
        "spreadsheet": sk.Spreadsheet.Name if sk.Spreadsheet else None,
        "analysis": hs.results(sk),
        "tolerances": hs.tolerances(sk),
        "tolerance_counts": dict(sk.ToleranceCounts),
        "parameter_classes": dict(sk.ParameterClasses),
        "callouts": {k: list(v.LabelText) for k, v in hs.callout_labels(sk).items()},
        "mobility": sk.Mobility,
        "overconstraint": sk.Overconstraint,
        "marker_size": sk.MarkerSize.Value,
        "markers": markers,
        "spheres": spheres,
        "needs_rebuild": hs.needs_rebuild(sk),
    }


def main():
    import FreeCAD

    import hyperstat_freecad as hs

    result = {"template": TEMPLATE, "timings": {}}
    t = time.monotonic()
    doc = FreeCAD.newDocument("scenario")
    sk = hs.insert_skeleton(doc, TEMPLATE)
    result["timings"]["insert_s"] = time.monotonic() - t
    t = time.monotonic()
    hs.analyze(sk)
    result["timings"]["analyze_s"] = time.monotonic() - t
    shutil.copy(hs.work_dir(sk) / "analysis.json", os.path.join(OUT, "solver_analysis.json"))
    result["before"] = state(sk)
    if TEMPLATE == "tripteor_x7":  # the headless report export of the issue: done, or told absent
        try:
            result["report"] = str(hs.export_report(sk, os.path.join(OUT, "report")))
        except hs.CommandMissing as exc:
            result["report_missing"] = str(exc)
    path = os.path.join(OUT, "scenario.FCStd")
    doc.saveAs(path)
    FreeCAD.closeDocument(doc.Name)
    t = time.monotonic()
    doc = FreeCAD.openDocument(path)
    result["timings"]["reopen_s"] = time.monotonic() - t
    found = hs.skeletons(doc)
    result["skeletons_after_reopen"] = [o.Name for o in found]
    result["after"] = state(found[0])
    FreeCAD.closeDocument(doc.Name)
    return result


# freecadcmd runs this file with a __name__ other than "__main__": run at import
os.makedirs(OUT, exist_ok=True)
_code = 1
try:
    _out = main()
    _code = 0
except BaseException:  # noqa: BLE001 - reported through result.json and the exit code
    _out = {"template": TEMPLATE, "error": traceback.format_exc()}
with open(os.path.join(OUT, "result.json"), "w", encoding="utf-8") as fh:
    json.dump(_out, fh, indent=1, sort_keys=True)
sys.exit(_code)
