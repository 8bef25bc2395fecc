"""The four machine families of the fifth blind generator: how each real machine moves.

A family knows its nominal kinematics (own code: ``serial.py`` for the arms, ``pkm.py`` for the
parallel machines read from the model file ``hyperstat build`` writes), draws a *real* machine
(geometric errors, true masses, a tracker placement), designs the poses a calibration engineer
would measure, and computes where each target really is for commanded joint values, with the
hooks the effects (``effects.py``) act through:

* ``joint_error``: actuated joint values the machine really has (gear errors, compliance, ...);
* ``link_post``: deformations of the links (a serial arm's bending link, a PKM's bowed guide; a
  PKM then closes its loops with the least elastic energy);
* ``world``: displacements of the whole measured structure in the base frame (base tilt,
  thermal growth, spindle growth, ...);
* ``offsets``: where the targets sit on the output frame (a loose reflector nest, ...);
* ``tracker``: what the tracker makes of a point (a moved station, a bent beam, ...).

Units: mm, rad, N, N mm, kg, degC, s.
"""

from __future__ import annotations

import json
import os
import subprocess

import numpy as np

from . import geom, pkm, serial

G = 9.81


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def random_rotation_small(rng, sigma):
    return geom.rotvec_to_matrix(rng.uniform(-sigma, sigma, 3))


class Family:
    """Common part: tracker, noise, metadata, measurement order."""

    name = ""
    kind = ""            # serial / parallel
    n_id = 80
    n_val = 30
    six_d = False
    payloads = (0.0,)
    noise_a = 0.01       # mm
    noise_b = 0.004      # mm/m
    orient_noise = None  # rad, 6-D only
    radial_ratio = 0.8   # the tracker's distance meter is better than its angle encoders
    length_unit = "mm"
    loss_rate = 0.02     # a target lost at random (beam broken)

    # ------------------------------------------------------------------ metadata
    def metadata(self, rng, n, profile):
        """Measurement order, time, temperature, payload, session, for n poses.

        profile: 'stable' (a metrology hall: +-0.05 degC sensor wander) or 'swing' (a shop floor:
        the structure's temperature swings several degrees, not in step with the poses)."""
        order = rng.permutation(n)
        t = np.zeros(n)
        k_break = n // 2
        clock = 0.0
        for k, i in enumerate(order):
            if k == k_break:
                clock += 1800.0 + rng.uniform(0, 600)         # lunch: the second session
            clock += rng.uniform(55.0, 95.0)
            t[i] = clock
        session = np.where(np.argsort(np.argsort(t)) < k_break, 1, 2)
        if profile == "swing":
            phase = rng.uniform(0, 2 * np.pi)
            period = rng.uniform(4200.0, 6000.0)
            amp = self.swing_amplitude * rng.uniform(0.85, 1.0)
            temp = 20.5 + amp * np.sin(2 * np.pi * t / period + phase) + 0.6 * amp * (t / t.max() - 0.5)
        else:
            temp = 20.4 + 0.03 * np.sin(2 * np.pi * t / 2500.0 + rng.uniform(0, 6.3))
        temp = temp + rng.normal(0, 0.02, n)
        payload = rng.choice(self.payloads, n)
        return {"order": order, "time": t, "temperature": temp, "payload": payload, "session": session}

    swing_amplitude = 3.0

    def mech_name(self):
        return self.name

    @staticmethod
    def directions(q_all, order):
        """Direction of each joint's last motion (+1 / -1) in the measurement order."""
        n, na = q_all.shape
        d = np.ones((n, na), dtype=int)
        prev = None
        for i in order:
            if prev is not None:
                step = q_all[i] - q_all[prev]
                d[i] = np.where(step >= 0, 1, -1)
            prev = i
        return d

    # ------------------------------------------------------------------ tracker
    def draw_tracker(self, rng):
        base = np.asarray(self.tracker_nominal, dtype=float)
        t = base + rng.uniform(-150, 150, 3) * np.array([1, 1, 0.3])
        yaw = rng.uniform(-np.pi, np.pi)
        r = geom.rot_z(yaw)[:3, :3] @ random_rotation_small(rng, 2e-3)   # a levelled tracker
        return geom.hom(r, t)

    def noise_sigma(self, d_mm):
        return self.noise_a + self.noise_b * d_mm / 1000.0

    def add_noise(self, rng, p_tr, factor):
        """Anisotropic tracker noise: full sigma across the line of sight, radial_ratio along it."""
        d = np.linalg.norm(p_tr)
        s = self.noise_sigma(d) * factor
        u = p_tr / d
        g = rng.normal(0.0, s, 3)
        return p_tr + g - (1.0 - self.radial_ratio) * np.dot(g, u) * u

    # ------------------------------------------------------------------ helpers for effects


