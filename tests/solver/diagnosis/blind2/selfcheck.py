"""Self-checks of the blind2 generator that do not depend on the diagnosis.

    python -m tests.solver.diagnosis.blind2.selfcheck --hyperstat .venv/bin/hyperstat [--out DIR] [--no-visibility]

1. forward kinematics: URDF composition (arms.frames) against a product of exponentials (arms.poe_tool)
   and against a second composition read back from the URDF text with xml.etree, 1e-9 mm;
2. gravity loads: -dV/dq (central differences) against the cross-product formula, relative 1e-6;
3. `hyperstat identify` on noise-free data of machines with geometric errors only: RMS < 1 um (both arms,
   1 and 3 reflectors, with and without masses);
4. the drawn magnitudes lie in the ranges stated in effects.CASES (over 5 seeds per case and variant),
   and the realised noise matches the stated one (none) or its factor (understated);
5. visibility: the noise-free rigid-fit RMS over the stated noise for every case and variant (seed 0),
   through `hyperstat identify`; campaigns below 0.6 are counted apart by the scorer.
Exit code 1 if a check of 1-4 fails.  Units: mm, rad.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import xml.etree.ElementTree as ET

import numpy as np

from . import arms as A
from .campaign import generate
from .cases import campaign_list, variants_of
from .effects import CASES
from .score import import_models, one


def urdf_tool_from_text(text, q):
    """Second composition, from the URDF text itself (metres -> mm)."""
    root = ET.fromstring(text)
    T = np.eye(4)
    k = 0
    for j in root.findall("joint"):
        o = j.find("origin")
        xyz = np.array([float(v) for v in o.get("xyz").split()]) * 1e3
        rpy = [float(v) for v in o.get("rpy").split()]
        T = T @ A.hom(A.rpy_matrix(*rpy), xyz)
        if j.get("type") == "revolute":
            ax = [float(v) for v in j.find("axis").get("xyz").split()]
            T = T @ A.hom(A.rot_axis(ax, q[k]))
            k += 1
    return T


def magnitude(case, c):
    p = c["par"]
    if case == "understated":
        return [p["noise_factor"]]
    if case == "compliance":
        return [v for v in p["compliance_rad_per_Nmm"] if v]
    if case in ("backlash", "backlash-gravity"):
        return [v for v in p["beta_rad"] if v]
    if case == "load-hysteresis":
        return [v for v in p["h_rad"] if v]
    if case in ("angle-harmonic-1", "angle-harmonic-2", "harmonic3-short", "stage-4.6", "cubic-joint2"):
        return [abs(p["amp"])]
    if case == "angle-scale":
        return [abs(p["scale"])]
    if case in ("thermal", "warmup"):
        return [p["alpha"]]
    if case == "tracker-drift":
        return [np.linalg.norm(p["drift_mm"]) / np.sqrt(3)]
    if case in ("beam-bending", "base-tilt", "tool-sag"):
        return [c["magnitude"]]
    if case == "wrist-coupling":
        return [abs(p["ratio"])]
    if case == "bearing-wobble":
        return [p["eps_rad"]]
    return []


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--hyperstat", default=".venv/bin/hyperstat")
    ap.add_argument("--out", default=None)
    ap.add_argument("--no-visibility", action="store_true")
    args = ap.parse_args(argv)
    hs = os.path.abspath(args.hyperstat)
    out = args.out or tempfile.mkdtemp(prefix="blind2_selfcheck_")
    fails = []
    rng = np.random.default_rng(1)
    # 1. kinematics
    worst = 0.0
    for arm in A.ARMS.values():
        text = A.urdf_text(arm, True)
        for _ in range(50):
            q = rng.uniform(arm.lower, arm.upper)
            g = A.nominal_geometry(arm)
            worst = max(worst, np.abs(A.frames(g, q)[6] - A.poe_tool(g, q)).max(),
                        np.abs(A.frames(g, q)[6] - urdf_tool_from_text(text, q)).max())
            gp = A.perturbed_geometry(arm, rng)
            worst = max(worst, np.abs(A.frames(gp, q)[6] - A.poe_tool(gp, q)).max())
    print(f"1. forward kinematics: URDF composition vs product of exponentials vs URDF text: max {worst:.2e} mm")
    if worst > 1e-9:
        fails.append("kinematics")
    # 2. gravity
    worst = 0.0
    for arm in A.ARMS.values():
        for _ in range(20):
            q = rng.uniform(arm.lower, arm.upper)
            g = A.perturbed_geometry(arm, rng)
            t1, t2 = A.gravity_torque(arm, g, q, 7.0), A.gravity_torque_cross(arm, g, q, 7.0)
            worst = max(worst, np.abs(t1 - t2).max() / np.abs(t2).max())
    print(f"2. gravity loads: -dV/dq vs cross products: max relative difference {worst:.2e}")
    if worst > 1e-6:
        fails.append("gravity")
    # 3. noise-free geometric-only data fitted to < 1 um
    models = import_models(hs, out)
    for v in variants_of("none"):
        r = one(hs, out, models, "none", v, 0, do_diagnose=False)
        ratio = r.get("visibility")
        rms = None if ratio is None else ratio * r["identify"]["noise_rms_mm"] * 1e3
        ok = rms is not None and rms < 1.0
        print(f"3. noise-free, geometric errors only, {v.label}: rigid-fit RMS {rms if rms is None else f'{rms:.2e}'} um "
              f"({'ok' if ok else 'FAIL'}); noisy data: sigma {r['identify']['sigma']:.3f}, fit quality {r['identify']['fit_quality']}")
        if not ok:
            fails.append(f"identify noise-free {v.label}")
    # 4. magnitudes and noise
    for case, (cat, _, rnge, src) in CASES.items():
        if rnge is None:
            continue
        vals, disp = [], []
        for v in variants_of(case):
            for s in range(5):
                c = generate(case, v, s)
                vals += magnitude(case, c)
                d = np.linalg.norm(c["points"] - c["points_rigid"], axis=2).max()
                disp.append(float(d))
        lo, hi = min(vals), max(vals)
        ok = rnge[0] <= lo and hi <= rnge[1]
        print(f"4. {case}: drawn {lo:.3g} .. {hi:.3g} in stated range {rnge} {'ok' if ok else 'FAIL'}; "
              f"largest reflector displacement by the effect {min(disp):.3f} .. {max(disp):.3f} mm")
        if not ok:
            fails.append(f"magnitude {case}")
    for case in ("none", "understated"):
        for v in variants_of(case)[:2]:
            c = generate(case, v, 0)
            cn = generate(case, v, 0, noise_free=True)
            z = (c["meas"] - cn["meas"]) / c["sigma"][..., None]
            f = c["par"].get("noise_factor", 1.0)
            ok = abs(z.std() / f - 1) < 0.1
            print(f"4. realised noise / stated, {case} {v.label}: {z.std():.3f} (expected {f:.3f}) {'ok' if ok else 'FAIL'}")
            if not ok:
                fails.append(f"noise {case}")
    # 5. visibility
    if not args.no_visibility:
        seen = set()
        for case, v, s in campaign_list(1):
            if case in ("none", "understated") or (case, v.label) in seen:
                continue
            seen.add((case, v.label))
            r = one(hs, out, models, case, v, s, do_diagnose=False)
            vis = r.get("visibility")
            print(f"5. visibility {case:18s} {v.label:32s}: {vis if vis is None else f'{vis:.2f}'}"
                  f"{'' if vis is not None and vis >= 0.6 else '  (below the floor: counted apart)'}")
    print("self-checks: " + ("all passed" if not fails else "FAILED: " + ", ".join(fails)))
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
