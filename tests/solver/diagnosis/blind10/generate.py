"""Campaign generator of the twelfth blind set (directory ``blind10``) for ``hyperstat diagnose``.

Units: mm, rad, degC, s, kg inside; the files state theirs per column.  Source-blind: written from
``docs/identification.md`` (the measurement file), ``docs/model-format.md`` (masses) and
``docs/diagnosis.md`` (effects); the model files are read by ``blind7/kin.py`` / ``blind8/machine.py``
(earlier source-blind generator code, imported, checked by ``selfcheck.py``).  Nothing here imports
hyperstat.

    python -m tests.solver.diagnosis.blind10.generate OUTDIR [--seed 0] [--cases a,b] [--no-visibility]
"""
from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import tempfile

import numpy as np
from scipy.spatial.transform import Rotation

from tests.solver.diagnosis.blind7.kin import R_to_rotvec, rotvec_to_R
from tests.solver.diagnosis.blind8.machine import Machine, write_variant
from tests.solver.diagnosis.blind10 import effects as E
from tests.solver.diagnosis.blind10.cases import CASES

HERE = os.path.dirname(os.path.abspath(__file__))
MODELS = os.path.join(HERE, "models")
MAG_FILE = os.path.join(HERE, "magnitudes.json")

# ---------------------------------------------------------------- families ---------------------------
FAMILIES = {
    "tx7": dict(base="tx7", parallel=True, share=0.8, noise=(0.005, 0.004), dist=(1.6, 2.4), dz=1000.0,
                pos_unit="mm", cols={"41": "mm", "42": "mm", "43": "mm", "6": "deg", "7": "deg"},
                payloads=(0.0, 10.0, 4.0, 10.0), moving_mass=40.0, geometry=False),
    "hexa": dict(base="hexa", parallel=True, share=0.8, noise=(0.004, 0.003), dist=(1.5, 2.2), dz=1000.0,
                 pos_unit="mm", cols={j: "m" for j in ("31", "32", "33", "34", "35", "36")},
                 payloads=(0.0, 12.0, 6.0, 12.0), moving_mass=25.0, geometry=True),
    "stan": dict(base="stan6", parallel=False, share=0.85, noise=(0.010, 0.005), dist=(1.8, 2.6),
                 dz=1000.0, pos_unit="mm",
                 cols={"1": "deg", "2": "deg", "3": "mm", "4": "rad", "5": "rad", "6": "rad"},
                 payloads=(0.0, 3.0, 1.5, 3.0), geometry=True,
                 masses={"1": 20.0, "2": 14.0, "3": 8.0, "4": 3.0, "5": 2.0, "6": 0.8}),
    "ceil": dict(base="ceil5", parallel=False, share=0.85, noise=(0.007, 0.006), dist=(1.6, 2.3),
                 dz=-1200.0, pos_unit="m", cols={j: "deg" for j in "12345"},
                 payloads=(0.0, 4.0, 2.0, 4.0), geometry=True,
                 masses={"1": 18.0, "2": 12.0, "3": 7.0, "4": 3.0, "5": 1.0}),
}

# target layouts: name -> (list of (target name or None, offset mm), six_d)
TARGETS = {
    "tee4": ([("A", (0.0, 0.0, 40.0)), ("B", (120.0, 0.0, 40.0)), ("C", (240.0, 0.0, 40.0)),
              ("D", (120.0, 90.0, 40.0))], False),
    "q6tool": ([(None, (-60.0, 40.0, 180.0))], True),
    "tri3w": ([("R1", (260.0, 150.0, 30.0)), ("R2", (-260.0, 150.0, 30.0)), ("R3", (0.0, -300.0, 30.0))],
              False),
    "q6top": ([(None, (30.0, -70.0, 110.0))], True),
    "duo": ([("F", (45.0, 0.0, 30.0)), ("K", (-45.0, 20.0, 90.0))], False),
    "one": ([(None, (0.0, 40.0, 50.0))], False),
    "tri3": ([("P1", (70.0, 0.0, 25.0)), ("P2", (-35.0, 60.0, 25.0)), ("P3", (-35.0, -60.0, 60.0))], False),
}
ROT_OFFSET = (0.03, -0.05, 0.02)  # rad, the 6-D target's true rotation offset
ORIENT_NOISE = 2e-5  # rad (0.02 mrad) 1 sigma per axis, stated
SESSION_START = (0.0, 9 * 3600.0, 52 * 3600.0)  # s: three shifts, the third two days later
POSE_TIME = 60.0  # s per pose