# ============================================================================ serial arms
class SerialFamily(Family):
    kind = "serial"

    def __init__(self, arm):
        self.arm = arm
        self.actuated = list(arm.joints)
        self.model_path = None

    # ------------------------------------------------------------------ machine
    def draw_machine(self, rng, rot=3e-4, offs=5e-4, lin=0.3):
        arm = self.arm
        F = []
        for i, fi in enumerate(arm.F):
            rv = rng.uniform(-rot, rot, 3)
            rv[2] = rng.uniform(-offs, offs)                  # zero offset (mastering)
            F.append(fi @ geom.small_transform(rv, rng.uniform(-lin, lin, 3)))
        F_tool = arm.F_tool @ geom.small_transform(rng.uniform(-rot, rot, 3), rng.uniform(-lin, lin, 3))
        masses = [(m * rng.uniform(0.95, 1.05), c + rng.uniform(-10, 10, 3)) for m, c in arm.masses]
        return {"F": F, "F_tool": F_tool, "masses": masses, "tracker": self.draw_tracker(rng)}

    def output_pose(self, machine, q, post=None, key=None):
        return self.arm.frames(q, F=machine["F"], F_tool=machine["F_tool"], link_post=post)[1]

    def gravity(self, machine, q, payload, key=None):
        return self.arm.gravity_torques(q, machine["masses"], payload, machine["F"], machine["F_tool"])

    def base_moment(self, machine, q, payload, key=None):
        return self.arm.base_moment(q, machine["masses"], payload, machine["F"], machine["F_tool"])

    def joint_frames(self, machine, q):
        return self.arm.frames(q, F=machine["F"], F_tool=machine["F_tool"])[0]

    # ------------------------------------------------------------------ pose design
    def wrist_solve(self, q, n_free, goal_r, rng):
        """Turn the last joints so that the tool frame takes the orientation goal_r (Newton on
        the rotation error, numerical Jacobian, a few starts).  Returns q or None."""
        arm = self.arm
        idx = list(range(len(q) - n_free, len(q)))
        for attempt in range(6):
            qq = q.copy()
            for i in idx:
                lo, hi = arm.windows[i]
                qq[i] = rng.uniform(lo, hi)
            for _ in range(30):
                t = arm.tool(qq)
                e = geom.matrix_to_rotvec(goal_r @ t[:3, :3].T)
                if np.linalg.norm(e) < 1e-10:
                    break
                jac = np.zeros((3, n_free))
                for k, i in enumerate(idx):
                    d = qq.copy()
                    d[i] += 1e-6
                    jac[:, k] = geom.matrix_to_rotvec(arm.tool(d)[:3, :3] @ t[:3, :3].T) / 1e-6
                step = np.linalg.lstsq(jac, e, rcond=1e-8)[0]
                step = np.clip(step, -0.5, 0.5)
                qq[idx] += step
            if np.linalg.norm(e) < 1e-8:
                qq[idx] = (qq[idx] + np.pi) % (2 * np.pi) - np.pi
                ok = all(arm.windows[i][0] <= qq[i] <= arm.windows[i][1] for i in idx)
                if ok:
                    return qq
        return None

    def design(self, rng, n, tracker):
        """n poses: the arm joints spread over their windows, the flange turned toward the
        tracker within a cone, a random roll; every pose keeps at least two targets in view."""
        arm = self.arm
        out = []
        t_pos = tracker[:3, 3]
        while len(out) < n:
            q = np.array([rng.uniform(lo, hi) for lo, hi in arm.windows])
            t = arm.tool(q)
            p = t[:3, 3]
            if p[2] < self.floor_z or np.hypot(p[0], p[1]) < self.min_radius:
                continue
            look = unit(t_pos - p)
            # a random direction within the cone about the line of sight
            ax = unit(np.cross(look, rng.normal(size=3)))
            tilt = rng.uniform(0, self.cone)
            z = geom.rotvec_to_matrix(ax * tilt) @ look
            x0 = unit(np.cross(z, rng.normal(size=3)))
            r = np.column_stack([x0, np.cross(z, x0), z]) @ geom.rot_z(rng.uniform(-np.pi, np.pi))[:3, :3]
            q2 = self.wrist_solve(q, self.n_wrist, r, rng)
            if q2 is None:
                continue
            p2 = arm.tool(q2)[:3, 3]
            if p2[2] < self.floor_z:
                continue
            vis = self.visible(arm.tool(q2), t_pos)
            if sum(vis) < min(2, len(vis)):
                continue
            out.append(q2)
        return np.array(out)

    def visible(self, t_out, t_pos):
        vis = []
        for name, (off, normal, _) in self.targets.items():
            p = t_out[:3, :3] @ off + t_out[:3, 3]
            n = t_out[:3, :3] @ normal
            vis.append(np.degrees(np.arccos(np.clip(np.dot(unit(t_pos - p), n), -1, 1))) < self.acceptance)
        return vis

    # ------------------------------------------------------------------ files
    def controller_columns(self):
        return [f"{c}[deg]" for c in self.arm.controller]

    def controller_values(self, q):
        return self.arm.to_controller(q)


