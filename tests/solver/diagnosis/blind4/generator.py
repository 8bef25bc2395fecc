"""Campaign generator of the sixth blind generator (see RULES.md).  Units: mm, rad, degC, kg, s.

Every campaign is one true machine (the model file's defect parameters drawn by this generator,
projected so that an over-constrained machine still assembles), one tracker, its targets, one
effect implemented here (or none), metadata (time, temperature, payload, approach directions,
tracker sessions), noise as the header states (or more, for the understated-noise cases).  It writes
`data.csv`, `val.csv` (noisy), `nf.csv`, `nf.val.csv` (the same poses without noise, for the
visibility line) and `truth.json`.  Nothing here imports hyperstat.

    python -m tests.solver.diagnosis.blind4.generator --hyperstat .venv/bin/hyperstat --out out/blind4 --seeds 0
"""
from __future__ import annotations

import argparse
import json
import os
import zlib

import numpy as np

from . import robots
from .kinematics import (G_ACC, ModelKinematics, matrix_to_rotvec, rot_x, rot_y, rot_z,
                         rotvec_to_matrix, target_point, transform)

DEG = np.pi / 180.0
DAY = 86400.0

# ------------------------------------------------------------------------------------------------
# Families: targets (mm, output frame), tracker (base frame: x y z mm, rotation vector rad), noise.
FAMILIES = {
    "pal5": dict(kind="serial", poses=(90, 30), targets={"": (60.0, 40.0, 180.0)}, six_d=False,
                 tracker=(3200.0, -2600.0, 600.0, 0.0, 0.0, 2.3), noise=(0.008, 0.004), pos_unit="m",
                 payloads=(0.0, 60.0, 160.0), joint_unit="deg"),
    "ow6": dict(kind="serial", poses=(90, 30),
                targets={"N1": (70.0, 0.0, 40.0), "N2": (-35.0, 60.0, 40.0), "N3": (-35.0, -60.0, 40.0)},
                six_d=False, tracker=(-1900.0, 2100.0, 300.0, 0.0, 0.0, -0.9), noise=(0.015, 0.006),
                pos_unit="m", payloads=(0.0, 8.0, 20.0), joint_unit="deg"),
    "xa6": dict(kind="serial", poses=(80, 30), targets={"": (0.0, 0.0, 120.0)}, six_d=True,
                target_rot=(0.3, -0.2, 1.1), tracker=(1500.0, 900.0, 200.0, 0.0, 0.0, 3.6),
                noise=(0.012, 0.004), rot_noise=4e-5, rot_format="rotvec", pos_unit="mm",
                payloads=(0.0, 2.0, 5.0), joint_unit="deg"),
    "tx7": dict(kind="parallel", poses=(100, 30),
                targets={"R1": (60.0, -190.0, 0.0), "R2": (-60.0, -190.0, 0.0),
                         "R3": (0.0, -170.0, 60.0), "R4": (0.0, -170.0, -60.0)},
                six_d=False, tracker=(-1600.0, 1500.0, -300.0, 0.0, 0.0, 0.7), noise=(0.006, 0.004),
                pos_unit="mm", payloads=(0.0, 15.0, 40.0), joint_unit="mixed"),
    "hexa": dict(kind="parallel", poses=(80, 30), targets={"": (30.0, -20.0, 90.0)}, six_d=True,
                 target_rot=(-0.4, 0.25, 0.6), tracker=(1400.0, 1700.0, 900.0, 0.0, 0.0, -2.4),
                 noise=(0.004, 0.003), rot_noise=2e-5, rot_format="quat", pos_unit="mm",
                 payloads=(0.0, 20.0, 50.0), joint_unit="mm"),
}

