"""Set the magnitudes of ``cases.py`` from this generator's own visibility line (never from a diagnose
answer): each in/out effect is scaled linearly towards a visibility of ``TARGET``, within caps (80 % of
the docs' plausible bound for a library effect; a physical size for the own effects), and
``cases.py`` is rewritten with the scaled values.  Run once before the freeze (``RULES.md`` records
the passes); the run of record does not run it.

    python -m tests.solver.diagnosis.blind9.tune OUTDIR
"""
from __future__ import annotations

import copy
import os
import pprint
import sys

import numpy as np

from tests.solver.diagnosis.blind9 import effects as fx
from tests.solver.diagnosis.blind9 import generate as gen
from tests.solver.diagnosis.blind9.cases import CASES

TARGET = 1.4


def _size(eff, serial_revolute):
    """(size, cap) of an effect's amplitude, in its own unit."""
    n = eff["name"]
    per = eff.get("per", {})
    amp = lambda v: float(np.hypot(*v)) if isinstance(v, list) else abs(float(v))  # noqa: E731
    if n == "screw-pitch":
        return max(amp(v) for v in per.values()), 1.6e-3
    if n == "screw-periodic":
        return max(amp(v) for v in per.values()), 0.04
    if n == "angle-scale":
        return max(amp(v) for v in per.values()), 4e-3
    if n == "angle-harmonic":
        return max(amp(v) for v in per.values()), 4.6e-4
    if n in ("backlash", "backlash-gravity"):
        j = next(iter(per))
        return max(amp(v) for v in per.values()), (1.2e-3 if serial_revolute(j) else 0.08)
    if n == "joint-clearance":
        return max(amp(v) for v in per.values()), 0.12
    if n in ("thermal",):
        return eff["kappa"], 2.4e-5
    if n == "leg-thermal":
        return max(per.values()), 2.4e-5
    if n == "tracker-drift":
        return max(np.linalg.norm(v) for v in eff["shift"].values()), 0.8
    if n == "guide-straightness":
        return max(amp(v) for v in per.values()), 0.04
    if n == "base-deformation":
        return max(eff["c"]), 8e-10
    if n == "compliance":
        j = next(iter(per))
        return max(per.values()), (8e-9 if serial_revolute(j) else 1.5e-3)
    if n == "link-bending":
        return max(v[1] for v in per.values()), 8e-9
    # own effects: physical sizes
    if n == "balancer-spring":
        return eff["c"], 1e-5
    if n == "rail-dent-pitch":
        return eff["a"], 8e-4
    if n == "worn-screw-play":
        return eff["beta"], 0.15
    if n == "spindle-growth":
        return eff["kappa"] * eff["L"], 2.4e-5 * 600
    if n == "axial-runout":
        return eff["a"], 0.08
    if n == "smr-incidence":
        return eff["c"], 0.3
    if n == "platform-twist-thermal":
        return eff["c"], 1e-4
    if n == "payload-tilt":
        return eff["c"], 3e-5
    if n == "carriage-rock":
        return eff["c"], 3e-4
    raise ValueError(n)


def main(argv=None):
    out = (argv or sys.argv[1:])[0]
    paths = gen.make_models(out)
    new = []
    for case in CASES:
        case = copy.deepcopy(case)
        if case["kind"] in ("in", "out"):
            tr = gen.campaign(case, paths, out, 0, True)
            v = tr["visibility"]
            m = gen.Machine(paths[case["model"]])
            serial_rev = lambda j: (not m.parallel) and m.types.get(j) == "R"  # noqa: E731
            size, cap = _size(case["effect"], serial_rev)
            f = TARGET / max(v, 1e-6)
            f = min(f, cap / size)
            f = float(f"{f:.2g}")
            case["effect"] = fx.scaled(case["effect"], f) if case["effect"]["name"] != "spindle-growth" else \
                dict(case["effect"], L=round(case["effect"]["L"] * f, 0))
            print(f"{case['name']}: visibility {v:.3f} -> factor {f} (cap {cap / size:.3g})", flush=True)
        new.append(case)
    path = os.path.join(gen.HERE, "cases.py")
    with open(path) as fh:
        text = fh.read()
    head = text.split("CASES = [")[0]
    body = "CASES = [\n" + "".join("    " + _fmt(c) + ",\n" for c in new) + "]\n"
    tail = "\nassert len({c[\"name\"] for c in CASES}) == len(CASES) == 72\n"
    with open(path + ".tmp", "w") as fh:
        fh.write(head + body + tail)
    os.replace(path + ".tmp", path)
    return 0


def _fmt(c):
    def r(x):
        if isinstance(x, float):
            return float(f"{x:.3g}")
        if isinstance(x, list):
            return [r(y) for y in x]
        if isinstance(x, dict):
            return {k: r(v) for k, v in x.items()}
        return x
    return pprint.pformat(r(c), width=10000, sort_dicts=False)


if __name__ == "__main__":
    sys.exit(main())
