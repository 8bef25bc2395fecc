"""Run by ``freecadcmd`` (not by Python directly): insert a template with the workbench and Analyse it, timed.

Units: seconds (s).

``benchmarks/commands.py`` runs this file in ``freecadcmd`` with ``HOME`` in a temporary folder where
the real installer put the workbench (``cad_plugin/freecad/install.py``), as a user's FreeCAD has it.
It times what the user waits for after clicking: *Insert template* (``hyperstat parameters`` and
``hyperstat build``, the STEP import into the document) and *Analyse* (``hyperstat analyze`` and
``hyperstat report``, colouring the markers), through the workbench's own functions
(``insert_skeleton``, ``analyze``), and writes ``{"insert_s": ..., "analyse_s": ...}`` to
``$HYPERSTAT_BENCH_OUT``.  FreeCAD's own start is not counted (the user's FreeCAD is running).

Environment: ``HYPERSTAT_BENCH_TEMPLATE`` (a shipped template's name, default ``tripteor_x7``),
``HYPERSTAT_BENCH_OUT`` (the JSON file to write).
"""

import json
import os
import sys
import time
import traceback

OUT = os.environ["HYPERSTAT_BENCH_OUT"]
TEMPLATE = os.environ.get("HYPERSTAT_BENCH_TEMPLATE", "tripteor_x7")


def main() -> dict:
    import FreeCAD

    import hyperstat_freecad as hs

    doc = FreeCAD.newDocument("bench")
    t = time.perf_counter()
    sk = hs.insert_skeleton(doc, TEMPLATE)
    insert_s = time.perf_counter() - t
    t = time.perf_counter()
    hs.analyze(sk)
    analyse_s = time.perf_counter() - t
    counts = dict(sk.ToleranceCounts)
    FreeCAD.closeDocument(doc.Name)
    return {"template": TEMPLATE, "insert_s": insert_s, "analyse_s": analyse_s, "tolerance_counts": counts}


# freecadcmd runs this file with a __name__ other than "__main__": run at import
_code = 1
try:
    _out = main()
    _code = 0
except BaseException:  # noqa: BLE001 - reported through the output file and the exit code
    _out = {"error": traceback.format_exc()}
with open(OUT, "w", encoding="utf-8") as fh:
    json.dump(_out, fh)
sys.exit(_code)