class KRFamily(SerialFamily):
    name = "kr_like"
    n_id = 80
    n_val = 30
    payloads = (0.0, 60.0, 120.0)
    noise_a = 0.010
    noise_b = 0.004
    length_unit = "m"
    tracker_nominal = (4300.0, -700.0, 600.0)
    floor_z = 250.0
    min_radius = 900.0
    cone = np.radians(35.0)
    acceptance = 55.0        # SMR acceptance half-angle (deg)
    n_wrist = 3
    swing_amplitude = 3.0

    def __init__(self):
        super().__init__(serial.kr_like())
        # three SMRs on a fixture at the flange: offset (mm) and nest normal in the tool frame
        self.targets = {
            "SMR1": (np.array([95.0, 0.0, 35.0]), unit([0.35, 0.0, 1.0]), None),
            "SMR2": (np.array([-48.0, 84.0, 35.0]), unit([-0.17, 0.3, 1.0]), None),
            "SMR3": (np.array([-48.0, -84.0, 70.0]), unit([-0.17, -0.3, 1.0]), None),
        }

    def prepare(self, workdir, hyperstat):
        path = os.path.join(workdir, "kr_like.skel.json")
        if os.path.exists(path):
            self.model_path = path
            return path
        dh = os.path.join(workdir, "kr_like.dh.yaml")
        with open(dh, "w") as fh:
            fh.write(serial.kr_dh_yaml())
        tmp = os.path.join(workdir, "kr_like.imported.json")
        subprocess.run([hyperstat, "import-robot", dh, "--out", tmp, "--quiet"], check=True)
        with open(tmp) as fh:
            model = json.load(fh)
        # the declared link masses: per joint, the body it moves, com in the base frame at home
        home = np.array([e.get("home", 0.0) for e in model["chains"][0]["elements"] if e["kind"] == "joint"])
        coms = self.arm.com_world(home)
        model["metadata"]["masses"] = {
            j: {"mass": float(m), "com": [float(x) for x in c], "source": "blind3: the arm's data sheet (declared)"}
            for j, (m, _), c in zip(self.arm.joints, self.arm.masses, coms)}
        with open(path + ".part", "w") as fh:
            json.dump(model, fh, indent=1)
        os.replace(path + ".part", path)
        self.model_path = path
        return path


