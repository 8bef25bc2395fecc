"""Benchmark: ``hyperstat diagnose`` on 3 reflectors x 36 poses of a 6R arm (issue 28, item 8; goal: within 5 s).

Units: seconds (wall clock and CPU time, fresh process each run: imports, DH import of the
model, stationarity analysis, rigid fit of every reflector at once, diagnosis of the whole
file, then of each reflector alone, JSON output).

The campaign: the FANUC-like 6R of the calibration tests (``tests/solver/calibration/
fanuc_like.py``: its own DH kinematics, laser tracker 3.5 m away, three SMRs, controller
joints through the J2/J3 coupling) with a two-cycle-per-revolution error of joint 1 added
to its true joint angles, 24 poses to identify and 12 held out, as the real campaign of
the issue (36 poses, 3 reflectors).  Run:
``.venv/bin/python benchmarks/diagnose_reflectors.py [--repeat 5]``; it prints the median,
min and max wall-clock times, the median CPU time (user + system of the child) and the
load average (on a shared machine the CPU time is what the command costs).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _campaign(directory: Path) -> tuple[Path, Path, Path]:
    from hyperstat.tests.solver.calibration.fanuc_like import DH_YAML, Campaign

    class GearCampaign(Campaign):
        def flange(self, q):
            q = list(q)
            q[0] += 1.2e-4 * math.sin(2.0 * q[0] + 0.4)
            return super().flange(q)

    c = GearCampaign(5)
    files = (directory / "fanuc_like.dh.yaml", directory / "meas.csv", directory / "meas.validation.csv")
    files[0].write_text(DH_YAML)
    files[1].write_text(c.csv(c.poses(24), "P"))
    files[2].write_text(c.csv(c.poses(12), "V"))
    return files


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    cli = [sys.executable, "-m", "hyperstat.cad_plugin.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        dh, data, validation = _campaign(tmp)
        model = tmp / "fanuc_like.skel.json"
        subprocess.run(cli + ["import-robot", str(dh), "--out", str(model), "--quiet"], check=True)
        times, cpu = [], []
        out = tmp / "diag.json"
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run(cli + ["diagnose", str(model), str(data), "--validation", str(validation), "--json",
                                  str(out), "--quiet"], check=True)
            c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            times.append(time.perf_counter() - t0)
            cpu.append(c1.ru_utime - c0.ru_utime + c1.ru_stime - c0.ru_stime)
        doc = json.loads(out.read_text())
    print(f"hyperstat diagnose, 6R, 3 reflectors x 36 poses (24 + 12): answer '{doc['outcome']}' "
          f"{'+'.join(doc['named_effects']) or '-'}, targets agree {doc['targets_agree']}; median "
          f"{statistics.median(times):.2f} s wall (min {min(times):.2f}, max {max(times):.2f}, {args.repeat} runs, "
          f"whole command in a fresh process); CPU time median {statistics.median(cpu):.2f} s; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    sys.exit(main())