# ------------------------------------------------------------------------------------------------
# Cases: (family, case, kind, effect, parameters).  kind: in / out / none / noise.
CASES = [
    # PAL5: palletiser-like 5-axis, masses declared, 1 reflector, positions in m
    ("pal5", "none", "none", None, {}),
    ("pal5", "understated-1.6", "noise", "noise", {"factor": 1.6}),
    ("pal5", "h1-j1", "in", "angle-harmonic-1", {"joint": "1", "amp": 6e-5}),
    ("pal5", "h2.5-j1", "in", "angle-harmonic-2.5", {"joint": "1", "amp": 6e-5}),
    ("pal5", "scale-j3", "in", "angle-scale", {"joint": "3", "s": 2e-4}),
    ("pal5", "compliance", "in", "compliance", {"c": {"2": 4e-11, "3": 8e-11, "4": 3e-10}}),
    ("pal5", "link-bending", "in", "link-bending", {"a": "2", "b": "3", "c": 5e-11}),
    ("pal5", "backlash-j1", "in", "backlash", {"beta": {"1": 2e-4}}),
    ("pal5", "gravity-backlash-j2", "in", "backlash-gravity", {"beta": {"2": 1.6e-4}}),
    ("pal5", "base-tilt", "in", "base-deformation", {"c": (1.5e-11, 1.5e-11)}),
    ("pal5", "thermal", "in", "thermal", {"kappa": 1.1e-5}),
    ("pal5", "tracker-drift", "in", "tracker-drift", {"d": (0.05, -0.04, 0.06)}),
    ("pal5", "elbow-bimetal", "out", "joint-offset-temperature", {"joint": "3", "g": 2e-5}),
    ("pal5", "dresspack-drag", "out", "coupling", {"joint": "1", "from": "3", "c": 1.2e-4}),
    ("pal5", "j2-thermal-scale", "out", "scale-temperature", {"joint": "2", "g": 2e-5}),
    # OW6: offset-wrist 6R, no masses, 3 reflectors, positions in m
    ("ow6", "none", "none", None, {}),
    ("ow6", "understated-1.45", "noise", "noise", {"factor": 1.45}),
    ("ow6", "h3-j1", "in", "angle-harmonic-3", {"joint": "1", "amp": 9e-5}),
    ("ow6", "h2-j4", "in", "angle-harmonic-2", {"joint": "4", "amp": 4.5e-4}),
    ("ow6", "scale-j2", "in", "angle-scale", {"joint": "2", "s": 1.5e-4}),
    ("ow6", "backlash-j3", "in", "backlash", {"beta": {"3": 2.5e-4}}),
    ("ow6", "thermal", "in", "thermal", {"kappa": 2.3e-5}),
    ("ow6", "tracker-drift", "in", "tracker-drift", {"d": (-0.08, 0.07, 0.05)}),
    ("ow6", "gripper-spread", "out", "payload-offset", {"mm_per_kg": (0.006, 0.0, -0.003)}),
    ("ow6", "nest-settling", "out", "nest-wear", {"target": "N2", "mm_per_day": 0.15}),
    ("ow6", "wrist-windup", "out", "coupling", {"joint": "6", "from": "4", "c": 4e-4}),
    # XA6: light cobot from a URDF with inertials, one 6-D probe
    ("xa6", "none", "none", None, {}),
    ("xa6", "understated-1.6", "noise", "noise", {"factor": 1.6}),
    ("xa6", "compliance", "in", "compliance", {"c": {"joint2": 4e-9, "joint3": 6e-9}}),
    ("xa6", "gravity-backlash-j2", "in", "backlash-gravity", {"beta": {"joint2": 3e-4}}),
    ("xa6", "h2-j1", "in", "angle-harmonic-2", {"joint": "joint1", "amp": 1.2e-4}),
    ("xa6", "scale-j3", "in", "angle-scale", {"joint": "joint3", "s": 2e-4}),
    ("xa6", "h1-j2", "in", "angle-harmonic-1", {"joint": "joint2", "amp": 1e-4}),
    ("xa6", "link-bending", "in", "link-bending", {"a": "joint2", "b": "joint3", "c": 5e-9}),
    ("xa6", "thermal", "in", "thermal", {"kappa": 2.3e-5}),
    ("xa6", "stylus-sag", "out", "stylus-sag", {"mm": 0.05}),
    ("xa6", "j1-warmup", "out", "joint-warmup", {"joint": "joint1", "amp": 2.5e-4, "tau_s": 2400.0}),
    # TX7: Tripteor X7 model file, moving mass 120 kg, 4 reflectors
    ("tx7", "none", "none", None, {}),
    ("tx7", "understated-1.5", "noise", "noise", {"factor": 1.5}),
    ("tx7", "leg-thermal", "in", "leg-thermal", {"kappa": {"41": 1.2e-5, "42": 1.2e-5, "43": 1.2e-5}}),
    ("tx7", "screw-pitch", "in", "screw-pitch", {"s": {"41": 1.5e-3, "42": -1.2e-3, "43": 1.5e-3}}),
    ("tx7", "screw-periodic-41", "in", "screw-periodic", {"amp": {"41": 0.018}, "lead": 10.0}),
    ("tx7", "straightness-42", "in", "guide-straightness", {"bow": {"42": (0.045, 0.0)}}),
    ("tx7", "clearance", "in", "joint-clearance", {"beta": {"41": 0.05, "42": 0.07, "43": 0.04}}),
    ("tx7", "base-tilt", "in", "base-deformation", {"c": (4e-10, 4e-10)}),
    ("tx7", "compliance", "in", "compliance", {"c": {"41": 1.5e-4, "42": 1.5e-4, "43": 1.5e-4}}),
    ("tx7", "backlash-42", "in", "backlash", {"beta": {"42": 0.05}}),
    ("tx7", "h1-c-axis", "in", "angle-harmonic-1", {"joint": "6", "amp": 3e-4}),
    ("tx7", "thermal", "in", "thermal", {"kappa": 1.2e-5}),
    ("tx7", "tracker-drift", "in", "tracker-drift", {"d": (0.03, -0.04, 0.025)}),
    ("tx7", "base-gradient", "out", "seat-sink-temperature", {"element": "12", "mm_per_degC": 0.012}),
    ("tx7", "wrist-drag", "out", "coupling", {"joint": "6", "from": "42", "c": 8e-4 / 150.0}),
    ("tx7", "spindle-sag", "out", "tool-sag", {"rad": 6e-4}),
    # HEXA: hexapod model file, moving mass 60 kg, screw lead 5 mm declared, one 6-D target
    ("hexa", "none", "none", None, {}),
    ("hexa", "understated-1.7", "noise", "noise", {"factor": 1.7}),
    ("hexa", "leg-thermal", "in", "leg-thermal", {"kappa": {n: 1.2e-5 for n in ("31", "32", "33", "34", "35", "36")}}),
    ("hexa", "screw-pitch-33", "in", "screw-pitch", {"s": {"33": 1.8e-3}}),
    ("hexa", "screw-periodic-35", "in", "screw-periodic", {"amp": {"35": 0.025}, "lead": 5.0}),
    ("hexa", "screw-periodic-half-lead-32", "in", "screw-periodic", {"amp": {"32": 0.025}, "lead": 2.5}),
    ("hexa", "clearance", "in", "joint-clearance", {"beta": {n: 0.05 for n in ("31", "32", "33", "34", "35", "36")}}),
    ("hexa", "base-tilt", "in", "base-deformation", {"c": (1e-9, 1e-9)}),
    ("hexa", "compliance", "in", "compliance", {"c": {n: 3e-4 for n in ("31", "32", "33", "34", "35", "36")}}),
    ("hexa", "backlash-31", "in", "backlash", {"beta": {"31": 0.03}}),
    ("hexa", "thermal", "in", "thermal", {"kappa": 1.2e-5}),
    ("hexa", "tracker-drift", "in", "tracker-drift", {"d": (0.02, 0.03, -0.025)}),
    ("hexa", "screw-warmup-34", "out", "joint-warmup", {"joint": "34", "amp": 0.08, "tau_s": 1800.0}),
    ("hexa", "screw-travel-heating", "out", "travel-heating", {"mm_per_mm": 1.5e-4, "tau_poses": 12.0}),
]