class LBRFamily(SerialFamily):
    name = "lbr_like"
    n_id = 80
    n_val = 30
    six_d = True
    payloads = (0.0, 5.0, 12.0)
    noise_a = 0.008
    noise_b = 0.004
    orient_noise = 6e-5
    length_unit = "mm"
    tracker_nominal = (2600.0, 900.0, 500.0)
    floor_z = 150.0
    min_radius = 300.0
    cone = np.radians(40.0)
    acceptance = 60.0        # 6-D probe
    n_wrist = 3
    swing_amplitude = 3.0

    def __init__(self):
        super().__init__(serial.lbr_like())
        r_off = geom.rotvec_to_matrix([0.05, -0.08, 0.6])
        self.targets = {"TMAC": (np.array([0.0, 0.0, 62.0]), np.array([0.0, 0.0, 1.0]), r_off)}

    def prepare(self, workdir, hyperstat):
        path = os.path.join(workdir, "lbr_like.skel.json")
        if os.path.exists(path):
            self.model_path = path
            return path
        urdf = os.path.join(workdir, "lbr_like.urdf")
        with open(urdf, "w") as fh:
            fh.write(serial.lbr_urdf())
        subprocess.run([hyperstat, "import-robot", urdf, "--out", path, "--quiet"], check=True)
        self.model_path = path
        return path

    def controller_columns(self):
        return [f"q{j}[deg]" for j in self.arm.joints]


