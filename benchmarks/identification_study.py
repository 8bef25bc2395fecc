"""Identification of the Tripteor X7 in the paper's setting: random vs D-optimal poses.

Units: lengths in mm (residuals printed in um), angles in rad.

For each seed: a virtual machine (admissible defects within +-2e-4 rad / +-0.05 mm,
tracker noise 5 um + 5 um/m per axis), 107 identification poses chosen either at
random or D-optimally among 1000 random candidates, 30 random validation poses.
Prints one Markdown row per seed and pose choice; ``docs/identification.md`` quotes
the output.  Run: ``.venv/bin/python benchmarks/identification_study.py``.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
warnings.simplefilter("ignore")

from hyperstat.cad_plugin.templates import build_template  # noqa: E402
from hyperstat.solver import Kinematics, analyze  # noqa: E402
from hyperstat.solver.calibration.identify import MeasurementModel, identify  # noqa: E402
from hyperstat.solver.calibration.poses import select_poses  # noqa: E402
from hyperstat.solver.calibration.virtual import VirtualMachine  # noqa: E402


def main(seeds: int = 5) -> None:
    mech = build_template(ROOT / "templates" / "tripteor_x7.py").mechanism()
    kin = Kinematics(mech)
    analysis = analyze(mech, kinematics=kin)
    model = MeasurementModel(mech, analysis, kin)
    print("| seed | poses | rank / unknowns | condition number | O1 | median std of defects (mm or rad x 1000 mm) "
          "| validation mean / max / RMS (um) | noise RMS (um) | time (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for seed in range(seeds):
        vm = VirtualMachine.random(mech, analysis, seed=seed, kinematics=kin)
        candidates = vm.poses(1000, seed=seed + 100)
        val = vm.measure(vm.poses(30, seed=seed + 200), seed=seed + 300, prefix="V")
        choice = {"random": np.random.default_rng(seed).choice(1000, 107, replace=False),
                  "D-optimal": select_poses(model, candidates, 107, noise=vm.noise).index}
        for label, index in choice.items():
            data = vm.measure(candidates[index], seed=seed + 400)
            res = identify(mech, analysis, data, val, kinematics=kin, model=model)
            stds = [p["std"] * (1000.0 if p["unit"] == "rad" else 1.0) for p in res.parameters
                    if p["identifiable"] and p["kind"] == "geometry"]
            v = res.validation
            print(f"| {seed} | {label} | {res.rank} / {res.n_unknowns} | {res.condition_number:.3g} | "
                  f"{res.observability['O1']:.3g} | {np.median(stds):.3g} | {1000 * v['mean']:.1f} / "
                  f"{1000 * v['max']:.1f} / {1000 * v['rms']:.1f} | {1000 * res.noise_rms:.1f} | {res.elapsed:.2f} |",
                  flush=True)


if __name__ == "__main__":
    main()