# ------------------------------------------------------------------------------------------------
class Machine:
    """One family's model file, its own kinematics and mass model."""

    def __init__(self, family, model_path):
        self.family = family
        self.cfg = FAMILIES[family]
        self.path = model_path
        self.kin = ModelKinematics(model_path)
        md = self.kin.model.get("metadata", {})
        self.serial = self.cfg["kind"] == "serial"
        self.moving_mass = float(md.get("moving_mass", 0.0) or 0.0)
        if family == "xa6":
            self.body_masses = self._urdf_masses()
        else:
            self.body_masses = robots.serial_masses(self.kin) if self.serial else []
        self.has_masses = bool(self.body_masses) or self.moving_mass > 0
        self.forced_basis = None

    def _urdf_masses(self):
        """Bodies from the URDF's own inertials (second source beside the import's metadata)."""
        out = []
        for (n, xyz, rpy, lo, hi), (link, m, c) in zip(robots.XA6_JOINTS, robots.XA6_INERTIALS):
            out.append((n, m, np.array(c) * 1000.0))  # com in the joint's moving frame (= link frame)
        return out

    # ---------------------------------------------------------------- poses
    def sample_poses(self, rng, n):
        k = self.kin
        ranges = {nm: k.elements[k.elem_by_name[nm]].rng for nm in k.actuated}
        out = []
        if self.family == "pal5":
            while len(out) < n:
                q1 = rng.uniform(-3.2, 3.2)
                q2 = rng.uniform(-0.6, 1.2)
                q3 = rng.uniform(-0.95, 0.95)
                q4 = np.clip(-(q2 + q3) + rng.uniform(-0.35, 0.35), -2.0, 2.0)  # flange near level
                q5 = rng.uniform(-6.0, 6.0)
                out.append(np.array([q1, q2, q3, q4, q5]))
        elif self.family == "ow6":
            # two work zones (left and right of the pedestal), the wrist turned freely
            while len(out) < n:
                zone = rng.integers(2)
                q1 = rng.uniform(-3.15, -0.6) if zone == 0 else rng.uniform(0.6, 3.15)
                q = [q1, rng.uniform(-1.3, 1.1), rng.uniform(-1.7, 0.9), rng.uniform(-3.25, 3.25),
                     rng.uniform(-1.9, 1.9), rng.uniform(-6.1, 6.1)]
                out.append(np.array(q))
        elif self.family == "xa6":
            while len(out) < n:
                q = [rng.uniform(-6.0, 6.0), rng.uniform(-1.6, 1.6), rng.uniform(-3.4, -0.1),
                     rng.uniform(-3.0, 3.0), rng.uniform(-1.4, 2.8), rng.uniform(-3.0, 3.0)]
                out.append(np.array(q))
        else:
            # parallel: legs within 85 % of their strokes, wrist joints within their ranges; kept when
            # the machine assembles with every passive joint in range
            tries = 0
            while len(out) < n:
                tries += 1
                if tries > 200 * n:
                    raise RuntimeError(f"{self.family}: too few assembled poses")
                q = []
                for nm in k.actuated:
                    lo, hi = ranges[nm]
                    mid, half = (lo + hi) / 2, (hi - lo) / 2
                    q.append(rng.uniform(mid - 0.85 * half, mid + 0.85 * half))
                q = np.array(q)
                qa, fk, rn, ok = k.assemble(q)
                if rn < 1e-7 and ok:
                    out.append(q)
        return out

    # ---------------------------------------------------------------- gravity
    def point_masses(self, fk, payload):
        """(mass, world point, ancestors) of every declared mass and the payload at the output."""
        k = self.kin
        pts = []
        for n, m, c in self.body_masses:
            ei = k.elem_by_name[n]
            t = fk["P"][ei]
            pts.append((m, t[:3, :3] @ c + t[:3, 3], fk["anc"][ei]))
        tout, anc = k.frame_of(fk, k.output)
        mo = payload + self.moving_mass
        if mo > 0:
            pts.append((mo, tout[:3, 3].copy(), anc))
        return pts


# ------------------------------------------------------------------------------------------------
def draw_geometry(machine: Machine, rng):
    """True defect values: angles within +-2.5e-4 rad, lengths within +-0.08 mm (uniform), projected
    on the directions that keep every loop closed at first order (over-constrained machines)."""
    k = machine.kin
    names = k.param_names
    kinds = []
    for el in k.elements:
        for comp, nm in el.defects.items():
            kinds.append("angle" if comp in "IJKG" else "length")
    x = np.array([rng.uniform(-2.5e-4, 2.5e-4) if kd == "angle" else rng.uniform(-0.08, 0.08) for kd in kinds])
    if machine.forced_basis is None:
        machine.forced_basis = forced_basis(machine)
    v = machine.forced_basis
    if v.size:
        x = x - v.T @ (v @ x)
    return dict(zip(names, x.tolist()))


