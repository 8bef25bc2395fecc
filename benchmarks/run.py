"""hyperstat benchmarks: medians over repeated runs (units: seconds, configurations per second, MiB).

Run with ``make bench`` (or ``.venv/bin/python benchmarks/run.py``).  Prints a table; with
``--markdown FILE`` also writes it as Markdown.  Timings are wall-clock medians of
``--repeat`` runs after one warm-up run ("warm"); "cold" runs start a fresh Python
process and include the imports.  Peak memory is the peak resident set of the run
measured with ``tracemalloc`` (Python allocations, numpy included) in one extra run,
or for a new process its maximum resident set size.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
import tracemalloc
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
warnings.simplefilter("ignore")

TEMPLATES = ["slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod"]
BENCHES: dict = {}


def bench(name: str, unit: str = "s"):
    """Register a benchmark: a function returning (setup-free callable, work count or None)."""

    def deco(fn):
        BENCHES[name] = (fn, unit)
        return fn

    return deco


def _mech(name: str):
    from cad_plugin.templates import build_template

    return build_template(ROOT / "templates" / f"{name}.py").mechanism()


for _t in TEMPLATES:
    def _make(t=_t):
        def setup():
            from solver import Kinematics, analyze

            mech = _mech(t)
            kin = Kinematics(mech)
            return (lambda: analyze(mech, kinematics=kin)), None
        return setup
    bench(f"stationarity analysis, {_t} (warm)")(_make())


@bench("stationarity analysis, tripteor_x7 (cold, new process)")
def _cold_tripteor():
    code = ("import warnings; warnings.simplefilter('ignore');"
            "from cad_plugin.templates import build_template; from solver import analyze;"
            f"analyze(build_template(r'{ROOT / 'templates' / 'tripteor_x7.py'}').mechanism())")
    return (lambda: subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)), None


@bench("identification, tripteor_x7, 107 + 30 validation points (warm)")
def _identify_tripteor():
    from solver import Kinematics, analyze
    from solver.identify import identify
    from solver.virtual import VirtualMachine

    mech = _mech("tripteor_x7")
    kin = Kinematics(mech)
    analysis = analyze(mech, kinematics=kin)
    vm = VirtualMachine.random(mech, analysis, seed=0, kinematics=kin)
    q = vm.poses(137, seed=1)
    data, val = vm.measure(q[:107], seed=2), vm.measure(q[107:], seed=3, prefix="V")
    return (lambda: identify(mech, analysis, data, val, kinematics=kin)), None


@bench("D-optimal choice of 107 poses among 1000, tripteor_x7")
def _select_tripteor():
    from solver import Kinematics, analyze
    from solver.identify import MeasurementModel
    from solver.poses import select_poses
    from solver.virtual import VirtualMachine

    mech = _mech("tripteor_x7")
    kin = Kinematics(mech)
    analysis = analyze(mech, kinematics=kin)
    vm = VirtualMachine.random(mech, analysis, seed=0, kinematics=kin)
    candidates = vm.poses(1000, seed=1)
    model = MeasurementModel(mech, analysis, kin)
    return (lambda: select_poses(model, candidates, 107, noise=vm.noise)), None


def _triflex_configurations(n: int):
    from solver import Kinematics
    from solver.accuracy import sample_workspace

    mech = _mech("triflex_ii")
    kin = Kinematics(mech)
    base = sample_workspace(mech, 2000, seed=0, kinematics=kin)
    return mech, kin, base[np.arange(n) % len(base)]


@bench("accuracy coefficients, 100,000 Triflex-II configurations")
def _accuracy_triflex():
    from solver.accuracy import accuracy_maps

    mech, kin, q = _triflex_configurations(100_000)
    return (lambda: accuracy_maps(mech, q, kinematics=kin)), None


@bench("Monte Carlo, 100,000 samples, Triflex-II (nonlinear re-assembly)")
def _montecarlo_triflex():
    from solver.montecarlo import monte_carlo

    mech, kin, q = _triflex_configurations(2000)
    tol = {p.name: (6.76e-3 if p.unit == "rad" else 5e-3) for p in mech.parameters}
    return (lambda: monte_carlo(mech, q, tol, samples=100_000, kinematics=kin)), None


def run(names: list[str], repeat: int) -> list[tuple[str, float, str, float]]:
    rows = []
    for name in names:
        fn, unit = BENCHES[name]
        work, count = fn()
        work()  # warm-up
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            work()
            times.append(time.perf_counter() - t0)
        if "new process" in name:
            import resource

            peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # largest child, KiB -> MiB
        else:
            tracemalloc.start()  # a separate run: tracing slows Python down
            work()
            peak = tracemalloc.get_traced_memory()[1] / 2**20
            tracemalloc.stop()
        med = statistics.median(times)
        value = count / med if count else med
        rows.append((name, value, unit if not count else "configs/s", peak))
        print(f"{name:<60} {value:>12.4g} {rows[-1][2]:<10} peak {peak:8.1f} MiB", flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--only", help="substring of the benchmarks to run")
    parser.add_argument("--markdown", help="also write the table as Markdown")
    args = parser.parse_args()
    names = [n for n in BENCHES if not args.only or args.only in n]
    rows = run(names, args.repeat)
    if args.markdown:
        lines = ["| benchmark | median | unit | peak memory (MiB) |", "|---|---|---|---|"]
        lines += [f"| {n} | {v:.4g} | {u} | {m:.1f} |" for n, v, u, m in rows]
        Path(args.markdown).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
