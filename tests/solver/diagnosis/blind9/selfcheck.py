"""Self-checks of the eleventh blind generator (directory ``blind9``), without diagnose.

Units: mm, rad.  Independent checks: the imported robots' forward kinematics against this file's own
standard-DH / modified-DH products written from the robot files (not from the model files), gravity
forces against central differences of the potential energy, the closed hexapod's output derivative
against finite differences of closed poses, the effects' equations at known points, zero amplitude and
a constant joint offset through the visibility fit.

    python -m tests.solver.diagnosis.blind9.selfcheck [OUTDIR]
"""
from __future__ import annotations

import csv
import os
import sys
import tempfile

import numpy as np

from tests.solver.diagnosis.blind8.machine import Machine, potential
from tests.solver.diagnosis.blind9 import effects as fx
from tests.solver.diagnosis.blind9 import generate as gen

HERE = os.path.dirname(os.path.abspath(__file__))


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def _tr(x, y, z):
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


def lift_dh_rows():
    """The lift7 CSV read here (m, deg -> mm, rad): (type, a, alpha, d, theta)."""
    with open(os.path.join(HERE, "robots", "lift7.dh.csv")) as f:
        rows = [r for r in csv.reader(l for l in f if not l.startswith("#"))]
    out = []
    for r in rows[1:]:
        out.append((r[1], float(r[2]) * 1000, np.radians(float(r[3])), float(r[4]) * 1000, np.radians(float(r[5]))))
    return out


def lift_fk(q):
    """Standard DH: T_i = Rz(theta_i [+ q_i]) Tz(d_i [+ q_i]) Tx(a_i) Rx(alpha_i)."""
    T = np.eye(4)
    for (typ, a, al, d, th), v in zip(lift_dh_rows(), q):
        if typ == "R":
            th = th + v
        else:
            d = d + v
        T = T @ _rz(th) @ _tr(0, 0, d) @ _tr(a, 0, 0) @ _rx(al)
    return T


def cyl_fk(q):
    """Modified DH (Craig) from robots/cyl5.mdh.yaml (values copied: m -> mm), tool Tx(85) Ry(pi/2)."""
    rows = [("R", 0.0, 0.0, 0.0, 420.0), ("P", 0.0, 0.0, 0.0, 50.0), ("P", -np.pi / 2, 90.0, 0.0, 320.0),
            ("R", 0.0, 0.0, 0.0, 140.0), ("R", np.pi / 2, 0.0, 0.0, 0.0)]
    T = np.eye(4)
    for (typ, al, a, th, d), v in zip(rows, q):
        if typ == "R":
            th = th + v
        else:
            d = d + v
        T = T @ _rx(al) @ _tr(a, 0, 0) @ _rz(th) @ _tr(0, 0, d)
    return T @ _tr(85.0, 0, 0) @ _ry(np.pi / 2)


def check_serial_fk(n=20):
    rng = np.random.default_rng(1)
    out = {}
    for name, fk in (("lift7", lift_fk), ("cyl5", cyl_fk)):
        m = Machine(os.path.join(HERE, "models", f"{name}.skel.json"))
        worst_own, worst_kin = 0.0, 0.0
        for _ in range(n):
            q = {j: rng.uniform(*m.ranges[j]) for j in m.actuated}
            T, _ = m.serial_frames(q)
            Tk = m.kin.output_pose(q)
            To = fk([q[j] for j in m.actuated])
            worst_own = max(worst_own, np.abs(T[:3, 3] - To[:3, 3]).max(), 1000 * np.abs(T[:3, :3] - To[:3, :3]).max())
            worst_kin = max(worst_kin, np.abs(T - Tk).max())
        out[name] = (worst_own, worst_kin)
    return out


def check_gravity():
    d = tempfile.mkdtemp(prefix="blind9_")
    paths = gen.make_models(d)
    out = {}
    for v, fam in (("lift_m", "lift"), ("cyl_m", "cyl"), ("hexa_m", "hexa")):
        m = Machine(paths[v], moving_mass=gen.MOVING_MASS.get(fam))
        qa_list, qf_list = gen.nominal_poses(fam, m, "antithetic", 4, 7)
        worst = 0.0
        for qa, qf in zip(qa_list, qf_list):
            tau, _ = m.gravity(qa, qf if m.parallel else None, 3.0)
            for j in m.actuated:
                h = 1e-3 if m.types[j] == "P" else 1e-6
                qp, qm = dict(qa), dict(qa)
                qp[j] += h
                qm[j] -= h
                num = -(potential(m, qp, 3.0) - potential(m, qm, 3.0)) / (2 * h)
                worst = max(worst, abs(num - tau[j]) / max(1.0, max(abs(t) for t in tau.values())))
        out[v] = worst
    return out, paths


def check_hexapod_derivative(paths):
    m = Machine(paths["hexa"])
    qa_list, qf_list = gen.nominal_poses("hexa", m, "corners", 3, 7)
    qa, qf = qa_list[0], qf_list[0]
    To, dTo = m.output_jacobian(qf)
    worst, res = 0.0, 0.0
    for k, j in enumerate(m.actuated):
        h = 1e-4
        qp, qm = dict(qa), dict(qa)
        qp[j] += h
        qm[j] -= h
        Tp, _, rp = m.pose(qp, init=m.passive_vector(qf))
        Tm, _, rm = m.pose(qm, init=m.passive_vector(qf))
        res = max(res, rp, rm)
        worst = max(worst, np.abs((Tp - Tm) / (2 * h) - dTo[k])[:3, 3].max())
    return worst, res