def forced_basis(machine: Machine):
    """Defect directions that open a loop at first order (own stationarity check, 16 poses)."""
    k = machine.kin
    names = k.param_names
    if k.closing and names:
        rows = []
        prng = np.random.default_rng(12345)
        configs = machine.sample_poses(prng, 16)
        scale = np.concatenate([[1, 1, 1, 1000, 1000, 1000]] * len(k.closing))
        pidx = [k.jpos[n] for n in k.passive]
        for qa in configs:
            q, fk, rn, ok = k.assemble(qa)
            r0, j = k.closure(fk)
            jp = j[:, pidx] * scale[:, None]
            proj = np.eye(len(r0)) - jp @ np.linalg.pinv(jp)
            if np.linalg.norm(proj) < 1e-8:
                continue  # the passive joints absorb every loop error here
            jd = np.zeros((len(r0), len(names)))
            for i, nm in enumerate(names):
                h = 1e-6
                fkp = k.forward(q, {nm: h})
                fkm = k.forward(q, {nm: -h})
                jd[:, i] = (k.closure(fkp)[0] - k.closure(fkm)[0]) * scale / (2 * h)
            rows.append(proj @ jd)
        if not rows:
            return np.zeros((0, len(names)))
        a = np.vstack(rows)
        u, s, vt = np.linalg.svd(a, full_matrices=False)
        rank = int(np.sum(s > s[0] * 1e-9))
        return vt[:rank]
    return np.zeros((0, len(names)))


