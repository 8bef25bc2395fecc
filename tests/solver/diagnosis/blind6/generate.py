"""Writes the blind6 campaigns: data.csv, val.csv (held out), truth.json per case.

Units: mm, rad, °C, s, kg (file columns state theirs: joints in mm, rad or deg; positions in mm
or m).  Numpy only; the kinematics is kin.py's, the effects effects.py's; hyperstat is not
imported.  `python -m tests.solver.diagnosis.blind6.generate OUTDIR [--seed 0] [--jobs 2]
[--cases a,b] [--no-visibility]`.
"""
from __future__ import annotations

import argparse
import json
import os
import zlib
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from . import effects as fx
from .cases import C, CASES
from .kin import Model, expm, logm, skew

HERE = Path(__file__).resolve().parent
VISIBILITY_LINE = 0.6

TARGETS = {
    "tx7": {"smr1": [(25, -30, 40)], "smr3": [(40, -20, 30), (-35, 30, 45), (10, 45, -25)], "6d": [(20, 25, 35)]},
    "hexa": {"smr1": [(150, -80, 60)], "smr3": [(180, -60, 50), (-120, 140, 40), (-60, -160, 70)], "6d": [(100, 90, 60)]},
    "serial": {"smr1": [(60, -40, 90)], "smr3": [(90, -30, 70), (-70, 80, 60), (20, -95, 110)], "6d": [(50, 40, 80)]},
}
ROT_OFFSET_6D = (0.2, -0.15, 0.25)  # rad, rotation vector of the 6-D target in the output frame
ORIENT_NOISE = 3e-5  # rad per axis (header: 0.03 mrad)

FAMILIES = {
    # model file, noise (mm, mm/m), poses id/val, joint column unit for revolutes, position unit,
    # stroke share used, payload levels (kg), tracker distance (mm), azimuth (rad), height offset (mm)
    "tx7": dict(model="tripteor_x7.skel.json", noise=(0.004, 0.003), n=(42, 18), rev="rad", pos="mm",
                share_p=0.8, share_r=0.95, payload=(0, 5, 12), dist=2600, az=0.7, dz=300, targets="tx7"),
    "hexa": dict(model="hexapod.skel.json", noise=(0.004, 0.003), n=(32, 12), rev="rad", pos="mm",
                 share_p=0.8, share_r=0.95, payload=(0, 10, 25), dist=2400, az=-2.2, dz=200, targets="hexa"),
    "st6": dict(model="st6.skel.json", noise=(0.010, 0.004), n=(40, 16), rev="deg", pos="mm",
                share_p=0.9, share_r=0.85, payload=(0, 4, 10), dist=2800, az=2.5, dz=-200, targets="serial"),
    "abb6": dict(model="abb6.skel.json", noise=(0.010, 0.004), n=(40, 16), rev="rad", pos="m",
                 share_p=0.9, share_r=0.8, payload=(0, 6, 15), dist=3200, az=-0.6, dz=-100, targets="serial"),
    "pal4": dict(model="pal4.skel.json", noise=(0.012, 0.005), n=(40, 16), rev="deg", pos="mm",
                 share_p=0.9, share_r=0.85, payload=(0, 40, 100), dist=3600, az=1.2, dz=0, targets="serial"),
}

_MODELS = {}


def model(fam):
    if fam not in _MODELS:
        _MODELS[fam] = Model(HERE / "models" / FAMILIES[fam]["model"])
    return _MODELS[fam]


def case_rng(seed, name, salt=""):
    return np.random.default_rng([seed, zlib.crc32((name + salt).encode())])


