"""Benchmark: the whole ``hyperstat diagnose`` command on the hexapod, campaigns of the PKM generator (seconds).

Units: seconds (wall clock and CPU time of a fresh process: imports, model file, stationarity
analysis, rigid fit, diagnosis, the check per target, JSON output).  Issue 40: every hexapod
campaign under 120 s on one idle core (the sixth blind run: 39-589 s at a load of 4-7, and the
joint-clearance campaign over 1,200 s).

Run: ``.venv/bin/python benchmarks/diagnose_hexapod.py [--cases joint-clearance,none] [--poses 107] [--seed 0]``.
Each campaign is made by ``tests/solver/diagnosis/pkm_generator.py`` (numpy only, shares no code with
hyperstat) and diagnosed once; the answer, the wall-clock and the CPU time (user + system: what the
command costs on an unloaded core) are printed, with the load average.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="joint-clearance,screw-periodic,base-deformation,compliance,none")
    parser.add_argument("--poses", type=int, default=107, help="identification poses (a third more held out)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    from tests.solver.diagnosis import pkm_generator as gen

    model = gen.MODELS["hexapod"]
    cli = [sys.executable, "-m", "hyperstat.cad_plugin.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases.split(","):
            n_val = max(args.poses * 2 // 7, 6)
            id_text, val_text, _ = gen.campaign(model, case, args.seed, n_id=args.poses, n_val=n_val)
            data, val, out = Path(tmp) / "id.csv", Path(tmp) / "val.csv", Path(tmp) / "out.json"
            data.write_text(id_text)
            val.write_text(val_text)
            t0 = time.perf_counter()
            c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run(cli + ["diagnose", str(model), str(data), "--validation", str(val), "--json", str(out),
                                  "--quiet"], check=True)
            c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = c1.ru_utime - c0.ru_utime + c1.ru_stime - c0.ru_stime
            doc = json.loads(out.read_text())
            print(f"hexapod {case} (seed {args.seed}, {args.poses} poses): {doc['outcome']}"
                  f"{' by ' + ', '.join(doc['named_effects']) if doc['named_effects'] else ''}; wall "
                  f"{time.perf_counter() - t0:.1f} s, CPU {cpu:.1f} s; "
                  f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
