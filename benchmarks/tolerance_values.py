"""CPU time of the tolerance stage of ``hyperstat report`` (units: seconds of process CPU time).

Times, in one process after the imports, each part of the report's "tolerances and accuracy" stage:
the classification over the analysis configurations plus the workspace checkpoints; the allocation
on the searched worst cases with the linear worst cases (bounds) of its allocations; the assembly
conditions' values searched over the workspace; the compensable tolerances' values with calibration
(simulated).  CPU time (``time.process_time``), because the machine is shared: quote the load average
beside it.

Usage::

    .venv/bin/python benchmarks/tolerance_values.py [templates/tripteor_x7.py]
"""

from __future__ import annotations

import sys
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main(path: str) -> None:
    import hyperstat.cad_plugin.cli  # noqa: F401  (registers the template loader)
    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.cli.common import load_source
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.tolerances.accuracy import sample_workspace
    from hyperstat.solver.tolerances.classification import classify
    from hyperstat.solver.tolerances.calibrated import calibrated_values
    from hyperstat.solver.tolerances.values import ASSEMBLY_SAMPLE, assign_values

    warnings.simplefilter("ignore")
    clock = time.process_time
    mech, _ = load_source(path, None)
    kin = Kinematics(mech)
    result = analyze(mech, kinematics=kin)
    ws = sample_workspace(mech, 200, seed=0, kinematics=kin)
    rows = []
    t = clock()
    cl = classify(mech, result, kin)
    rows.append(("classify (analysis + workspace checkpoints)", clock() - t))
    t = clock()
    assign_values(cl, mech, kin, ws, assembly=False, calibrate=False)
    allocation = clock() - t
    rows.append(("allocation on searched worst cases, bounds (+ re-check of the classes)", allocation))
    t = clock()
    assign_values(cl, mech, kin, ws, calibrate=False, assembly_configurations=result.configurations[:ASSEMBLY_SAMPLE])
    rows.append(("assembly conditions searched over the workspace", clock() - t - allocation))
    t = clock()
    calibrated_values(cl, mech, kin, ws, cl.declaration.position_mm, cl.declaration.orientation_rad,
                      share=cl.allocation.get("second_order_share"))
    rows.append(("values with calibration (simulated)", clock() - t))
    print(f"{mech.name}: {cl.checked['configurations']} configurations classified, "
          f"{cl.allocation.get('assembly_configurations')}")
    for name, s in rows:
        print(f"  {name:<66} {s:6.3f} s CPU")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else str(ROOT / "templates" / "tripteor_x7.py"))
