"""Self-checks of the ninth blind generator (directory ``blind7``), without diagnose.

``python -m tests.solver.diagnosis.blind7.selfcheck`` (a few seconds).  Units: mm, rad.
1. the own model-file kinematics (``kin.py``) of the hyperstat-written model files against an own
   DH product (PUMA-like table) and an own URDF product (Denso-like URDF);
2. the generalized gravity forces (``generate.gravity_funcs``: -dV/dq by central differences)
   against the closed form ``z_j . sum_b (c_b - o_j) x m_b g`` of the declared masses;
3. the rigid visibility fit absorbs a constant joint offset (visibility near 0) and does not
   absorb a harmonic error (visibility well above the line).
"""
from __future__ import annotations

import os
import sys
import xml.etree.ElementTree as ET

import numpy as np

from . import generate as gen
from .kin import Model, rotvec_to_R

HERE = os.path.dirname(os.path.abspath(__file__))


def dh_fk(rows, q, tool):
    T = np.eye(4)
    for (a, alpha, d, theta), qi in zip(rows, q):
        c, s = np.cos(theta + qi), np.sin(theta + qi)
        ca, sa = np.cos(alpha), np.sin(alpha)
        T = T @ np.array([[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0, sa, ca, d], [0, 0, 0, 1]])
    Tt = np.eye(4)
    Tt[:3, 3] = tool
    return T @ Tt


def urdf_fk(path, q):
    root = ET.parse(path).getroot()
    T = np.eye(4)
    i = 0
    for j in root.findall("joint"):
        o = np.array([float(v) for v in j.find("origin").get("xyz").split()]) * 1000.0
        Tj = np.eye(4)
        Tj[:3, 3] = o
        T = T @ Tj
        if j.get("type") == "revolute":
            ax = np.array([float(v) for v in j.find("axis").get("xyz").split()])
            R = np.eye(4)
            R[:3, :3] = rotvec_to_R(ax * q[i])
            T = T @ R
            i += 1
    return T


def check_fk(rng):
    out = []
    import yaml
    with open(os.path.join(HERE, "robots", "puma560_like.dh.yaml")) as f:
        dh = yaml.safe_load(f)
    rows = [(j["a"], np.radians(j["alpha"]), j["d"], np.radians(j["theta"])) for j in dh["joints"]]
    for stem, fk in (("puma", lambda q: dh_fk(rows, q, dh["tool"]["origin"])),
                     ("denso_m", lambda q: urdf_fk(os.path.join(HERE, "robots", "denso_like.urdf"), q))):
        M = Model(os.path.join(HERE, "models", stem + ".skel.json"))
        worst = 0.0
        for _ in range(20):
            q = [rng.uniform(*M.joints[j].range) for j in M.actuated]
            A = M.output_pose(dict(zip(M.actuated, q)))
            B = fk(q)
            dev = np.abs(np.hstack([A[:3, 3] - B[:3, 3], 1000 * (A[:3, :3] - B[:3, :3]).ravel()])).max()
            worst = max(worst, dev)
        out.append((stem, worst))
    return out


def check_gravity(rng):
    res = []
    for stem in ("puma_m", "denso_m", "scara_m"):
        M = Model(os.path.join(HERE, "models", stem + ".skel.json"))
        masses = M.data["metadata"]["masses"]
        home = {j: M.joints[j].home for j in M.joints}
        _, _, jfh = M.frames(home)
        worst = 0.0
        for _ in range(5):
            q = {j: M.joints[j].home + 0.6 * rng.uniform(-1, 1) * 0.5 * (M.joints[j].range[1] - M.joints[j].range[0])
                 for j in M.actuated}
            q = {j: min(max(v, M.joints[j].range[0]), M.joints[j].range[1]) for j, v in q.items()}
            pay = 3.0
            grav, _ = gen.gravity_funcs(M, q, pay)
            tau = grav()
            F, _, jf = M.frames(q)
            names = M.actuated
            loads = []
            for j in names:
                c = np.append(np.asarray(masses[j]["com"], float), 1.0)
                loads.append((j, masses[j]["mass"], (jf[j] @ np.linalg.solve(jfh[j], c))[:3]))
            loads.append((None, pay, F[M.output][:3, 3]))
            for i, j in enumerate(names):
                Tj = jf[j]
                z, oj = Tj[:3, 2], Tj[:3, 3]
                down = set(names[i:])
                if M.joints[j].type == "R":
                    t = sum(z @ np.cross(c - oj, np.array([0, 0, -m * gen.fx.G])) for b, m, c in loads if b is None or b in down)
                else:
                    t = sum(z @ np.array([0, 0, -m * gen.fx.G]) for b, m, c in loads if b is None or b in down)
                worst = max(worst, abs(t - tau[j]) / (1.0 + abs(t)))
        res.append((stem, worst))
    return res


def check_offset_absorbed():
    out = []
    for cname, joint, size in (("pu_none", "2", 5e-4), ("tx_none", "42", 0.1), ("hx_none", "33", 0.1), ("sc_none", "3", 0.1)):
        case = dict(next(c for c in gen.CASES if c["name"] == cname))
        case["effect"] = "zero-creep"  # r t_op / 3600 with t_op = 3600 s for every pose: a constant offset
        case["params"] = {"joint": joint, "r": size}
        v = _vis_const(case, joint, size)
        case2 = dict(case)
        out.append((cname, joint, size, v))
    return out


def _vis_const(case, joint, size):
    orig = gen.fx.EFFECTS["zero-creep"]

    def const(ctx, p):
        m = gen.fx.Mod()
        m.add(p["joint"], p["r"])
        return m
    gen.fx.EFFECTS["zero-creep"] = const
    try:
        import tempfile
        with tempfile.TemporaryDirectory() as d:
            return gen.campaign(case, d, seed=0, vis=True)[1]
    finally:
        gen.fx.EFFECTS["zero-creep"] = orig


def main():
    rng = np.random.default_rng(7)
    ok = True
    print("1. own model-file kinematics against own DH / URDF products (max |deviation|, 20 poses; rotation entries x 1000):")
    for stem, w in check_fk(rng):
        print(f"   {stem:8s} {w:.2e} mm")
        ok &= w < 1e-6
    print("2. gravity forces -dV/dq (central differences) against z_j . sum (c_b - o_j) x m_b g (relative, 5 poses, payload 3 kg):")
    for stem, w in check_gravity(rng):
        print(f"   {stem:8s} {w:.2e}")
        ok &= w < 1e-4
    print("3. visibility of a constant joint offset (the rigid fit must absorb it; line 0.6):")
    for cname, joint, size, v in check_offset_absorbed():
        print(f"   {cname:8s} joint {joint} + {size}: {v:.3f}")
        ok &= v < 0.1
    print("all checks passed" if ok else "A CHECK FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
