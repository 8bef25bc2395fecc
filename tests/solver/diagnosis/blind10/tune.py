"""The magnitude pass of the twelfth blind set (run before the freeze; not part of the run of record).

Each effect's amplitudes are scaled linearly towards a visibility of 1.4 (``generate.Campaign.visibility``,
the line 0.6 fixed in advance), within caps: 80 % of the docs' plausible bound for a library effect,
three times the first physical guess for an own effect.  Writes ``magnitudes.json`` (factor per case).
Units as ``effects.py``.

    python -m tests.solver.diagnosis.blind10.tune [CASE ...]   # the named cases only, the others kept
"""
from __future__ import annotations

import json
import math
import os
import sys

from tests.solver.diagnosis.blind10 import generate as G
from tests.solver.diagnosis.blind10.cases import CASES

TARGET = 1.4
CAP = {"screw-pitch": 1.6e-3, "angle-scale": 4e-3, "screw-periodic": 0.04, "angle-harmonic": 4.6e-4,
       "joint-clearance": 0.12, "leg-thermal": 2.4e-5, "thermal": 2.4e-5, "tracker-drift": 0.8,
       "tracker-scale": 8e-5, "guide-straightness": 0.04, "base-deformation": 8e-10, "link-bending": 8e-9}
CAP_RP = {"backlash": (1.2e-3, 0.08), "backlash-gravity": (1.2e-3, 0.08), "compliance": (8e-9, 1.5e-3)}
OWN_CAP = 3.0


def cap_factor(case):
    eff, p = case["effect"], case["params"]
    if eff not in CAP and eff not in CAP_RP:
        return OWN_CAP
    m = G.machine(case["family"])
    f = math.inf
    if eff in ("thermal", "tracker-scale"):
        v = abs(p.get("kappa", p.get("s")))
        return CAP[eff] / v
    if eff == "tracker-drift":
        v = max(abs(x) for s in p["shift"].values() for x in s)
        return CAP[eff] / v
    if eff == "guide-straightness":
        return CAP[eff] / max(abs(x) for x in p["c"])
    if eff == "base-deformation":
        return CAP[eff] / max(p["c"])
    for j, v in p["per"].items():
        if eff == "link-bending":
            v = v[1]
        a = math.hypot(*v) if isinstance(v, (list, tuple)) else abs(v)
        c = CAP_RP[eff][0 if m.types[j] == "R" else 1] if eff in CAP_RP else CAP[eff]
        f = min(f, c / a)
    return f


def main(argv=None):
    names = (argv or sys.argv[1:])
    out = G.magnitudes() if names else {}
    for case in CASES:
        if case["effect"] is None or (names and case["name"] not in names):
            continue
        v0 = G.Campaign(case, 0, factor=1.0).visibility()
        f = min(TARGET / max(v0, 1e-9), cap_factor(case))
        f = float(f"{f:.3g}")
        out[case["name"]] = f
        print(f"{case['name']:20s} vis(1) {v0:8.3f} factor {f:8.3g} -> ~{v0 * f:.2f}", flush=True)
    tmp = G.MAG_FILE + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(out, fh, indent=1, sort_keys=True)
    os.replace(tmp, G.MAG_FILE)


if __name__ == "__main__":
    main()