def temperature(t, ts):
    """Hall temperature (degC): a day cycle, the HVAC's 30-min sawtooth, the machine's warm-up."""
    x = t / 1800.0
    saw = 2.0 * (x - math.floor(x + 0.5))
    return 20.3 + 3.5 * math.sin(2 * math.pi * t / 86400.0 - 1.9) + 0.7 * saw + 1.2 * (1 - math.exp(-ts / 2400.0))


# ---------------------------------------------------------------- models -----------------------------
def model_path(outdir, variant):
    return os.path.join(outdir, "models", variant + ".skel.json")


def serial_masses(fam):
    """Declared masses: each body's centre of mass at home midway between its joint's origin and the
    next joint's (the output's for the last), base frame, mm."""
    m = Machine(os.path.join(MODELS, FAMILIES[fam]["base"] + ".skel.json"))
    home = {n: m.home[n] for n in m.actuated}
    T, jf = m.serial_frames(home)
    names = list(m.actuated)
    out = {}
    for i, j in enumerate(names):
        a = jf[j][:3, 3]
        b = jf[names[i + 1]][:3, 3] if i + 1 < len(names) else T[:3, 3]
        out[j] = {"mass": FAMILIES[fam]["masses"][j], "com": [float(v) for v in (a + b) / 2]}
    return out


def make_models(outdir):
    os.makedirs(os.path.join(outdir, "models"), exist_ok=True)
    for fam, F in FAMILIES.items():
        src = os.path.join(MODELS, F["base"] + ".skel.json")
        write_variant(src, model_path(outdir, fam))
        if F["parallel"]:
            write_variant(src, model_path(outdir, fam + "_m"), moving_mass=F["moving_mass"])
        else:
            write_variant(src, model_path(outdir, fam + "_m"), masses=serial_masses(fam))


_MACH = {}


def machine(fam, massed=False):
    key = (fam, massed)
    if key not in _MACH:
        F = FAMILIES[fam]
        path = os.path.join(MODELS, F["base"] + ".skel.json")
        if massed and not F["parallel"]:
            tmp = os.path.join(tempfile.gettempdir(), f"blind10_{fam}_m_{os.getpid()}.json")
            write_variant(path, tmp, masses=serial_masses(fam))
            _MACH[key] = Machine(tmp)
            os.remove(tmp)
        else:
            _MACH[key] = Machine(path, moving_mass=F.get("moving_mass") if massed else None)
    return _MACH[key]


# ---------------------------------------------------------------- poses ------------------------------
def _seed(*parts):
    return int(hashlib.sha256("/".join(map(str, parts)).encode()).hexdigest()[:8], 16)


def design_u(design, n, dim, rng):
    """Normalised actuator coordinates u in [-1, 1]^dim, in measuring order."""
    if design == "walk":  # a random walk: 2 joints moved per pose by 0.3-0.7, reflected at the bounds
        u = np.zeros((n, dim))
        cur = rng.uniform(-0.5, 0.5, dim)
        for i in range(n):
            for j in rng.choice(dim, size=min(2, dim), replace=False):
                v = cur[j] + rng.choice([-1, 1]) * rng.uniform(0.3, 0.7)
                if v > 1:
                    v = 2 - v
                if v < -1:
                    v = -2 - v
                cur[j] = v
            u[i] = cur
        return u
    if design == "arcsine":  # arcsine-distributed: most poses near the ends of the strokes
        return np.sin(np.pi * (rng.uniform(0, 1, (n, dim)) - 0.5))
    if design == "clusters":  # seven regions revisited in turn, +-0.12 around their centres
        cen = rng.uniform(-0.8, 0.8, (7, dim))
        return np.clip(cen[np.arange(n) % 7] + rng.uniform(-0.12, 0.12, (n, dim)), -1, 1)
    raise KeyError(design)


