"""Self-checks of the tenth blind generator (``blind8``), without any diagnose run.

    python -m tests.solver.diagnosis.blind8.selfcheck [OUTDIR]

1. the model files' kinematics (own serial FK) against own products: the desktop 6R against an own
   modified-DH product of its table, the gantry against its URDF read by hand (translations along x, y,
   -z, turns about z and x); the serial FK against ``kin.py``'s (mm);
2. the hexapod: a closed pose's leg lengths (distance from each leg's base joint centre to its
   platform joint centre, computed from the frames) equal the commanded leg values minus the home offset
   of the file (mm), and the closure residual;
3. gravity: the generalized forces against central differences of the potential energy (relative);
4. an effect at zero amplitude gives the rigid data bit for bit, and a constant joint offset is
   absorbed by the rigid visibility fit (below 0.05 of the 0.6 line's scale).
Units: mm, rad, N, N mm.
"""
from __future__ import annotations

import os
import sys
import tempfile

import numpy as np

from .machine import Machine, mdh_product, potential
from . import generate as gen

DESK_ROWS = [(0.0, 0.0, 0.0, 168.0), (-np.pi / 2, 0.0, -np.pi / 2, 0.0), (0.0, 226.0, 0.0, 0.0),
             (-np.pi / 2, 28.0, 0.0, 221.0), (np.pi / 2, 0.0, 0.0, 0.0), (-np.pi / 2, 0.0, 0.0, 0.0)]


def _rx(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _tr(x, y, z):
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def gantry_by_hand(q):
    """The URDF of robots/gantry5.urdf read by hand (mm, rad)."""
    return (_tr(200 + q[0], 100, 1300) @ _tr(0, 50 + q[1], 120) @ _tr(80, 0, -100 - q[2]) @ _tr(0, 0, -620)
            @ _rz(q[3]) @ _tr(0, 0, -130) @ _rx(q[4]) @ _tr(0, 0, -160))


def check_fk(outdir, n=20, seed=1):
    rng = np.random.default_rng(seed)
    res = {}
    for variant, ref in (("desk", lambda q: mdh_product(DESK_ROWS, 62.0, q)), ("gantry_m", gantry_by_hand)):
        m = gen.machine(outdir, variant)
        worst, worst_kin = 0.0, 0.0
        for _ in range(n):
            qa = {j: rng.uniform(*m.ranges[j]) for j in m.actuated}
            T, _ = m.serial_frames(qa)
            R = ref([qa[j] for j in m.actuated])
            worst = max(worst, np.max(np.abs(T[:3, 3] - R[:3, 3])), 1000 * np.max(np.abs(T[:3, :3] - R[:3, :3])))
            Tk = m.kin.output_pose(qa)
            worst_kin = max(worst_kin, np.max(np.abs(T - Tk)))
        res[variant] = (worst, worst_kin)
    return res


def check_hexapod_legs(outdir, n=5, seed=2):
    m = gen.machine(outdir, "hexa")
    qas, full = gen.poses(outdir, "hexa", "hexa", "sobol", n, seed)
    worst, worst_r = 0.0, 0.0
    home = {j: m.kin.joints[j].home for j in m.actuated}
    _, _, jf0 = m.kin.frames(m.kin.solve_path(home)[0])
    for qa, q in zip(qas, full):
        _, r, jf = m.kin.frames(q)
        worst_r = max(worst_r, float(np.linalg.norm(r)))
        for leg in m.actuated:
            i = leg[-1]
            lo = jf["2" + i][:3, 3]  # the base U joint's centre (its second axis' frame)
            hi = jf["4" + i][:3, 3]  # the platform joint's centre
            lo0, hi0 = jf0["2" + i][:3, 3], jf0["4" + i][:3, 3]
            L, L0 = np.linalg.norm(hi - lo), np.linalg.norm(hi0 - lo0)
            worst = max(worst, abs((L - L0) - (q[leg] - home[leg])))
    return worst, worst_r


def check_gravity(outdir, seed=3):
    rng = np.random.default_rng(seed)
    out = {}
    for variant in ("desk_m", "gantry_m", "hexa_m"):
        m = gen.machine(outdir, variant)
        worst = 0.0
        for _ in range(3):
            qa = {j: rng.uniform(0.3, 0.7) * (m.ranges[j][1] - m.ranges[j][0]) + m.ranges[j][0]
                  for j in m.actuated}
            q = m.kin.solve_path(qa)[0] if m.parallel else None
            tau, _ = m.gravity(qa, q, payload=2.0)
            for j in m.actuated:
                h = 1e-4 if m.types[j] == "P" else 1e-6
                qp, qm = dict(qa), dict(qa)
                qp[j] += h
                qm[j] -= h
                d = -(potential(m, qp, 2.0) - potential(m, qm, 2.0)) / (2 * h)
                worst = max(worst, abs(d - tau[j]) / max(1.0, abs(tau[j])))
        out[variant] = worst
    return out


def check_zero_and_offset(outdir):
    from .cases import CASES
    base = {c["name"]: c for c in CASES}
    res = {}
    other = os.path.join(outdir, "zero")
    gen.make_models(other)
    for nm, eff, par in (("dm_none", "angle-harmonic", {"k": 1, "per": {"2": [0.0, 0.0]}}),
                         ("hx_none_6d", "screw-pitch", {"per": {"33": 0.0}})):
        c0 = dict(base[nm], effect=eff, params=par)
        gen.campaign(other, c0, 0, visibility=False)
        gen.campaign(outdir, base[nm], 0, visibility=False)
        same = True
        for fn in ("data.csv", "val.csv"):
            with open(os.path.join(other, "campaigns", nm, fn)) as f0, \
                    open(os.path.join(outdir, "campaigns", nm, fn)) as f1:
                same &= f0.read() == f1.read()
        res[f"{eff} at zero amplitude = the rigid data ({nm})"] = same
    for nm, j, v in (("gm_none", "1", 0.3), ("dm_none", "2", 1e-3)):
        c = dict(base[nm], name=nm + "_off", effect="offset", params={"per": {j: v}})
        res[f"{nm} offset of joint {j}"] = gen.campaign(outdir, c, 0)["visibility"]
    return res


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    outdir = argv[0] if argv else tempfile.mkdtemp(prefix="blind8-selfcheck-")
    gen.make_models(outdir)
    ok = True
    print("1. serial FK against own products (max |deviation| mm, rotation entries x 1000) / against kin.py:")
    for k, (a, b) in check_fk(outdir).items():
        print(f"   {k:9s} {a:.2e} / {b:.2e}")
        ok &= a < 1e-8 and b < 1e-8
    w, r = check_hexapod_legs(outdir)
    print(f"2. hexapod: leg length change against the leg values {w:.2e} mm, closure residual {r:.2e}")
    ok &= w < 1e-6 and r < 1e-8
    print("3. gravity forces against -dV/dq (relative):")
    for k, v in check_gravity(outdir).items():
        print(f"   {k:9s} {v:.2e}")
        ok &= v < 1e-5
    print("4. zero amplitude and a constant offset (visibility, line 0.6):")
    for k, v in check_zero_and_offset(outdir).items():
        print(f"   {k}: {v}")
        ok &= (v is True) if isinstance(v, bool) else v < 0.05
    print("all checks passed" if ok else "A CHECK FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