class Campaign:
    """One campaign's design: poses (file values), metadata in measuring order, tracker, targets."""

    def __init__(self, case, seed):
        self.case = case
        fam = FAMILIES[case["family"]]
        self.fam = fam
        self.m = m = model(case["family"])
        rng = case_rng(seed, case["name"])
        n_id, n_val = fam["n"]
        self.n = n = n_id + n_val
        # poses
        act = m.actuated
        mids = {j: 0.5 * (m.range[j][0] + m.range[j][1]) for j in act}
        half = {j: 0.5 * (m.range[j][1] - m.range[j][0]) * (fam["share_p"] if m.types[j] == "P" else fam["share_r"])
                for j in act}
        self.q, self.full = [], []
        u = rng.uniform(-1, 1, len(act))
        tries = 0
        while len(self.q) < n:
            tries += 1
            if tries > 50 * n:
                raise RuntimeError("pose design failed for " + case["name"])
            d = case["design"]
            if d == "uniform":
                v = rng.uniform(-1, 1, len(act))
            elif d == "walk":
                v = u + rng.normal(0, 0.45, len(act))
                v = np.where(v > 1, 2 - v, v)
                v = np.where(v < -1, -2 - v, v)
                v = np.clip(v, -1, 1)
            else:  # shell: most poses near the boundary of the box, a quarter inside
                g = rng.normal(0, 1, len(act))
                v = g / np.max(np.abs(g)) * (rng.uniform(0.8, 1.0) if rng.uniform() < 0.75 else rng.uniform(0, 0.8))
            qa = {j: mids[j] + half[j] * v[i] for i, j in enumerate(act)}
            full = m.assemble(qa, guess=self.full[-1] if self.full else None)
            if full is None or not m.in_range(full):
                full = m.assemble(qa) if full is None else full
                if full is None or not m.in_range(full):
                    continue
            u = v
            self.q.append(qa)
            self.full.append(full)
        # metadata in measuring order: two sessions (days)
        half_n = n // 2
        self.session = np.array([1] * half_n + [2] * (n - half_n))
        ts = np.array([80.0 * k for k in range(half_n)] + [80.0 * (k - half_n) for k in range(half_n, n)])
        self.time = np.where(self.session == 1, ts, ts + 86400.0)
        start = np.where(self.session == 1, 18.5, 20.0)
        rise = np.where(self.session == 1, 5.5, 4.5)
        self.temp = (start + rise * (1 - np.exp(-ts / 2500.0)) + 0.4 * np.sin(2 * np.pi * ts / 1700.0 + 0.3 * self.session)
                     + rng.normal(0, 0.08, n))
        levels = fam["payload"]
        self.payload = np.array([levels[rng.integers(len(levels))] for _ in range(n // 7 + 1) for _ in range(7)][:n], float)
        self.dirs, self.move = [], []
        prev_dir = {j: int(rng.choice([-1, 1])) for j in act}
        for k in range(n):
            mv = {j: (self.q[k][j] - self.q[k - 1][j]) if k else prev_dir[j] * half[j] * 0.3 for j in act}
            dr = {j: (int(np.sign(mv[j])) if mv[j] != 0 else prev_dir[j]) for j in act}
            prev_dir = dr
            self.dirs.append(dr)
            self.move.append(mv)
        self.val = np.sort(rng.choice(n, n_val, replace=False))
        self.ident = np.array([k for k in range(n) if k not in set(self.val)])
        # tracker: about `dist` from the workspace centre, turned about z
        centre = np.mean([m.output_pose(f)[:3, 3] for f in self.full], axis=0)
        az = fam["az"] + rng.uniform(-0.2, 0.2)
        self.t_trk = centre + np.array([fam["dist"] * np.cos(az), fam["dist"] * np.sin(az), fam["dz"]])
        self.r_trk = np.array([0.0, 0.0, (az + np.pi + rng.uniform(-0.3, 0.3) + np.pi) % (2 * np.pi) - np.pi])
        self.R_trk = expm(self.r_trk)
        self.header_tracker = np.concatenate([np.round(self.t_trk + rng.normal(0, 1.5, 3), 1),
                                              np.round(self.r_trk + [0, 0, rng.normal(0, 2e-3)], 4)])
        lay = TARGETS[fam["targets"]][case["targets"]]
        self.offsets = [np.array(o, float) + rng.uniform(-3, 3, 3) for o in lay]
        self.priors = [np.round(o + rng.uniform(-2, 2, 3), 1) for o in self.offsets]
        self.six_d = case["targets"] == "6d"
        self.R_off = expm(ROT_OFFSET_6D)
        self.noise_rng = case_rng(seed, case["name"], "noise")
        self.effect = fx.make(case["effect"], **case["params"]) if case["effect"] else None

    # ------------------------------------------------------------------
    def measure(self, with_effect=True):
        """Noise-free measurements: list over poses of (points (nt,3) in the tracker frame, R (3,3) or None)."""
        m, e = self.m, (self.effect if with_effect else None)
        out = []
        for k in range(self.n):
            full = self.full[k]
            T = m.output_pose(full)
            if e is not None:
                dq = e.dq(self, k)
                if dq:
                    qa = dict(self.q[k])
                    for j, v in dq.items():
                        qa[j] += v
                    full = m.assemble(qa, guess=self.full[k])
                    T = m.output_pose(full)
                B = e.base_motion(self, k)
                if B is not None:
                    T = B @ T
            pts = []
            for i, off in enumerate(self.offsets):
                o = e.target(self, k, i, off) if e is not None else off
                p = T[:3, :3] @ o + T[:3, 3]
                if e is not None:
                    p = e.point(self, k, p, T)
                mm = self.R_trk.T @ (p - self.t_trk)
                if e is not None:
                    mm = e.meas(self, k, mm)
                pts.append(mm)
            R = self.R_trk.T @ T[:3, :3] @ self.R_off if self.six_d else None
            out.append((np.array(pts), R))
        return out

    def sigmas(self, meas):
        a, b = self.fam["noise"]
        return np.array([[a + b * np.linalg.norm(p) / 1000.0 for p in pts] for pts, _ in meas])

    def noisy(self, meas):
        f = self.case["factor"]
        sig = self.sigmas(meas) * f
        rng = self.noise_rng
        res = []
        for k, (pts, R) in enumerate(meas):
            P = pts + rng.normal(0, 1, pts.shape) * sig[k][:, None]
            RR = expm(rng.normal(0, ORIENT_NOISE * f, 3)) @ R if R is not None else None
            res.append((P, RR))
        return res

    # ------------------------------------------------------------------
    def write(self, outdir, visibility=True):
        out = Path(outdir) / self.case["name"]
        out.mkdir(parents=True, exist_ok=True)
        meas = self.noisy(self.measure(True))
        for fname, rows in (("data.csv", self.ident), ("val.csv", self.val)):
            tmp = out / (fname + ".tmp")
            tmp.write_text(self.csv(meas, rows))
            os.replace(tmp, out / fname)
        truth = dict(case=self.case["name"], family=self.case["family"], kind=self.case["kind"],
                     truth=(self.effect.name if self.effect is not None else None),
                     joints=(self.effect.joints() if self.effect is not None and self.case["kind"] == "in" else []),
                     params=self.case["params"], targets=self.case["targets"], design=self.case["design"],
                     noise_factor=self.case["factor"], model=FAMILIES[self.case["family"]]["model"],
                     poses=[len(self.ident), len(self.val)])
        if visibility and self.effect is not None:
            truth["visibility"] = round(float(self.visibility()), 3)
        (out / "truth.json").write_text(json.dumps(truth, indent=1, default=list))
        return truth

    def csv(self, meas, rows):
        m, fam = self.m, self.fam
        a, b = fam["noise"]
        lines = ["# hyperstat measurements, version 1", "# mechanism: %s" % m.data["name"],
                 "# noise: %g mm + %g mm/m" % (a, b),
                 "# tracker: " + " ".join("%g" % v for v in self.header_tracker)]
        multi = len(self.offsets) > 1
        names = ["SMR%d" % (i + 1) for i in range(len(self.offsets))] if multi else [None]
        for nm, pr in zip(names, self.priors):
            lines.append("# target%s: %s" % (" " + nm if nm else "", " ".join("%g" % v for v in pr)))
        if self.six_d:
            lines.append("# orientation noise: %g mrad" % (ORIENT_NOISE * 1000))
        pu = fam["pos"]
        cols = ["pose"]
        for j in m.actuated:
            cols.append("q%s[%s]" % (j, "mm" if m.types[j] == "P" else fam["rev"]))
        for nm in names:
            sfx = "_" + nm if nm else ""
            cols += ["x%s[%s]" % (sfx, pu), "y%s[%s]" % (sfx, pu), "z%s[%s]" % (sfx, pu)]
        if self.six_d:
            cols += ["rx[rad]", "ry[rad]", "rz[rad]"]
        cols += ["time[s]", "temperature[degC]", "payload[kg]", "session"] + ["dir%s" % j for j in m.actuated]
        lines.append(",".join(cols))
        sc = 1000.0 if pu == "m" else 1.0
        for k in rows:
            pts, R = meas[k]
            v = ["P%d" % (k + 1)]
            for j in m.actuated:
                q = self.q[k][j]
                v.append("%.9f" % (np.degrees(q) if (m.types[j] == "R" and fam["rev"] == "deg") else q))
            for p in pts:
                v += ["%.10f" % (x / sc) for x in p]
            if R is not None:
                v += ["%.10f" % x for x in logm(R)]
            v += ["%.1f" % self.time[k], "%.3f" % self.temp[k], "%g" % self.payload[k], "%d" % self.session[k]]
            v += ["%d" % self.dirs[k][j] for j in m.actuated]
            lines.append(",".join(v))
        return "\n".join(lines) + "\n"

    # ------------------------------------------------------------------ visibility (own linearised rigid fit)
    def jacobian(self):
        """Rows: 3 per (pose, target) in the tracker frame; columns: every defect of the model file,
        tracker (3 shifts, 3 turns), each target's offset (3).  Passive joints follow the closures
        (implicit differentiation, least squares where the structure is over-constrained)."""
        m = self.m
        nd = len(m.defects)
        h = 1e-6
        rows = []
        for k in range(self.n):
            q = self.full[k]
            F0, cl0 = m.frames(q)
            T0 = F0[m.output]
            c0 = np.concatenate(cl0) if cl0 else np.zeros(0)

            def dpose(F):
                T = F[m.output]
                return np.concatenate([(T[:3, 3] - T0[:3, 3]) / h, logm(T[:3, :3] @ T0[:3, :3].T) / h])

            Pd = np.zeros((6, nd))
            Cd = np.zeros((len(c0), nd))
            for i, (el, comp) in enumerate(m.defects):
                F, cl = m.frames(q, {el: {comp: h}})
                Pd[:, i] = dpose(F)
                if len(c0):
                    Cd[:, i] = (np.concatenate(cl) - c0) / h
            if len(c0) and m.passive:
                Pp = np.zeros((6, len(m.passive)))
                Cp = np.zeros((len(c0), len(m.passive)))
                for i, n in enumerate(m.passive):
                    qq = dict(q)
                    qq[n] += h
                    F, cl = m.frames(qq)
                    Pp[:, i] = dpose(F)
                    Cp[:, i] = (np.concatenate(cl) - c0) / h
                Pd = Pd - Pp @ np.linalg.pinv(Cp, rcond=1e-9) @ Cd
            for i, off in enumerate(self.offsets):
                p = T0[:3, :3] @ off + T0[:3, 3]
                mm = self.R_trk.T @ (p - self.t_trk)
                Jg = self.R_trk.T @ (Pd[:3] - skew(T0[:3, :3] @ off) @ Pd[3:])
                Jt = np.hstack([-self.R_trk.T, skew(mm)])
                Jo = np.zeros((3, 3 * len(self.offsets)))
                Jo[:, 3 * i:3 * i + 3] = self.R_trk.T @ T0[:3, :3]
                rows.append(np.hstack([Jg, Jt, Jo]))
        prior = [1e-3 if comp in "IJKG" else 0.5 for _, comp in m.defects] + [20.0] * 3 + [0.02] * 3 + [5.0] * (3 * len(self.offsets))
        return np.vstack(rows), np.array(prior)

    def visibility(self):
        """Held-out RMS of the effect's noise-free signature left by the rigid fit (MAP, priors above) on the
        identification poses, over the stated noise's 3-D RMS (sqrt(3) sigma) on the held-out points."""
        A, prior = self.jacobian()
        d0, d1 = self.measure(False), self.measure(True)
        nt = len(self.offsets)
        dm = np.concatenate([(d1[k][0] - d0[k][0]).ravel() for k in range(self.n)])
        sig = np.repeat(self.sigmas(d0).ravel(), 3)
        idr = np.concatenate([np.arange(3 * nt * k, 3 * nt * (k + 1)) for k in self.ident])
        vr = np.concatenate([np.arange(3 * nt * k, 3 * nt * (k + 1)) for k in self.val])
        Aw = np.vstack([A[idr] / sig[idr, None], np.diag(1.0 / prior)])
        bw = np.concatenate([dm[idr] / sig[idr], np.zeros(len(prior))])
        x = np.linalg.lstsq(Aw, bw, rcond=None)[0]
        r = (dm[vr] - A[vr] @ x).reshape(-1, 3)
        s = sig[vr].reshape(-1, 3)[:, 0]
        return np.sqrt(np.mean(np.sum(r ** 2, axis=1))) / np.sqrt(np.mean(3 * s ** 2))


def _one(args):
    name, seed, outdir, vis = args
    return Campaign(CASES[name], seed).write(outdir, visibility=vis)


def generate(outdir, seed=0, names=None, jobs=2, visibility=True):
    names = names or [c["name"] for c in C]
    work = [(n, seed, str(outdir), visibility) for n in names]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as ex:
            return list(ex.map(_one, work))
    return [_one(w) for w in work]


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m tests.solver.diagnosis.blind6.generate",
                                 description="write the blind6 campaigns (data.csv, val.csv, truth.json per case)")
    ap.add_argument("outdir")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all)")
    ap.add_argument("--no-visibility", action="store_true", help="skip the visibility fit")
    a = ap.parse_args(argv)
    names = [s for s in a.cases.split(",") if s] or None
    for t in generate(a.outdir, a.seed, names, a.jobs, not a.no_visibility):
        print("%-20s %-5s %-6s %-22s vis %s" % (t["case"], t["family"], t["kind"], t["truth"], t.get("visibility", "-")))


if __name__ == "__main__":
    main()