# ------------------------------------------------------------------------------------------------
def timeline(rng, n, payloads):
    """Metadata of n poses in measuring order: two sessions (days), temperature with a daily rise
    and fluctuations, payload changed every 8 poses, approach directions at random."""
    half = n // 2
    t = np.zeros(n)
    sess = np.zeros(n, int)
    temp = np.zeros(n)
    for i in range(n):
        s = 1 if i < half else 2
        j = i if s == 1 else i - half
        ts = 90.0 * j + rng.uniform(0, 20)
        t[i] = ts + (0.0 if s == 1 else DAY)
        sess[i] = s
        base = 18.0 if s == 1 else 20.5
        temp[i] = base + 5.0 * (1 - np.exp(-ts / 2500.0)) + 0.8 * np.sin(ts / 700.0) + rng.normal(0, 0.15)
    pay = np.array([payloads[(i // 8 + (i // 24)) % len(payloads)] for i in range(n)])
    return t, sess, temp, pay


def harmonic_order(effect):
    return float(effect.split("-")[-1])


class Truth:
    """Applies one effect to the true machine (the generator's own implementation)."""

    def __init__(self, machine: Machine, geometry, effect, prm, rng):
        self.m = machine
        self.g = geometry
        self.effect = effect
        self.prm = prm
        self.phase = rng.uniform(0, 2 * np.pi, size=8)
        self.heat = None

    def assemble(self, q_act, pre=None, post=None, q_start=None):
        return self.m.kin.assemble(q_act, self.g, pre, post, q_start)

    def pose(self, q_cmd, meta, state):
        """True output frame, targets (world, mm) and orientation for commanded actuated values."""
        k, e, p = self.m.kin, self.effect, self.prm
        temp, pay, tsec, sess, dirs = meta["T"], meta["payload"], meta["t"], meta["session"], meta["dir"]
        dT = temp - 20.0
        act = list(k.actuated)
        dq = np.zeros(len(act))
        pre, post = {}, {}
        # loads at the commanded pose of the true geometry
        need_loads = e in ("compliance", "backlash-gravity", "joint-clearance", "link-bending")
        q0, fk0, tau = state.get("q"), None, None
        if need_loads or e in ("leg-thermal",):
            q0, fk0, rn0, _ = self.assemble(q_cmd, q_start=state.get("q"))
        if need_loads:
            tau = k.gravity_loads(fk0, self.m.point_masses(fk0, pay))
        if e and e.startswith("angle-harmonic"):
            kk = harmonic_order(e)
            i = act.index(p["joint"])
            dq[i] += p["amp"] * np.sin(kk * q_cmd[i] + self.phase[0])
        elif e == "angle-scale":
            i = act.index(p["joint"])
            dq[i] += p["s"] * q_cmd[i]
        elif e == "compliance":
            for n, c in p["c"].items():
                dq[act.index(n)] += c * tau[act.index(n)]
        elif e == "backlash":
            for n, b in p["beta"].items():
                dq[act.index(n)] += -0.5 * b * dirs[act.index(n)]
        elif e == "backlash-gravity":
            for n, b in p["beta"].items():
                dq[act.index(n)] += 0.5 * b * np.sign(tau[act.index(n)])
        elif e == "joint-clearance":
            for n, b in p["beta"].items():
                dq[act.index(n)] += 0.5 * b * np.sign(tau[act.index(n)])
        elif e == "screw-pitch":
            for n, s in p["s"].items():
                dq[act.index(n)] += s * q_cmd[act.index(n)]
        elif e == "screw-periodic":
            for j, (n, a) in enumerate(p["amp"].items()):
                i = act.index(n)
                dq[i] += a * np.sin(2 * np.pi * q_cmd[i] / p["lead"] + self.phase[j])
        elif e == "leg-thermal":
            # each leg (base joint centre to platform joint centre) grows by kappa dT times its length
            for n, kap in p["kappa"].items():
                ch = k.chains[k.elements[k.elem_by_name[n]].chain]
                js = [ei for ei in ch["elements"] if k.elements[ei].kind == "joint"]
                a0 = fk0["L"][js[0]][:3, 3]
                pj = [ei for ei in js if k.elements[ei].name != n and ch["elements"].index(ei) > ch["elements"].index(k.elem_by_name[n])]
                b0 = fk0["L"][pj[0]][:3, 3]
                dq[act.index(n)] += kap * dT * np.linalg.norm(b0 - a0)
        elif e == "guide-straightness":
            for n, (cx, cy) in p["bow"].items():
                lo, hi = k.elements[k.elem_by_name[n]].rng
                mid, h = (lo + hi) / 2, (hi - lo) / 2

                def bow(qj, cx=cx, cy=cy, mid=mid, h=h):
                    s = (qj - mid) / h
                    slope = -2 * s / h
                    t = transform(None, [cx * (1 - s * s), cy * (1 - s * s), 0.0])
                    return t @ transform(rot_y(cx * slope) @ rot_x(-cy * slope))
                post[n] = bow
        elif e == "link-bending":
            # the link from joint a to joint b bends as a cantilever: end slope theta = c tau_a,
            # end deflection 2/3 L theta, in the plane normal to joint a's axis
            ia = act.index(p["a"])
            theta = p["c"] * tau[ia]
            eb = k.elem_by_name[p["b"]]
            la = fk0["L"][k.elem_by_name[p["a"]]]
            lb = fk0["L"][eb]
            axis = la[:3, 2]
            arm = lb[:3, 3] - la[:3, 3]
            arm_perp = arm - axis * (axis @ arm)
            length = np.linalg.norm(arm_perp)
            w_dir = np.cross(axis, arm_perp) / length
            w = 2.0 / 3.0 * length * theta
            # world displacement and rotation of frame b, expressed in the frame before b
            parent = fk0["P"][eb - 1] if eb - 1 in fk0["P"] and k.elements[eb - 1].chain == k.elements[eb].chain else np.eye(4)
            rw = rotvec_to_matrix(axis * theta)
            dw = w * w_dir

            def bend(t_pl, parent=parent, rw=rw, dw=dw, lb=lb):
                # world pose of L_b: T = parent @ t_pl; bent: T' = [rw R, p + dw]
                tw = parent @ t_pl
                tb = np.eye(4)
                tb[:3, :3] = rw @ tw[:3, :3]
                tb[:3, 3] = tw[:3, 3] + dw
                return np.linalg.solve(parent, tb)
            pre[p["b"]] = bend
        elif e == "joint-offset-temperature":
            dq[act.index(p["joint"])] += p["g"] * dT
        elif e == "scale-temperature":
            i = act.index(p["joint"])
            dq[i] += p["g"] * dT * q_cmd[i]
        elif e == "coupling":
            i, j = act.index(p["joint"]), act.index(p["from"])
            lo, hi = k.elements[k.elem_by_name[p["from"]]].rng
            dq[i] += p["c"] * (q_cmd[j] - (lo + hi) / 2)
        elif e == "joint-warmup":
            ts = tsec - (0.0 if sess == 1 else DAY)
            dq[act.index(p["joint"])] += p["amp"] * (1 - np.exp(-ts / p["tau_s"]))
        elif e == "travel-heating":
            prev = state.get("q_prev")
            if self.heat is None:
                self.heat = np.zeros(len(act))
            if prev is not None:
                self.heat = self.heat * np.exp(-1.0 / p["tau_poses"]) + np.abs(q_cmd - prev)
            pris = np.array([k.elements[k.elem_by_name[n]].jtype == "P" for n in act])
            dq += p["mm_per_mm"] * self.heat * pris
        elif e == "seat-sink-temperature":
            sink = p["mm_per_degC"] * dT

            def sink_fn(t_pl, sink=sink):
                t2 = t_pl.copy()
                t2[2, 3] -= sink  # the base frame is the element's parent
                return t2
            pre[p["element"]] = sink_fn
        elif e == "thermal":
            kap = p["kappa"] * dT

            def grow(t_pl, kap=kap):
                t2 = t_pl.copy()
                t2[:3, 3] *= (1 + kap)
                return t2
            for el in k.elements:
                pre[el.name] = grow
            for i, n in enumerate(act):  # the screws grow with the structure
                if k.elements[k.elem_by_name[n]].jtype == "P":
                    dq[i] += kap * q_cmd[i]
        q_true = q_cmd + dq
        q, fk, rn, ok = self.assemble(q_true, pre, post, q_start=q0)
        state["q"] = q
        state["closure"] = max(state.get("closure", 0.0), rn)
        tout, _ = k.frame_of(fk, k.output)
        offsets = {}
        for name, off in self.m.cfg["targets"].items():
            off = np.array(off, float)
            if e == "thermal":
                off = off * (1 + p["kappa"] * dT)
            if e == "nest-wear" and name == p["target"]:
                off = off - np.array([0, 0, 1.0]) * p["mm_per_day"] * tsec / DAY
            if e == "payload-offset":  # the gripper's fingers spread with the load they hold
                off = off + np.array(p["mm_per_kg"]) * pay
            if e == "stylus-sag":
                gl = tout[:3, :3].T @ np.array([0, 0, -1.0])  # gravity in the tool frame
                gperp = gl - np.array([0, 0, 1.0]) * gl[2]
                off = off + p["mm"] * gperp
            offsets[name] = off
        rot_extra = np.eye(3)
        if e == "tool-sag":
            tz = tout[:3, 2]
            ax = np.cross(tz, np.array([0, 0, -1.0]))
            rot_extra = rotvec_to_matrix(p["rad"] * ax)  # sags toward gravity, zero when vertical
        pts = {}
        for name, off in offsets.items():
            if e == "tool-sag":  # pivot: the housing, 150 mm up the tool axis from the output frame
                pivot = tout[:3, 3] - 150.0 * tout[:3, 2]
                pts[name] = pivot + rot_extra @ (target_point(tout, off) - pivot)
            else:
                pts[name] = target_point(tout, off)
        r_out = rot_extra @ tout[:3, :3]
        if e == "base-deformation":
            mom = np.zeros(3)
            for m, c, _ in self.m.point_masses(fk, pay):
                mom += np.cross(c, np.array([0, 0, -m * G_ACC]))
            th = p["c"][0] * mom[0] * np.array([1.0, 0, 0]) + p["c"][1] * mom[1] * np.array([0, 1.0, 0])
            rt = rotvec_to_matrix(th)
            pts = {n: rt @ v for n, v in pts.items()}
            r_out = rt @ r_out
        return pts, r_out


# ------------------------------------------------------------------------------------------------
def fmt(v):
    return f"{v:.10g}"


def joint_columns(machine):
    k = machine.kin
    fam = machine.family
    if fam == "pal5":
        return [f"J{i}[deg]" for i in range(1, 6)]
    if fam in ("ow6", "xa6"):
        return [f"q{n}[deg]" for n in k.actuated]
    cols = []
    for n in k.actuated:
        el = k.elements[k.elem_by_name[n]]
        if el.jtype == "P":
            cols.append(f"q{n}[mm]")
        else:
            cols.append(f"q{n}[deg]" if n == "6" else f"q{n}[rad]")
    return cols


def joint_values(machine, q):
    fam = machine.family
    k = machine.kin
    if fam == "pal5":
        d = np.asarray(q) / DEG
        # inverse of the joint map: q1 = J1, q2 = J2, q3 = J3 - J2, q4 = J4 + 0.5, q5 = -J5 (deg)
        return [d[0], d[1], d[2] + d[1], d[3] - 0.5, -d[4]]
    if fam in ("ow6", "xa6"):
        return list(np.asarray(q) / DEG)
    out = []
    for n, v in zip(k.actuated, q):
        el = k.elements[k.elem_by_name[n]]
        out.append(v / DEG if (el.jtype == "R" and n == "6") else v)
    return out


def quat_from_matrix(r):
    w = matrix_to_rotvec(r)
    a = np.linalg.norm(w)
    if a < 1e-15:
        return np.array([1.0, 0, 0, 0])
    return np.concatenate([[np.cos(a / 2)], np.sin(a / 2) * w / a])


def write_csv(path, machine, header_noise, rows, names):
    cfg = machine.cfg
    tr = cfg["tracker"]
    lines = ["# hyperstat measurements, version 1", f"# mechanism: {machine.kin.model['name']}",
             f"# noise: {header_noise[0]:g} mm + {header_noise[1]:g} mm/m",
             f"# tracker: {tr[0]:g} {tr[1]:g} {tr[2]:g} {tr[3]:g} {tr[4]:g} {tr[5]:g}"]
    if cfg["six_d"]:
        lines.append(f"# orientation noise: {cfg['rot_noise'] * 1000:g} mrad")
    for tname, off in cfg["targets"].items():
        pr = np.round(np.array(off) + np.array([3.0, -2.0, 4.0]), 1)  # rough prior, a few mm off
        lines.append(f"# target{(' ' + tname) if tname else ''}: {pr[0]:g} {pr[1]:g} {pr[2]:g}")
    lines.append("# written by tests/solver/diagnosis/blind4 (sixth blind generator)")
    u = cfg["pos_unit"]
    cols = ["pose"] + joint_columns(machine)
    for tname in cfg["targets"]:
        sfx = f"_{tname}" if tname else ""
        cols += [f"x{sfx}[{u}]", f"y{sfx}[{u}]", f"z{sfx}[{u}]"]
        if cfg["six_d"]:
            if cfg["rot_format"] == "quat":
                cols += ["quat_w", "quat_x", "quat_y", "quat_z"]
            else:
                cols += ["rx[rad]", "ry[rad]", "rz[rad]"]
    cols += [f"dir{n}" for n in machine.kin.actuated] + ["payload[kg]", "session", "temperature[degC]", "time[s]"]
    lines.append(",".join(cols))
    for r in rows:
        lines.append(",".join([r["pose"]] + [fmt(v) for v in r["vals"]]))
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(tmp, path)


class Design:
    """What every case of one family and seed shares: the true geometry, the poses, the time line,
    the held-out split, the approach directions; the noise-free measurements without any effect, and
    the rigid model's linearised columns at the truth (for the visibility line)."""

    def __init__(self, machine, seed):
        rng = np.random.default_rng([seed, zlib.crc32(machine.family.encode())])
        cfg = machine.cfg
        n_id, n_val = cfg["poses"]
        self.n = n = n_id + n_val
        self.geometry = draw_geometry(machine, rng)
        self.poses = machine.sample_poses(rng, n)
        self.t, self.sess, self.temp, self.pay = timeline(rng, n, cfg["payloads"])
        self.is_val = np.zeros(n, bool)
        self.is_val[rng.choice(n, n_val, replace=False)] = True
        self.dirs = rng.choice([-1, 1], size=(n, len(machine.kin.actuated)))
        tr = cfg["tracker"]
        self.r_trk = rotvec_to_matrix(tr[3:])
        self.o_trk = np.array(tr[:3], float)
        self.machine = machine
        self.baseline = self.measure(Truth(machine, self.geometry, None, {}, rng), None, {})
        self.sigma = self.baseline[2]
        self.columns = rigid_columns(machine, self)
        v = machine.forced_basis
        if v is not None and v.size:
            # the rigid model holds the forced defect combinations at zero: their columns (a loop
            # that cannot close) are projected out
            npar = len(machine.kin.param_names)
            jd = self.columns[:, :, :npar]
            self.columns[:, :, :npar] = jd - (jd @ v.T) @ v
        # prior size of each rigid unknown: the defects as drawn, tracker 50 mm / 0.05 rad, targets 10 mm
        k = machine.kin
        kinds = {nm: (2.5e-4 if comp in "IJKG" else 0.08) for el in k.elements for comp, nm in el.defects.items()}
        self.prior = np.array([kinds[nm] for nm in k.param_names] + [50.0] * 3 + [0.05] * 3
                              + [10.0] * (3 * len(cfg["targets"])))

    def meta(self, i):
        return {"T": self.temp[i], "payload": self.pay[i], "t": self.t[i], "session": self.sess[i],
                "dir": self.dirs[i]}

    def measure(self, truth, eff, prm):
        """Noise-free measurements (tracker frame, mm; orientation matrices) of every pose and target."""
        cfg = self.machine.cfg
        state = {}
        pos = np.zeros((self.n, len(cfg["targets"]), 3))
        rot = []
        sig = np.zeros((self.n, len(cfg["targets"])))
        for i in range(self.n):
            pts, r_out = truth.pose(self.poses[i], self.meta(i), state)
            state["q_prev"] = self.poses[i]
            for k, tname in enumerate(cfg["targets"]):
                p = pts[tname]
                d_m = np.linalg.norm(p - self.o_trk) / 1000.0
                if eff == "refraction":
                    p = p + np.array([0, 0, 1.0]) * (1e-6 * prm["gradient_K_per_m"] * d_m ** 2 / 2 * 1000.0)
                m = self.r_trk.T @ (p - self.o_trk)
                if eff == "tracker-drift" and self.sess[i] == 2:
                    m = m + np.array(prm["d"])
                pos[i, k] = m
                sig[i, k] = cfg["noise"][0] + cfg["noise"][1] * d_m
            rot.append(self.r_trk.T @ r_out)
        self.last_closure = state.get("closure", 0.0)
        return pos, rot, sig


def rigid_columns(machine, design, h_angle=1e-6, h_len=1e-4):
    """d(measured position)/d(rigid unknowns) at the truth: every defect parameter of the model file
    (finite differences at fixed actuated joints, the passive joints following the closures to first
    order), the tracker frame (6) and each target offset (3).  Rows: pose, target, axis."""
    k = machine.kin
    cfg = machine.cfg
    offs = [np.array(o, float) for o in cfg["targets"].values()]
    names = k.param_names
    kinds = {}
    for el in k.elements:
        for comp, nm in el.defects.items():
            kinds[nm] = h_angle if comp in "IJKG" else h_len
    pidx = [k.jpos[n] for n in k.passive]
    rt = design.r_trk
    blocks = []
    cache0 = k.placements(design.geometry)
    owner = {nm: ei for ei, el in enumerate(k.elements) for nm in el.defects.values()}
    caches = {}
    for nm in names:
        ei = owner[nm]
        pair = []
        for sgn in (1.0, -1.0):
            gg = dict(design.geometry)
            gg[nm] = gg.get(nm, 0.0) + sgn * kinds[nm]
            cc = dict(cache0)
            cc[ei] = k.placement(k.elements[ei], gg)
            pair.append(cc)
        caches[nm] = pair
    state_q = None
    for i in range(design.n):
        q, fk, rn, ok = k.assemble(design.poses[i], design.geometry, q_start=state_q)
        state_q = q
        tout, anc = k.frame_of(fk, k.output)
        pts = [tout[:3, :3] @ o + tout[:3, 3] for o in offs]
        if k.closing:
            _, jc = k.closure(fk)
            pinv = np.linalg.pinv(jc[:, pidx])
            axes = k.joint_axes(fk)
            jpass = [k.point_jacobian(fk, p, anc, axes)[:3][:, pidx] for p in pts]
        ncol = len(names) + 6 + 3 * len(offs)
        blk = np.zeros((3 * len(offs), ncol))
        for c, nm in enumerate(names):
            h = kinds[nm]
            f1 = k.forward(q, None, cache=caches[nm][0])
            f2 = k.forward(q, None, cache=caches[nm][1])
            t1, _ = k.frame_of(f1, k.output)
            t2, _ = k.frame_of(f2, k.output)
            if k.closing:
                dr = (k.closure(f1)[0] - k.closure(f2)[0]) / (2 * h)
                dqp = -pinv @ dr
            for j, o in enumerate(offs):
                dp = ((t1[:3, :3] @ o + t1[:3, 3]) - (t2[:3, :3] @ o + t2[:3, 3])) / (2 * h)
                if k.closing:
                    dp = dp + jpass[j] @ dqp
                blk[3 * j:3 * j + 3, c] = rt.T @ dp
        for j, p in enumerate(pts):
            m = rt.T @ (p - design.o_trk)
            blk[3 * j:3 * j + 3, len(names):len(names) + 3] = -rt.T
            blk[3 * j:3 * j + 3, len(names) + 3:len(names) + 6] = np.array(
                [[0, -m[2], m[1]], [m[2], 0, -m[0]], [-m[1], m[0], 0]]).T
            blk[3 * j:3 * j + 3, len(names) + 6 + 3 * j:len(names) + 9 + 3 * j] = rt.T @ tout[:3, :3]
        blocks.append(blk)
    return np.array(blocks)  # (poses, 3 * targets, columns)


def visibility(design, delta):
    """Held-out RMS of what a rigid calibration of the identification poses leaves of `delta` (the
    noise-free change of the measurements an effect makes), over the stated noise RMS (3-D).

    The calibration is the maximum a posteriori fit with the rigid unknowns' prior sizes
    (`design.prior`): directions the noise cannot determine (the hexapod's many weak defect
    combinations) are not fitted exactly, as a calibration with noisy data would not."""
    sig = np.repeat(design.sigma, 3, axis=1)  # (poses, 3 * targets)
    d = delta.reshape(design.n, -1)
    ids, vals = ~design.is_val, design.is_val
    a = design.columns[ids].reshape(-1, design.columns.shape[2]) / sig[ids].reshape(-1, 1) * design.prior
    y = (d[ids] / sig[ids]).reshape(-1)
    u, s, vt = np.linalg.svd(a, full_matrices=False)
    x = vt.T @ ((s / (s ** 2 + 1.0)) * (u.T @ y))
    theta = x * design.prior
    res = d[vals] - (design.columns[vals] @ theta)
    res3 = res.reshape(-1, 3)
    noise3 = np.sqrt(3 * np.mean(design.sigma[vals] ** 2))
    return float(np.sqrt(np.mean(np.sum(res3 ** 2, axis=1))) / noise3)


def generate_campaign(machine, design, family, case, kind, effect, prm, seed, out_dir):
    rng = np.random.default_rng([seed, zlib.crc32(f"{family}/{case}".encode())])
    cfg = machine.cfg
    eff = None if kind in ("none", "noise") else effect
    if eff is None:
        pos, rot, sig = design.baseline
        closure = 0.0
    else:
        pos, rot, sig = design.measure(Truth(machine, design.geometry, eff, prm, rng), eff, prm)
        closure = design.last_closure
    vis = visibility(design, pos - design.baseline[0]) if eff is not None else None
    r_tgt = rotvec_to_matrix(cfg.get("target_rot", (0, 0, 0)))
    factor = prm.get("factor", 1.0) if kind == "noise" else 1.0
    a, b = cfg["noise"]
    unit = 1000.0 if cfg["pos_unit"] == "m" else 1.0
    rows = {"id": [], "val": [], "nf_id": [], "nf_val": []}
    for i in range(design.n):
        vals_clean, vals_noisy = [], []
        for k, tname in enumerate(cfg["targets"]):
            m = pos[i, k]
            mn = m + rng.normal(0, sig[i, k] * factor, 3)
            vals_clean += list(m / unit)
            vals_noisy += list(mn / unit)
            if cfg["six_d"]:
                r_meas = rot[i] @ r_tgt
                rn = rotvec_to_matrix(rng.normal(0, cfg["rot_noise"] * factor, 3)) @ r_meas
                for rr, lst in ((r_meas, vals_clean), (rn, vals_noisy)):
                    if cfg["rot_format"] == "quat":
                        qv = quat_from_matrix(rr)
                        lst += list(qv if qv[0] >= 0 else -qv)
                    else:
                        lst += list(matrix_to_rotvec(rr))
        jv = joint_values(machine, design.poses[i])
        md = list(design.dirs[i]) + [design.pay[i], design.sess[i], design.temp[i], design.t[i]]
        name = f"P{i + 1}"
        key = "val" if design.is_val[i] else "id"
        rows[key].append({"pose": name, "vals": jv + vals_noisy + md})
        rows["nf_" + key].append({"pose": name, "vals": jv + vals_clean + md})
    os.makedirs(out_dir, exist_ok=True)
    hn = (a, b)
    write_csv(os.path.join(out_dir, "data.csv"), machine, hn, rows["id"], None)
    write_csv(os.path.join(out_dir, "val.csv"), machine, hn, rows["val"], None)
    write_csv(os.path.join(out_dir, "nf.csv"), machine, hn, rows["nf_id"], None)
    write_csv(os.path.join(out_dir, "nf.val.csv"), machine, hn, rows["nf_val"], None)
    info = {"family": family, "case": case, "kind": kind, "effect": effect, "parameters": prm, "seed": seed,
            "serial": machine.serial, "model": os.path.abspath(machine.path), "has_masses": machine.has_masses,
            "targets": list(cfg["targets"]), "six_d": cfg["six_d"], "noise_factor": factor,
            "visibility": vis, "max_closure_residual": closure, "geometry": design.geometry}
    with open(os.path.join(out_dir, "truth.json"), "w") as f:
        json.dump(info, f, indent=1, default=float)
    return info


def campaign_list(seeds, limit=None, only=None):
    out = []
    for seed in seeds:
        for c in CASES:
            if only and f"{c[0]}/{c[1]}" not in only and c[0] not in only:
                continue
            out.append((seed,) + c)
    if limit:
        out = out[:limit]
    return out


def generate_all(hyperstat, out, seeds, limit=None, only=None, repo_root=None):
    repo_root = repo_root or os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "..", ".."))
    paths = robots.prepare_models(hyperstat, repo_root, os.path.join(out, "models"))
    machines = {f: Machine(f, p) for f, p in paths.items()}
    designs = {}
    done = []
    for seed, fam, case, kind, effect, prm in campaign_list(seeds, limit, only):
        if (fam, seed) not in designs:
            designs[(fam, seed)] = Design(machines[fam], seed)
        d = os.path.join(out, "campaigns", f"{fam}__{case}__s{seed}")
        info = generate_campaign(machines[fam], designs[(fam, seed)], fam, case, kind, effect, prm, seed, d)
        done.append((d, info))
    return done


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--hyperstat", default=".venv/bin/hyperstat")
    ap.add_argument("--out", default="out/blind4")
    ap.add_argument("--seeds", default="0", help="comma-separated seeds (default 0)")
    ap.add_argument("--limit", type=int, default=None, help="only the first N campaigns")
    ap.add_argument("--only", default=None, help="comma-separated families or family/case")
    a = ap.parse_args(argv)
    seeds = [int(s) for s in a.seeds.split(",")]
    only = set(a.only.split(",")) if a.only else None
    for d, info in generate_all(a.hyperstat, a.out, seeds, a.limit, only):
        v = info["visibility"]
        print(d, info["kind"], info["effect"], f"closure {info['max_closure_residual']:.1e}",
              "visibility -" if v is None else f"visibility {v:.2f}")


if __name__ == "__main__":
    main()
