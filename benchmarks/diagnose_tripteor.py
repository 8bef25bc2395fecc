"""Benchmark: the whole ``hyperstat diagnose`` command on the Tripteor X7 with 107 + 30 points (seconds).

Units: seconds (wall clock, fresh process each run: imports, template build, stationarity
analysis, rigid fit, diagnosis, text output).  Goal of issue 20: within 5 s.

Run: ``.venv/bin/python benchmarks/diagnose_tripteor.py [--repeat 5] [--effect backlash]``.
The campaign is simulated once with ``hyperstat simulate`` (a withheld effect, default
backlash); the diagnosis runs ``--repeat`` times with ``--quiet`` (no progress bar) and
the median, min and max wall-clock times are printed with the median CPU time
(user + system) and the load average: on a shared machine the CPU time is what the
command costs, the wall-clock time what the user waits.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--effect", default="backlash", help="effect withheld from the fitted model")
    args = parser.parse_args()
    template = str(ROOT / "templates" / "tripteor_x7.py")
    cli = [sys.executable, "-m", "hyperstat.cad_plugin.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "campaign.csv"
        subprocess.run(cli + ["simulate", template, "--poses", "107", "--validation", "30", "--effect", args.effect,
                              "--out", str(data), "--quiet"], check=True)
        validation = data.with_name("campaign.validation.csv")
        times, cpu = [], []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run(cli + ["diagnose", template, str(data), "--validation", str(validation), "--quiet"],
                           check=True)
            c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            times.append(time.perf_counter() - t0)
            cpu.append(c1.ru_utime - c0.ru_utime + c1.ru_stime - c0.ru_stime)
    print(f"hyperstat diagnose, Tripteor X7, 107 + 30 points, effect {args.effect}: median "
          f"{statistics.median(times):.2f} s (min {min(times):.2f}, max {max(times):.2f}, {args.repeat} runs, "
          f"whole command in a fresh process); CPU time median {statistics.median(cpu):.2f} s "
          f"(user + system: what the command costs on an unloaded core); load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    sys.exit(main())