_POSES = {}
_JAC = {}  # nominal output derivatives per shared pose


def poses(fam, design, n, seed):
    """Actuated values (list of dicts, mm/rad) and closed passive values (parallel) in measuring order."""
    key = (fam, design, n, seed)
    if key in _POSES:
        return _POSES[key]
    F = FAMILIES[fam]
    m = machine(fam)
    rng = np.random.default_rng(_seed("poses", fam, design, n, seed))
    U = design_u(design, n, len(m.actuated), rng)
    out = []
    for u in U:
        for _ in range(12):
            qa = {}
            for k, j in enumerate(m.actuated):
                lo, hi = m.ranges[j]
                qa[j] = (lo + hi) / 2 + F["share"] * (hi - lo) / 2 * u[k]
            if not m.parallel:
                out.append((qa, None))
                break
            q, r = m.kin.solve_path(qa)
            if r < 1e-8 and m.kin.passive_inside(q, 0.02):
                out.append((qa, q))
                break
            u = 0.8 * u
        else:
            raise RuntimeError(f"{fam}: no closed pose near u={u}")
    _POSES[key] = out
    return out


# ---------------------------------------------------------------- campaign ---------------------------
def scaled(params, f):
    """Parameters with every amplitude multiplied by f (orders, leads, positions, names kept)."""
    keep = {"k", "order", "lead", "joint", "x0", "w", "tau", "L0", "b", "from_session", "cx", "cy", "R"}

    def sc(v, key=None):
        if key in keep or isinstance(v, str):
            return v
        if isinstance(v, dict):
            return {k: sc(x, k) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [sc(x) for x in v]
        return v * f

    return sc(params)


def magnitudes():
    if os.path.exists(MAG_FILE):
        with open(MAG_FILE) as f:
            return json.load(f)
    return {}


def case_params(case, factor=None):
    if case.get("params") is None:
        return None
    f = magnitudes().get(case["name"], 1.0) if factor is None else factor
    return scaled(case["params"], f)


class Campaign:
    """One campaign's virtual measurements (noise-free with and without the effect, and noisy)."""

    def __init__(self, case, seed=0, factor=None):
        self.case = case
        self.fam = case["family"]
        F = self.F = FAMILIES[self.fam]
        self.m = machine(self.fam)
        self.mg = machine(self.fam, massed=True)  # the true masses, whatever the file declares
        rng = self.rng = np.random.default_rng(_seed("campaign", case["name"], seed))
        self.params = case_params(case, factor)
        self.effect = case.get("effect")
        n = case["n"]
        self.poses = poses(self.fam, case["design"], n, seed)
        self.val = np.array([i % 4 == 3 for i in range(n)])
        # true geometry
        self.defects = {}
        if F["geometry"]:
            for (e, comp) in self.m.kin.defect_list:
                self.defects[(e, comp)] = rng.normal(0, 2e-4 if comp in "IJKG" else 0.15)
        self.targets, self.six_d = TARGETS[case["targets"]]
        self.toff = [np.asarray(o, float) + rng.uniform(-2, 2, 3) for _, o in self.targets]
        self.tprior = [o + rng.uniform(-1.5, 1.5, 3) for o in self.toff]
        # metadata
        sizes = [n // 3 + (1 if k < n % 3 else 0) for k in range(3)]
        self.session = np.repeat([1, 2, 3], sizes)
        ts = np.concatenate([np.arange(s) * POSE_TIME for s in sizes])
        self.ts = ts
        self.t = np.array([SESSION_START[s - 1] for s in self.session]) + ts
        self.T = np.array([temperature(a, b) for a, b in zip(self.t, self.ts)]) + rng.normal(0, 0.03, n)
        pl = F["payloads"]
        self.payload = np.array([pl[(i // 8) % len(pl)] for i in range(n)])
        self.dirs = []
        prev = {j: self.m.home[j] for j in self.m.actuated}
        last = {j: 1.0 for j in self.m.actuated}
        for qa, _ in self.poses:
            d = {}
            for j in self.m.actuated:
                dv = qa[j] - prev[j]
                d[j] = float(np.sign(dv)) if abs(dv) > 1e-12 else last[j]
            self.dirs.append(d)
            last, prev = d, qa
        # tracker
        P0 = np.mean([self._rigid_pose(i)[0][:3, 3] for i in range(min(12, n))], axis=0)
        az = rng.uniform(0, 2 * np.pi)
        d = rng.uniform(*F["dist"]) * 1000.0
        self.to = P0 + np.array([d * math.cos(az), d * math.sin(az), F["dz"] + rng.uniform(-200, 200)])
        self.tR = rotvec_to_R([0, 0, rng.uniform(-np.pi, np.pi)]) @ rotvec_to_R(
            [rng.normal(0, 0.01), rng.normal(0, 0.01), 0.0])
        self.header_o = self.to + rng.normal(0, 1.0, 3)
        self.header_r = R_to_rotvec(self.tR) + rng.normal(0, 1e-3, 3)
        self.noise_factor = case.get("noise_factor", 1.0)
        self._rigid = {}

    # -- one pose -----------------------------------------------------------------------------------
    def _rigid_pose(self, i, qa=None, post=None):
        qa0, qfull = self.poses[i]
        qa = qa0 if qa is None else qa
        if not self.m.parallel:
            T, _ = self.m.serial_frames(qa, post, self.defects)
            return T, None
        init = None if qfull is None else np.array([qfull[n] for n in self.m.kin.passive])
        q, r = self.m.kin.solve(qa, self.defects or None, init=init)
        if r > 1e-6:
            q, r = self.m.kin.solve_path(qa, self.defects or None)
        if r > 1e-6:
            raise RuntimeError(f"{self.case['name']}: pose {i} does not close ({r:.2e})")
        return self.m.kin.output_pose(q, self.defects or None), q

    def ctx(self, i):
        qa, qfull = self.poses[i]
        m = self.m
        if m.parallel:
            tau, M = self.mg.gravity(qa, qfull, payload=self.payload[i])
            F, _, jf = m.kin.frames(qfull)
        else:
            tau, M = self.mg.gravity(qa, payload=self.payload[i])
            _, jf = m.serial_frames(qa)
        return {"q": qa, "dir": self.dirs[i], "tau": tau, "M": M, "T": self.T[i], "ts": self.ts[i],
                "session": int(self.session[i]), "payload": self.payload[i],
                "lo": {j: m.ranges[j][0] for j in m.actuated}, "hi": {j: m.ranges[j][1] for j in m.actuated},
                "jx": {j: jf[j][:3, 0] for j in m.actuated}, "jR": {j: jf[j][:3, :3] for j in m.actuated}}

    def points(self, i, with_effect=True):
        """Measured target points (tracker frame, mm) and the output orientation in the tracker frame,
        noise-free."""
        if (i, with_effect) in self._rigid:
            return self._rigid[(i, with_effect)]
        name = self.effect if with_effect else None
        kind = E.KIND.get(name) if name else None
        c = self.ctx(i) if name else None
        qa = self.poses[i][0]
        post = None
        if kind == "joint":
            dq = E.joint_dq(name, self.params, c)
            qa = {j: v + dq.get(j, 0.0) for j, v in qa.items()}
        elif kind == "frame":
            post = E.frame_post(name, self.params, c)
            if self.m.parallel:
                raise ValueError("frame effects are serial only here")
        T, _ = self._rigid_pose(i, qa, post)
        Rout = T[:3, :3]
        offs = self.toff
        if kind == "target":
            offs = [o + E.target_shift(name, self.params, c, o) for o in self.toff]
        P = [T[:3, :3] @ o + T[:3, 3] for o in offs]
        Rb = np.eye(3)
        if kind == "point_base":
            res = [E.point_base(name, self.params, c, p) for p in P]
            P = [r[0] for r in res]
            Rb = res[0][1]
        M = [self.tR.T @ (p - self.to) for p in P]
        if kind == "point_tracker":
            M = [E.point_tracker(name, self.params, c, mm) for mm in M]
            P = [self.to + self.tR @ mm for mm in M]  # the measurement's change seen in the base frame
        Rt = self.tR.T @ Rb @ Rout @ rotvec_to_R(ROT_OFFSET)
        self._rigid[(i, with_effect)] = (M, Rt, P)
        return M, Rt, P

    def sigma(self, m):
        a, b = self.F["noise"]
        return a + b * np.linalg.norm(m) / 1000.0

    # -- files --------------------------------------------------------------------------------------
    def write(self, outdir):
        os.makedirs(outdir, exist_ok=True)
        rng = np.random.default_rng(_seed("noise", self.case["name"]))
        rows = {False: [], True: []}
        for i in range(len(self.poses)):
            M, Rt, _ = self.points(i, self.effect is not None)
            vals = []
            for mm in M:
                s = self.sigma(mm) * self.noise_factor
                vals.append(mm + rng.normal(0, s, 3))
            ori = None
            if self.six_d:
                w = rng.normal(0, ORIENT_NOISE * self.noise_factor, 3)
                ori = Rotation.from_matrix(rotvec_to_R(w) @ Rt).as_quat()  # x y z w
            rows[bool(self.val[i])].append((i, vals, ori))
        self._write_csv(os.path.join(outdir, "data.csv"), rows[False])
        self._write_csv(os.path.join(outdir, "val.csv"), rows[True])

    def _write_csv(self, path, rows):
        F, m = self.F, self.m
        a, b = F["noise"]
        lines = ["# hyperstat measurements, version 1", f"# mechanism: {m.data.get('name', self.fam)}",
                 f"# noise: {a} mm + {b} mm/m"]
        if F["pos_unit"] == "mm":
            lines.append("# tracker: " + " ".join(f"{v:.4f}" for v in self.header_o) + " "
                         + " ".join(f"{v:.6f}" for v in self.header_r))
        for (tn, _), pr in zip(self.targets, self.tprior):
            lines.append(("# target: " if tn is None else f"# target {tn}: ") + " ".join(f"{v:.3f}" for v in pr))
        if self.six_d:
            lines.append(f"# orientation noise: {ORIENT_NOISE * 1000:.3f} mrad")
        u = F["pos_unit"]
        cols = ["pose"] + [f"q{j}[{F['cols'][j]}]" for j in m.actuated]
        for tn, _ in self.targets:
            sfx = "" if tn is None else "_" + tn
            cols += [f"x{sfx}[{u}]", f"y{sfx}[{u}]", f"z{sfx}[{u}]"]
        if self.six_d:
            cols += ["quat_w", "quat_x", "quat_y", "quat_z"]
        cols += ["time[s]", "session", "temperature[degC]", "payload[kg]"] + [f"dir{j}" for j in m.actuated]
        lines.append(",".join(cols))
        conv = {"mm": 1.0, "m": 1e-3, "rad": 1.0, "deg": 180.0 / math.pi}
        for i, vals, ori in rows:
            qa = self.poses[i][0]
            r = [f"P{i + 1}"] + [repr(float(qa[j] * conv[F["cols"][j]])) for j in m.actuated]
            for v in vals:
                r += [repr(float(x * conv[u])) for x in v]
            if self.six_d:
                r += [repr(float(ori[3])), repr(float(ori[0])), repr(float(ori[1])), repr(float(ori[2]))]
            r += [f"{self.t[i]:.1f}", str(int(self.session[i])), f"{self.T[i]:.3f}", f"{self.payload[i]:g}"]
            r += [str(int(self.dirs[i][j])) for j in m.actuated]
            lines.append(",".join(r))
        tmp = path + ".tmp"
        with open(tmp, "w") as f:
            f.write("\n".join(lines) + "\n")
        os.replace(tmp, path)

    # -- visibility ---------------------------------------------------------------------------------
    def visibility(self):
        """RMS of the held-out 3-D residual norms of the linearised rigid fit of the effect's
        displacement, over the RMS of the stated noise's 3-D norms (positions only)."""
        if self.effect is None:
            return None
        A_rows, y_rows, w_rows, val_rows = [], [], [], []
        dl = list(self.m.kin.defect_list)
        prior = np.array([1e-3 if c in "IJKG" else 0.5 for _, c in dl] + [20.0] * 3 + [0.02] * 3
                         + [5.0] * (3 * len(self.toff)))
        nt = len(self.toff)
        for i in range(len(self.poses)):
            qa, qfull = self.poses[i]
            q = qfull if self.m.parallel else qa
            key = (self.fam, self.case["design"], len(self.poses), i, id(self.poses))
            if key not in _JAC:
                To, dTo = self.m.output_jacobian(q, dl)
                _JAC[key] = (To, dTo[len(self.m.actuated):])
            To, dTo = _JAC[key]
            _, _, Pe = self.points(i, True)
            _, _, Pr = self.points(i, False)
            for k, o in enumerate(self.toff):
                p = To[:3, :3] @ o + To[:3, 3]
                J = np.zeros((3, len(prior)))
                for c, D in enumerate(dTo):
                    J[:, c] = D[:3, :3] @ o + D[:3, 3]
                nd = len(dl)
                J[:, nd:nd + 3] = np.eye(3)
                J[:, nd + 3:nd + 6] = -np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
                J[:, nd + 6 + 3 * k:nd + 9 + 3 * k] = To[:3, :3]
                s = self.sigma(self.tR.T @ (p - self.to))
                A_rows.append(J / s)
                y_rows.append((Pe[k] - Pr[k]) / s)
                w_rows.append(np.full(3, s))
                val_rows.append(np.full(3, self.val[i]))
        A = np.vstack(A_rows)
        y = np.concatenate(y_rows)
        sg = np.concatenate(w_rows)
        v = np.concatenate(val_rows)
        idr = ~v
        As = A * prior  # scaled unknowns, ridge of one
        x = np.linalg.solve(As[idr].T @ As[idr] + np.eye(len(prior)), As[idr].T @ y[idr])
        r = (y - As @ x) * sg  # mm
        rv = r[v].reshape(-1, 3)
        sv = sg[v].reshape(-1, 3)[:, 0]
        return float(np.sqrt(np.mean(np.sum(rv ** 2, axis=1))) / np.sqrt(np.mean(3 * sv ** 2)))


def truth(case, vis):
    return {"name": case["name"], "family": case["family"], "model": case["model"], "kind": case["kind"],
            "effect": case.get("truth"), "joints": case.get("joints"), "params": case_params(case),
            "noise_factor": case.get("noise_factor", 1.0), "visibility": vis,
            "targets": case["targets"], "design": case["design"], "n": case["n"]}


def generate(outdir, seed=0, names=None, visibility=True):
    make_models(outdir)
    out = {}
    for case in CASES:
        if names and case["name"] not in names:
            continue
        c = Campaign(case, seed)
        d = os.path.join(outdir, "campaigns", case["name"])
        c.write(d)
        vis = c.visibility() if visibility else None
        t = truth(case, vis)
        with open(os.path.join(d, "truth.json"), "w") as f:
            json.dump(t, f, indent=1)
        out[case["name"]] = t
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("outdir")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cases")
    ap.add_argument("--no-visibility", action="store_true")
    a = ap.parse_args(argv)
    names = a.cases.split(",") if a.cases else None
    res = generate(a.outdir, a.seed, names, not a.no_visibility)
    for n, t in res.items():
        print(f"{n:22s} {t['kind']:6s} {t['effect'] or '-':24s} vis {t['visibility']}")


if __name__ == "__main__":
    sys.exit(main())
