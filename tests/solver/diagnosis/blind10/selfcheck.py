"""Self-checks of the twelfth blind generator (no diagnose).  Units: mm, rad.

    python -m tests.solver.diagnosis.blind10.selfcheck

1. the imported robots' FK (``machine.py`` reading the model files ``import-robot`` wrote) against this
   file's own standard-DH / modified-DH products of the robot files' rows;
2. gravity loads against central differences of the potential energy;
3. effect equations at known points;
4. zero amplitude gives the rigid data; a constant joint offset is absorbed by the rigid fit.
"""
from __future__ import annotations

import copy
import math
import sys

import numpy as np

from tests.solver.diagnosis.blind8.machine import potential
from tests.solver.diagnosis.blind10 import effects as E
from tests.solver.diagnosis.blind10 import generate as G
from tests.solver.diagnosis.blind10.cases import CASES


def _Rz(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _Rx(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _T(x, y, z):
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


STAN = [  # (type, a, alpha, d, theta) of robots/stan6.dh.yaml, mm rad
    ("R", 0, -math.pi / 2, 412, 0), ("R", 0, math.pi / 2, 154, 0), ("P", 0, 0, 300, -math.pi / 2),
    ("R", 0, -math.pi / 2, 0, 0), ("R", 0, math.pi / 2, 0, 0), ("R", 0, 0, 160, 0)]
CEIL = [  # (alpha, a, theta, d) of robots/ceil5.mdh.csv, mm rad
    (math.pi, 0, 0, 380), (-math.pi / 2, 150, 0, 0), (0, 560, math.pi / 2, 0), (0, 480, 0, 0),
    (-math.pi / 2, 0, 0, 120)]


def stan_fk(q):
    T = np.eye(4)
    for (typ, a, al, d, th), v in zip(STAN, q):
        T = T @ _Rz(th + (v if typ == "R" else 0)) @ _T(0, 0, d + (v if typ == "P" else 0)) @ _T(a, 0, 0) @ _Rx(al)
    return T @ _T(60, 0, 80)


def ceil_fk(q):
    T = np.eye(4)
    for (al, a, th, d), v in zip(CEIL, q):
        T = T @ _Rx(al) @ _T(a, 0, 0) @ _Rz(th + v) @ _T(0, 0, d)
    return T


def check_fk(rng, n=30):
    out = {}
    for fam, fk in (("stan", stan_fk), ("ceil", ceil_fk)):
        m = G.machine(fam)
        worst = 0.0
        for _ in range(n):
            qa = {j: rng.uniform(*m.ranges[j]) for j in m.actuated}
            A, _ = m.serial_frames(qa)
            B = fk([qa[j] for j in m.actuated])
            worst = max(worst, np.abs(A[:3, 3] - B[:3, 3]).max(), 1000 * np.abs(A[:3, :3] - B[:3, :3]).max())
        out[fam] = worst
    return out


def check_gravity(rng):
    out = {}
    for fam in ("stan", "ceil", "hexa"):
        m = G.machine(fam, massed=True)
        worst, scale = 0.0, 0.0
        for _ in range(3):
            qa = {j: (m.ranges[j][0] + m.ranges[j][1]) / 2 + 0.5 * (m.ranges[j][1] - m.ranges[j][0]) / 2
                  * rng.uniform(-1, 1) for j in m.actuated}
            qf = None
            if m.parallel:
                qf, _ = m.kin.solve_path(qa)
            tau, _ = m.gravity(qa, qf, payload=2.0)
            for j in m.actuated:
                h = 1e-4 if m.types[j] == "P" else 1e-6
                qp, qm = dict(qa), dict(qa)
                qp[j] += h
                qm[j] -= h
                d = -(potential(m, qp, 2.0) - potential(m, qm, 2.0)) / (2 * h)
                worst = max(worst, abs(d - tau[j]))
                scale = max(scale, abs(tau[j]))
        out[fam] = worst / scale
    return out


def check_effects():
    ctx = {"q": {"3": 2.5, "1": math.pi / 1.5}, "dir": {"3": 1.0}, "tau": {"3": -5.0, "2": 10.0},
           "T": 23.0, "ts": 0.0, "session": 3, "lo": {"3": 0.0}, "hi": {"3": 420.0}}
    r = {}
    r["screw-periodic: its sine term at a quarter of its period (lead 10, order 1)"] = abs(
        E.joint_dq("screw-periodic", {"order": 1, "per": {"3": [0.01, 0.0]}}, ctx)["3"] - 0.01) < 1e-15
    r["angle-harmonic-1.5: its cosine term is -b at q = pi / 1.5"] = abs(
        E.joint_dq("angle-harmonic", {"k": 1.5, "per": {"1": [0.0, 1e-4]}}, ctx)["1"] + 1e-4) < 1e-15
    r["backlash: half the play against the last motion"] = E.joint_dq("backlash", {"per": {"3": 0.04}}, ctx)["3"] == -0.02
    r["backlash-gravity: to the side of the load"] = E.joint_dq("backlash-gravity", {"per": {"3": 0.04}}, ctx)["3"] == -0.02
    lb = E.joint_dq("link-bending", {"per": {"2": ["3", 3e-9]}}, ctx)
    r["link-bending 2/3 and 1/3"] = abs(lb["2"] - 2e-8) < 1e-20 and abs(lb["3"] - 1e-8) < 1e-20
    P, _ = E.point_base("thermal", {"kappa": 1e-5}, ctx, np.array([1000.0, 0, 0]))
    r["thermal: 1000 mm grows 0.03 mm at 23 degC"] = abs(P[0] - 1000.03) < 1e-9
    m = E.point_tracker("tracker-drift", {"shift": {"3": [0.1, 0, 0]}}, ctx, np.zeros(3))
    r["tracker-drift in session 3"] = m[0] == 0.1
    ctx2 = dict(ctx, q={"3": 315.0})
    T = E.frame_post("guide-straightness", {"joint": "3", "c": [0.04, 0.0]}, ctx2)["3"]
    r["guide-straightness: bow 0.75 c at s = 0.5"] = abs(T[0, 3] - 0.03) < 1e-12
    # screw-hotspot: the integral over the whole spot is D w sqrt(pi) kappa after a long session
    ctx3 = dict(ctx, q={"3": 420.0}, ts=1e7)
    d = E.joint_dq("screw-hotspot", {"joint": "3", "D": 4.0, "x0": 210.0, "w": 30.0}, ctx3)["3"]
    r["screw-hotspot: whole spot = kappa D w sqrt(pi)"] = abs(d - 1.15e-5 * 4 * 30 * math.sqrt(math.pi)) < 1e-9
    return r


def check_zero_and_offset():
    out = {}
    case = next(c for c in CASES if c["name"] == "st_harm1_1")
    c0 = G.Campaign(case, 0, factor=0.0)
    same = all(np.allclose(c0.points(i, True)[0], c0.points(i, False)[0], atol=1e-12) for i in range(len(c0.poses)))
    out["angle-harmonic at zero amplitude = the rigid data (stan)"] = same
    for fam, j, v in (("stan", "2", 2e-3), ("ceil", "3", 2e-3), ("stan", "3", 0.5)):
        base = next(c for c in CASES if c["family"] == fam and c["kind"] == "in")
        cc = copy.deepcopy(base)
        cc.update(effect="offset", params={"per": {j: v}}, name="offset_" + fam)
        out[f"{fam}: visibility of a constant offset of joint {j} ({v})"] = G.Campaign(cc, 0, factor=1.0).visibility()
    return out


def main():
    rng = np.random.default_rng(7)
    ok = True
    print("1. serial FK of the imported robots against own DH products (max |deviation| mm, rotation x 1000):")
    for k, v in check_fk(rng).items():
        print(f"   {k:6s} {v:.3g}")
        ok &= v < 1e-9
    print("2. gravity loads against -dV/dq (relative to the largest):")
    for k, v in check_gravity(rng).items():
        print(f"   {k:6s} {v:.3g}")
        ok &= v < 1e-4
    print("3. effect equations at known points:")
    for k, v in check_effects().items():
        print(f"   {k}: {v}")
        ok &= bool(v)
    print("4. zero amplitude and a constant offset (visibility, line 0.6):")
    for k, v in check_zero_and_offset().items():
        print(f"   {k}: {v}")
        ok &= (v is True) or (not isinstance(v, bool) and v < 0.1)
    print("all checks passed" if ok else "SOME CHECKS FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