# ============================================================================ parallel machines
class ParallelFamily(Family):
    kind = "parallel"
    template = ""
    loss_rate = 0.02

    def __init__(self):
        self.mech = None
        self.model_path = None

    def prepare(self, workdir, hyperstat, repo="."):
        path = os.path.join(workdir, f"{self.name}.skel.json")
        if not os.path.exists(path):
            tmp = os.path.join(workdir, f"{self.name}.built.json")
            subprocess.run([hyperstat, "build", os.path.join(repo, "templates", f"{self.template}.py"),
                            "--model", tmp, "--quiet"], check=True)
            with open(tmp) as fh:
                model = json.load(fh)
            model["metadata"]["moving_mass"] = self.moving_mass
            model["metadata"]["com"] = list(self.com)
            model["metadata"]["screw_lead"] = self.screw_lead
            with open(path + ".part", "w") as fh:
                json.dump(model, fh, indent=1)
            os.replace(path + ".part", path)
        self.model_path = path
        self.mech = pkm.Mechanism(path)
        self.actuated = list(self.mech.actuated)
        return path

    # ------------------------------------------------------------------ machine
    def draw_machine(self, rng, rot=2e-4, lin=0.05):
        m = self.mech
        if not hasattr(self, "_basis"):
            cfgs = self.sample_configs(np.random.default_rng(12345), 16)
            self._pvars, self._basis = m.admissible_basis(cfgs)
        raw = np.array([rng.uniform(-rot, rot) if v[2] < 3 else rng.uniform(-lin, lin) for v in self._pvars])
        scale = np.array([1000.0 if v[2] < 3 else 1.0 for v in self._pvars])
        b = self._basis * scale[:, None]
        coef = np.linalg.lstsq(b, raw * scale, rcond=None)[0]
        x = self._basis @ coef                       # projection on the admissible subspace
        pert = {}
        for v, val in zip(self._pvars, x):
            pert.setdefault(v[1], np.zeros(6))[v[2]] = val
        pert = {k: geom.small_transform(v[:3], v[3:]) for k, v in pert.items()}
        return {"pert": pert, "mass": self.moving_mass * rng.uniform(0.95, 1.05),
                "com": np.asarray(self.com) + rng.uniform(-10, 10, 3), "tracker": self.draw_tracker(rng),
                "cache": {}}

    def sample_configs(self, rng, n):
        m = self.mech
        out = []
        while len(out) < n:
            q = self.random_pose(rng)
            if q is not None:
                out.append(q)
        return out

    def full_q(self, qa):
        q = dict(self.mech.home)
        for j, v in zip(self.actuated, qa):
            q[j] = float(v)
        return q

    def closed(self, machine, qa, post=None, elastic=None, key=None):
        """Close the loops of the real machine at actuated values qa (continuation from the
        nominal solution of the same pose)."""
        m = self.mech
        q0 = self.full_q(qa)
        start = machine["cache"].get(("nominal", key)) if key is not None else None
        if start is None:
            start, _, res0, _ = m.solve(q0)
            if key is not None:
                machine["cache"][("nominal", key)] = start
        q = dict(start)
        for j, v in zip(self.actuated, qa):
            q[j] = float(v)
        q, e, res, st = m.solve(q, pert=machine["pert"], post=post, elastic=elastic if post else None)
        return q, st, res

    def output_pose(self, machine, qa, post=None, key=None):
        q, st, res = self.closed(machine, qa, post=post, elastic=self.elastic if post else None, key=key)
        return st["frames"][self.mech.output]

    def gravity(self, machine, qa, payload, key=None):
        """Generalized gravity force on each actuated joint (N for a leg, N mm for a revolute):
        tau = m g . d(com)/dq_a with the passive joints following."""
        q, st, res = self.closed(machine, qa, key=key)
        m = self.mech
        dqp, av, pv = m.passive_sensitivity(st)
        t = st["frames"][m.output]
        g = np.array([0.0, 0.0, -G])
        tau = np.zeros(len(av))
        for mass, c_local in ((machine["mass"], machine["com"]), (payload, np.zeros(3))):
            if mass == 0:
                continue
            c = t[:3, :3] @ c_local + t[:3, 3]
            dc = m.point_motion(st, m.output, c, dqp, av, pv)
            tau += mass * (g @ dc)
        return tau

    def base_moment(self, machine, qa, payload, key=None):
        t = self.output_pose(machine, qa, key=key)
        g = np.array([0.0, 0.0, -G])
        c = t[:3, :3] @ machine["com"] + t[:3, 3]
        return np.cross(c, machine["mass"] * g) + np.cross(t[:3, 3], payload * g)

    def controller_columns(self):
        out = []
        for j in self.actuated:
            el = self.mech.elements[j]
            out.append(f"q{j}[mm]" if el.type == "P" else f"q{j}[deg]")
        return out

    def controller_values(self, qa):
        out = []
        for j, v in zip(self.actuated, qa):
            out.append(v if self.mech.elements[j].type == "P" else np.degrees(v))
        return out

    def design(self, rng, n, tracker):
        out = []
        while len(out) < n:
            q = self.random_pose(rng)
            if q is not None:
                out.append(np.array([q[j] for j in self.actuated]))
        return np.array(out)

    elastic = None