def check_effects():
    """Equations at known points (exact values)."""
    ok = {}
    ctx = dict(q={"1": 0.3, "2": 5.0}, dir={"1": -1.0, "2": 1.0}, T=23.0, payload=2.0, session=3, ts=0.0,
               tau={"1": -200.0, "2": 50.0}, M=np.array([1e5, -2e5, 0.0]), s={"1": 0.0, "2": 0.5},
               half={"1": 1.0, "2": 100.0}, tracker=(np.zeros(3), np.eye(3)))
    c2 = dict(ctx, q={"1": 0.3, "2": 1.25})  # a quarter of the period lead / order = 5 mm
    dq = fx.apply({"name": "screw-periodic", "order": 2, "lead": 10.0, "per": {"2": [0.01, 0.0]}}, c2)["dq"]["2"]
    ok["screw-periodic: its sine term at a quarter of its period (lead 10 mm, order 2)"] = abs(dq - 0.01) < 1e-15
    dh = fx.apply({"name": "angle-harmonic", "k": 1.5, "per": {"1": [0.0, 2e-4]}}, dict(ctx, q={"1": np.pi / 1.5}))["dq"]["1"]
    ok["angle-harmonic-1.5: its cosine term is -b at q = pi / 1.5"] = abs(dh + 2e-4) < 1e-15
    ok["backlash: half the play against the last motion"] = fx.apply({"name": "backlash", "per": {"1": 0.002}}, ctx)["dq"]["1"] == 0.001
    ok["backlash-gravity: to the side of the load"] = fx.apply({"name": "backlash-gravity", "per": {"1": 0.002}}, ctx)["dq"]["1"] == -0.001
    lb = fx.apply({"name": "link-bending", "per": {"1": ["2", 3e-9]}}, ctx)["dq"]
    ok["link-bending 2/3 and 1/3"] = abs(lb["1"] - 2 * lb["2"]) < 1e-18
    p, R = fx.apply({"name": "thermal", "kappa": 1e-5}, ctx)["base"](np.array([1000.0, 0, 0]), np.eye(3), ctx)
    ok["thermal: 1000 mm grows 0.03 mm at 23 degC"] = abs(p[0] - 1000.03) < 1e-9
    m = fx.apply({"name": "tracker-drift", "shift": {"3": [0.1, 0, 0]}}, ctx)["meas"](np.zeros(3), ctx)
    ok["tracker-drift in session 3"] = m[0] == 0.1
    g = fx.apply({"name": "guide-straightness", "per": {"2": [0.04, 0.0]}}, ctx)["post"]["2"]
    ok["guide-straightness: bow 0.75 c at s = 0.5"] = abs(g[0, 3] - 0.03) < 1e-15
    return ok


def check_visibility(paths):
    """Zero amplitude gives the rigid data; a constant joint offset is absorbed by the rigid fit."""
    from tests.solver.diagnosis.blind9.cases import CASES
    d = tempfile.mkdtemp(prefix="blind9v_")
    base = [c for c in CASES if c["name"] == "lf_harm2_2"][0]
    out = {}
    z = dict(base, effect=fx.scaled(base["effect"], 0.0))
    gen.campaign(z, paths, d, 0, False)
    gen.campaign(dict(base, effect=None, kind="none"), paths, os.path.join(d, "b"), 0, False)
    a = open(os.path.join(d, "campaigns", base["name"], "data.csv")).read()
    b = open(os.path.join(d, "b", "campaigns", base["name"], "data.csv")).read()
    out["angle-harmonic at zero amplitude = the rigid data (lift)"] = a == b
    for fam, case, j, v in (("lift", "lf_harm2_2", "3", 2e-3), ("cyl", "cy_pitch_3", "2", 0.5)):
        c = [x for x in CASES if x["name"] == case][0]
        tr = gen.campaign(dict(c, effect={"name": "offset", "joint": j, "value": v}), paths, d, 0, True)
        out[f"{fam}: visibility of a constant offset of joint {j}"] = tr["visibility"]
    return out


def main(argv=None):
    ok = True
    print("1. serial FK of the imported robots against own DH products (max |deviation| mm, rotation x 1000) / "
          "this generator's FK against kin.py:")
    for k, (a, b) in check_serial_fk().items():
        print(f"   {k:8s} {a:.2e} / {b:.2e}")
        ok &= a < 1e-8 and b < 1e-8
    g, paths = check_gravity()
    print("2. gravity forces against -dV/dq (relative to the largest):")
    for k, v in g.items():
        print(f"   {k:8s} {v:.2e}")
        ok &= v < 1e-4
    w, r = check_hexapod_derivative(paths)
    print(f"3. hexapod output derivative against closed finite differences: {w:.2e} mm/mm, closure residual {r:.1e}")
    ok &= w < 1e-4 and r < 1e-8
    print("4. effect equations at known points:")
    for k, v in check_effects().items():
        print(f"   {k}: {v}")
        ok &= bool(v)
    print(f"5. zero amplitude and a constant offset (visibility, line {gen.VIS_LINE}):")
    for k, v in check_visibility(paths).items():
        print(f"   {k}: {v}")
        ok &= (v is True) or (not isinstance(v, bool) and v < 0.05)
    print("all checks passed" if ok else "SOME CHECKS FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
