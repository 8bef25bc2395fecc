"""Analysis time with one and two independent samples, and the certified workspace-sampling rate.

Units: seconds of CPU time (``time.process_time``: user + system of this process, all
threads), configurations per second of CPU time.

Issue 18 asks that the second sample of ``hyperstat analyze`` (the verdict-stability
check, on by default) cost at most 1.5x the single-sample analysis, and that the
workspace-sampling rate of the certified continuation be shown.  For every model this
script times :func:`hyperstat.solver.analysis.stationarity.analyze` with ``samples=1``
and ``samples=2`` (24 configurations, the command's default) inside one warm process
(median of ``--repeat`` runs after one warm-up, each on a fresh ``Kinematics`` so that no
cache is shared between runs), and the rate of
:func:`hyperstat.solver.kinematics.sampling.sample_configurations` (200 certified
configurations) and of :func:`hyperstat.solver.tolerances.accuracy.sample_workspace`
on the Triflex-II (100,000 draws, the ``accuracy`` command's sampler; every kept
configuration certified).  CPU time is used because the machine may be shared.  The whole
``hyperstat analyze`` command adds about 0.6 s of imports and loading to both, so its ratio
is smaller (Triflex-II, 2026-11-26: 0.78 s CPU with one sample, 0.94 s with two, 1.21x);
``benchmarks/run.py --only "analyze command"`` times the whole commands.

Usage::

    .venv/bin/python benchmarks/analysis_samples.py [--repeat 3] [--models slider_crank,triflex_ii]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # the four-bar model files are written by the test helpers
    sys.path.insert(0, str(ROOT))

MODELS = ["slider_crank", "tripteor_x7", "triflex_ii", "crossed_isogram", "crank_rocker"]


def mechanism(name: str):
    """The mechanism of a template, or of a planar four-bar written from its closed-form geometry."""
    import numpy as np

    from hyperstat.cad_plugin.templates import TEMPLATE_DIR, build_template
    from hyperstat.solver import load_model

    if name in ("crossed_isogram", "crank_rocker"):
        from tests.solver.kinematics.fourbar import fourbar_document

        doc = (fourbar_document(100.0, 300.0, 100.0, 300.0, -0.2, 1, (-np.pi, 0.0), name=name)
               if name == "crossed_isogram" else
               fourbar_document(40.0, 120.0, 90.0, 110.0, 0.5, 1, (-np.pi, np.pi), name=name))
        path = Path(tempfile.mkdtemp(prefix="hyperstat-bench-")) / f"{name}.json"
        path.write_text(json.dumps(doc))
        return load_model(path)
    return build_template(TEMPLATE_DIR / f"{name}.py").mechanism()


def cpu(fn, repeat: int) -> float:
    """Median CPU time (s) of ``fn()`` over ``repeat`` runs after one warm-up."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--models", default=",".join(MODELS))
    parser.add_argument("--workspace", type=int, default=100000, help="Triflex-II draws for the accuracy sampler")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.kinematics.sampling import sample_configurations

    print(f"{'model':<16} {'1 sample (s CPU)':>17} {'2 samples (s CPU)':>18} {'ratio':>6} "
          f"{'certified sampling (configs/s CPU)':>35}")
    for name in args.models.split(","):
        mech = mechanism(name)
        one = cpu(lambda: analyze(mech, kinematics=Kinematics(mech), samples=1), args.repeat)
        two = cpu(lambda: analyze(mech, kinematics=Kinematics(mech), samples=2), args.repeat)
        kin = Kinematics(mech)
        rate = 200 / cpu(lambda: sample_configurations(kin, 200, seed=0), args.repeat)
        print(f"{name:<16} {one:17.3f} {two:18.3f} {two / one:6.2f} {rate:35.0f}", flush=True)
    if args.workspace:
        from hyperstat.solver.tolerances.accuracy import sample_workspace

        mech = mechanism("triflex_ii")
        kin = Kinematics(mech)
        t0 = time.process_time()
        q = sample_workspace(mech, args.workspace, seed=0, kinematics=kin)
        t = time.process_time() - t0
        print(f"\nTriflex-II accuracy workspace sampler: {args.workspace} draws, {len(q)} certified configurations "
              f"in {t:.2f} s CPU ({args.workspace / t:.0f} draws/s, {len(q) / t:.0f} certified configs/s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