class TripteorFamily(ParallelFamily):
    name = "tripteor_x7"
    template = "tripteor_x7"
    n_id = 107
    n_val = 30
    payloads = (0.0, 50.0, 100.0)       # test masses hung at the spindle
    noise_a = 0.005
    noise_b = 0.005
    length_unit = "mm"
    tracker_nominal = (1300.0, -900.0, -700.0)
    moving_mass = 180.0                 # platform, wrist and spindle head (kg)
    com = (0.0, 0.0, 250.0)             # in the tool frame: up the spindle
    screw_lead = 20.0
    swing_amplitude = 4.0

    def __init__(self):
        super().__init__()
        self.targets = {
            # a calibration bar in the tool holder: two nests 180 mm either side of the spindle axis
            "SMR1": (np.array([180.0, 10.0, 40.0]), None, None),
            "SMR2": (np.array([-175.0, -12.0, 45.0]), None, None),
        }
        # every element of the legs can flex a little: rotational rad/(N mm), translational mm/N
        self.elastic = None

    def prepare(self, workdir, hyperstat, repo="."):
        path = super().prepare(workdir, hyperstat, repo)
        names = []
        for ch in self.mech.chains:
            if ch.name.startswith("leg"):
                names += [e.name for e in ch.elements if e.kind in ("joint", "fixed")]
        self.elastic = {n: np.array([2e-9, 2e-9, 2e-9, 2e-5, 2e-5, 2e-5]) for n in names}
        self.home_mps = self.mech.evaluate(self.mech.home)["frames"]["MPS"][:3, 3].copy()
        return path

    def random_pose(self, rng):
        """Inverse kinematics: a platform position in the working box, then the leg and passive
        joints that put the platform there; the wrist angles drawn over their windows."""
        m = self.mech
        goal = self.home_mps + np.array([rng.uniform(-230, 230), rng.uniform(-230, 230), rng.uniform(-110, 110)])
        free = [j for j in m.joints if j not in ("6", "7")]
        q, _, res, st = m.solve(dict(m.home), free=free, goal=("MPS", geom.hom(t=goal), np.array([False] * 3 + [True] * 3)))
        if res > 1e-8:
            return None
        q["6"] = rng.uniform(-3.0, 3.0)
        q["7"] = rng.uniform(-0.95, 0.95)
        if not m.in_range(q, margin=0.0):
            return None
        for j in ("41", "42", "43"):
            lo, hi = m.elements[j].range
            if not (lo + 8 <= q[j] <= hi - 8):
                return None
        st = m.evaluate(q)
        if m.passive_conditioning(st) < 1e-4:
            return None
        return q


class HexapodFamily(ParallelFamily):
    name = "hexapod"
    template = "hexapod"
    n_id = 56
    n_val = 20
    six_d = True
    payloads = (0.0, 100.0, 200.0)
    noise_a = 0.005
    noise_b = 0.004
    orient_noise = 4e-5
    length_unit = "mm"
    tracker_nominal = (1100.0, 600.0, 1100.0)
    moving_mass = 120.0               # platform and a side-mounted spindle (kg)
    com = (140.0, 30.0, 110.0)        # in the platform frame
    screw_lead = 5.0
    swing_amplitude = 4.0

    def __init__(self):
        super().__init__()
        r_off = geom.rotvec_to_matrix([0.3, -0.2, 0.9])
        self.targets = {"PROBE": (np.array([60.0, -40.0, 85.0]), None, r_off)}

    def prepare(self, workdir, hyperstat, repo="."):
        path = super().prepare(workdir, hyperstat, repo)
        self.home_p = self.mech.evaluate(self.mech.home)["frames"][self.mech.output].copy()
        return path

    def random_pose(self, rng):
        m = self.mech
        t = self.home_p.copy()
        t[:3, 3] += np.array([rng.uniform(-60, 60), rng.uniform(-60, 60), rng.uniform(-40, 40)])
        t[:3, :3] = geom.rotvec_to_matrix([rng.uniform(-0.07, 0.07), rng.uniform(-0.07, 0.07),
                                           rng.uniform(-0.12, 0.12)]) @ t[:3, :3]
        q, _, res, st = m.solve(dict(m.home), free=list(m.joints), goal=(m.output, t, np.array([True] * 6)))
        if res > 1e-8 or not m.in_range(q):
            return None
        for j in self.actuated:
            lo, hi = m.elements[j].range
            if not (lo + 4 <= q[j] <= hi - 4):
                return None
        return q


FAMILIES = {"kr_like": KRFamily, "lbr_like": LBRFamily, "tripteor_x7": TripteorFamily, "hexapod": HexapodFamily}
