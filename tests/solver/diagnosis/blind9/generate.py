"""Campaign generation of the eleventh blind generator (directory ``blind9``).

Units: mm, rad inside; the files state theirs per column (mm or m, rad or deg); degC, s, kg.
Source-blind (``RULES.md``): the model files are read by ``blind8/machine.py`` / ``blind7/kin.py``
(generator code written source-blind, imported); the families, model variants, pose designs,
metadata, targets, tracker, noise, true geometry, effects and the visibility fit are this file's own.
Nothing here imports hyperstat.

    python -m tests.solver.diagnosis.blind9.generate OUTDIR [--seed 0] [--cases a,b] [--no-visibility]
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
import zlib

import numpy as np
from scipy.spatial.transform import Rotation

from tests.solver.diagnosis.blind8.machine import Machine, write_variant
from tests.solver.diagnosis.blind9 import effects as fx
from tests.solver.diagnosis.blind9.cases import CASES

HERE = os.path.dirname(os.path.abspath(__file__))
VIS_LINE = 0.6

# ---- families -------------------------------------------------------------------------------
FAMILIES = {
    "tx7": dict(base="tx7", parallel=True, share=0.8, true_model="tx7_m", true_geometry=False,
                units={"41": "m", "42": "m", "43": "m", "6": "rad", "7": "rad"}, pos_unit="mm",
                tracker_header=True, noise=(0.004, 0.003), dist=(2.2, 3.2), payloads=[0.0, 6.0, 15.0]),
    "hexa": dict(base="hexa", parallel=True, share=0.8, true_model="hexa_m", true_geometry=True,
                 units={j: "mm" for j in ("31", "32", "33", "34", "35", "36")}, pos_unit="m",
                 tracker_header=False, noise=(0.005, 0.002), dist=(1.8, 2.6), payloads=[0.0, 8.0, 20.0]),
    "lift": dict(base="lift7", parallel=False, share=0.85, true_model="lift_m", true_geometry=True,
                 units={"1": "mm", "2": "deg", "3": "deg", "4": "deg", "5": "deg", "6": "deg", "7": "deg"},
                 pos_unit="mm", tracker_header=True, noise=(0.008, 0.005), dist=(2.5, 3.5),
                 payloads=[0.0, 2.0, 5.0]),
    "cyl": dict(base="cyl5", parallel=False, share=0.85, true_model="cyl_m", true_geometry=True,
                units={"1": "deg", "2": "m", "3": "m", "4": "deg", "5": "deg"}, pos_unit="m",
                tracker_header=False, noise=(0.006, 0.004), dist=(2.0, 3.0), payloads=[0.0, 1.0, 3.0]),
}
LIFT_MASSES = {"1": 25.0, "2": 18.0, "3": 12.0, "4": 6.0, "5": 3.0, "6": 1.5, "7": 0.6}
CYL_MASSES = {"1": 30.0, "2": 15.0, "3": 8.0, "4": 2.5, "5": 1.2}
MOVING_MASS = {"tx7": 55.0, "hexa": 30.0}
CYL_LEAD = 16.0  # mm, declared in both cyl model variants

# target layouts: offsets in the output frame (mm); six_d: "rotvec" or "quat" or None
TARGETS = {
    "cross5": dict(offsets={"C": [0, 0, 60], "E": [150, 0, 60], "N": [0, 150, 60], "W": [-150, 0, 60],
                            "S": [0, -150, 60]}, six_d=None),
    "tcp6r": dict(offsets={"": [20, -10, 150]}, six_d="rotvec"),
    "ring4": dict(offsets={"A": [177, 177, 25], "B": [-177, 177, 25], "C": [-177, -177, 25],
                           "D": [177, -177, 25]}, six_d=None),
    "tip6q": dict(offsets={"": [80, 50, 220]}, six_d="quat"),
    "fork3": dict(offsets={"F1": [60, 0, 90], "F2": [-30, 52, 90], "F3": [-30, -52, 150]}, six_d=None),
    "flange6r": dict(offsets={"": [0, 25, 120]}, six_d="rotvec"),
    "single": dict(offsets={"": [35, 20, 60]}, six_d=None),
    "pair": dict(offsets={"P1": [0, 70, 50], "P2": [0, -70, 50]}, six_d=None),
}
ROT_OFFSET = np.array([0.04, -0.06, 0.03])  # rad, true rotation offset of a 6-D target
ORI_NOISE = 0.025e-3  # rad, 1 sigma per axis


def _rng(*keys):
    return np.random.default_rng([zlib.crc32("/".join(str(k) for k in keys).encode())])


# ---- models -------------------------------------------------------------------------------------
def make_models(out):
    """The model variants (deterministic) in OUT/models; returns {variant: path}."""
    d = os.path.join(out, "models")
    os.makedirs(d, exist_ok=True)
    src = {k: os.path.join(HERE, "models", f"{k}.skel.json") for k in ("tx7", "hexa", "lift7", "cyl5")}
    paths = {}
    for k, v in (("tx7", "tx7"), ("hexa", "hexa"), ("lift", "lift7")):
        paths[k] = os.path.join(d, f"{k}.skel.json")
        shutil.copyfile(src[v], paths[k] + ".tmp")
        os.replace(paths[k] + ".tmp", paths[k])
    for k in ("tx7", "hexa"):
        paths[k + "_m"] = write_variant(src[k], os.path.join(d, f"{k}_m.skel.json"), moving_mass=MOVING_MASS[k])
    paths["lift_m"] = write_variant(src["lift7"], os.path.join(d, "lift_m.skel.json"),
                                    masses=_masses(src["lift7"], LIFT_MASSES))
    paths["cyl"] = write_variant(src["cyl5"], os.path.join(d, "cyl.skel.json"), screw_lead=CYL_LEAD)
    paths["cyl_m"] = write_variant(src["cyl5"], os.path.join(d, "cyl_m.skel.json"),
                                   masses=_masses(src["cyl5"], CYL_MASSES), screw_lead=CYL_LEAD)
    return paths


def _masses(path, table):
    """Each body's centre of mass at home midway between its joint's origin and the next joint's
    (the output's for the last), base frame, mm."""
    m = Machine(path)
    q0 = {n: m.home[n] for n in m.actuated}
    T, jf = m.serial_frames(q0)
    names = [e.name for e in m.elements if e.kind == "joint"]
    out = {}
    for i, n in enumerate(names):
        a = jf[n][:3, 3]
        b = jf[names[i + 1]][:3, 3] if i + 1 < len(names) else T[:3, 3]
        out[n] = {"mass": table[n], "com": [round(float(x), 3) for x in (a + b) / 2]}
    return out


# ---- pose designs -------------------------------------------------------------------------------
def design_u(design, n, dim, rng):
    """n points u in [-1, 1]^dim in the order the program visits them."""
    from scipy.stats import qmc
    if design == "antithetic":
        h = qmc.Halton(dim, scramble=True, seed=rng).random((n + 1) // 2) * 2 - 1
        u = np.empty((2 * len(h), dim))
        u[0::2], u[1::2] = h, -h
        return u[:n]
    if design == "star":
        k = min(int(0.45 * n), 4 * dim)
        rows = []
        levels = [1.0, -1.0, 0.5, -0.5]
        for i in range(k):
            v = rng.uniform(-0.15, 0.15, dim)
            v[i % dim] = levels[(i // dim) % 4]
            rows.append(v)
        rows += list(rng.uniform(-1, 1, (n - k, dim)))
        return np.array(rows)
    if design == "corners":
        rows = []
        for i in range(n):
            if i % 5 == 4:
                rows.append(rng.uniform(-0.3, 0.3, dim))
            else:
                rows.append(rng.choice([-0.92, 0.92], dim) + rng.normal(0, 0.05, dim))
        return np.clip(np.array(rows), -1, 1)
    if design == "shells":
        v = rng.normal(size=(n, dim))
        v = v / np.abs(v).max(axis=1, keepdims=True)
        r = np.where(np.arange(n) % 2 == 0, 0.55, 0.95)
        return v * r[:, None]
    raise ValueError(design)


_POSES = {}


def nominal_poses(fam, machine, design, n, seed=0):
    """Actuated values (model units) and the closed nominal joints of n poses (cached)."""
    key = (fam, design, n, seed)
    if key in _POSES:
        return _POSES[key]
    F = FAMILIES[fam]
    rng = _rng(seed, "poses", fam, design, n)
    u = design_u(design, n, len(machine.actuated), rng)
    qa_list, qf_list = [], []
    for row in u:
        for attempt in range(8):
            qa = {}
            for j, x in zip(machine.actuated, row):
                lo, hi = machine.ranges[j]
                qa[j] = (lo + hi) / 2 + F["share"] * (hi - lo) / 2 * x
            if not machine.parallel:
                qa_list.append(qa)
                qf_list.append(dict(qa))
                break
            q, r = machine.kin.solve_path(qa)
            if r < 1e-8 and machine.kin.passive_inside(q, 0.02):
                qa_list.append(qa)
                qf_list.append(q)
                break
            row = row * 0.8
        else:
            raise RuntimeError(f"{fam}: no closed pose near {row}")
    _POSES[key] = (qa_list, qf_list)
    return _POSES[key]


# ---- metadata -----------------------------------------------------------------------------------
SESSION_START = [0.0, 5 * 3600.0, 22 * 3600.0, 28 * 3600.0]  # s from the campaign's start
POSE_TIME = 80.0  # s per pose


def metadata(n, machine, qa_list, overshoot, payloads, rng):
    sess = np.minimum(np.arange(n) * 4 // n, 3) + 1
    meta = []
    prev = None
    k_in = 0
    for i in range(n):
        s = int(sess[i])
        if i > 0 and sess[i - 1] != s:
            k_in = 0
        ts = k_in * POSE_TIME
        k_in += 1
        t = SESSION_START[s - 1] + ts
        day = 21.0 + 3.5 * np.sin(2 * np.pi * t / 86400.0 - 1.2)
        warm = 2.5 * (1 - np.exp(-ts / 1500.0)) if s in (1, 3) else -1.0 * (1 - np.exp(-ts / 2000.0))
        T = day + warm + rng.normal(0, 0.03)
        qa = qa_list[i]
        if overshoot:
            dr = {j: float(rng.choice([-1.0, 1.0])) for j in machine.actuated}
        else:
            dr = {j: (1.0 if prev is None or qa[j] >= prev[j] else -1.0) for j in machine.actuated}
        prev = qa
        meta.append(dict(session=s, t=t, ts=ts, T=float(T), payload=float(rng.choice(payloads)), dir=dr))
    return meta


# ---- the campaign -------------------------------------------------------------------------------
def rigid_defects(machine, rng, on):
    if not on:
        return None
    out = {}
    for e, comp in machine.kin.defect_list:
        out[(e, comp)] = float(rng.normal(0, 2e-4 if comp in "IJKG" else 0.15))
    return out


def tracker_pose(centre, F, rng):
    az = rng.uniform(0, 2 * np.pi)
    d = rng.uniform(*F["dist"]) * 1000.0
    o = centre + np.array([d * np.cos(az), d * np.sin(az), rng.uniform(-300, 300)])
    R = Rotation.from_rotvec([rng.normal(0, 0.015), rng.normal(0, 0.015), 0.0]).as_matrix() @ \
        Rotation.from_rotvec([0, 0, rng.uniform(-np.pi, np.pi)]).as_matrix()
    return o, R


def _ctx(machine, truth_m, qa, qf, md, tracker):
    tau, M = truth_m.gravity(qa, qf if machine.parallel else None, md["payload"])
    s, half = {}, {}
    for j in machine.actuated:
        lo, hi = machine.ranges[j]
        half[j] = (hi - lo) / 2
        s[j] = (qa[j] - (lo + hi) / 2) / half[j]
    ctx = dict(q=qa, dir=md["dir"], T=md["T"], payload=md["payload"], session=md["session"], ts=md["ts"],
               tau=tau, M=M, s=s, half=half, tracker=tracker)
    if machine.parallel:
        jf = machine.kin.frames(qf)[2]
        ctx["legdir"] = {j: jf[j][:3, 2] for j in machine.actuated if machine.types[j] == "P"}
    else:
        ctx["jframes"] = machine.serial_frames(qa)[1]
    return ctx


def true_points(machine, qa, qf, defects, eff_parts, offsets, Roff, ctx):
    """Noise-free base-frame positions and orientations of the targets."""
    dq = eff_parts.get("dq", {})
    q2 = {j: qa[j] + dq.get(j, 0.0) for j in machine.actuated}
    if machine.parallel:
        T, q, r = machine.pose(q2, init=machine.passive_vector(qf), defects=defects)
        if r > 1e-6:
            T, q, r = machine.pose(q2, defects=defects)
        if r > 1e-6:
            raise RuntimeError(f"loop closure residual {r}")
    else:
        T, _ = machine.serial_frames(q2, eff_parts.get("post"), defects)
    if "out" in eff_parts:
        T = T @ eff_parts["out"]
    ctx = dict(ctx, Rout=T[:3, :3])
    pts = []
    for o in offsets:
        p = T[:3, :3] @ o + T[:3, 3]
        R = T[:3, :3] @ Roff
        if "base" in eff_parts:
            p, R = eff_parts["base"](p, R, ctx)
        pts.append((p, R))
    return pts


def campaign(case, paths, outdir, seed=0, visibility=True):
    """Write OUT/campaigns/<case>/data.csv, val.csv, truth.json; returns the truth dict."""
    name = case["name"]
    F = FAMILIES[case["family"]]
    machine = Machine(paths[case["model"]], moving_mass=MOVING_MASS.get(case["family"]))
    truth_m = Machine(paths[F["true_model"]], moving_mass=MOVING_MASS.get(case["family"]))
    n = case["n_id"] + case["n_val"]
    qa_list, qf_list = nominal_poses(case["family"], machine, case["design"], n, seed)
    rng = _rng(seed, "case", name)
    defects = rigid_defects(machine, rng, F["true_geometry"])
    meta = metadata(n, machine, qa_list, case.get("overshoot", False), F["payloads"], rng)
    lay = TARGETS[case["targets"]]
    tnames = list(lay["offsets"])
    offsets = [np.asarray(v, float) + rng.uniform(-2, 2, 3) for v in lay["offsets"].values()]
    priors = [o + rng.uniform(-1.5, 1.5, 3) for o in offsets]
    Roff = Rotation.from_rotvec(ROT_OFFSET).as_matrix() if lay["six_d"] else np.eye(3)
    # workspace centre and tracker
    centre = np.mean([machine.pose(qa, init=machine.passive_vector(qf) if machine.parallel else None)[0][:3, 3]
                      for qa, qf in zip(qa_list[:12], qf_list[:12])], axis=0)
    o_t, R_t = tracker_pose(centre, F, rng)
    eff = case.get("effect")
    a, b = F["noise"]
    factor = case.get("noise_factor", 1.0)
    # held-out poses: a random quarter-ish of each session (stratified)
    sess = np.array([m["session"] for m in meta])
    val = set()
    for s in range(1, 5):
        idx = np.flatnonzero(sess == s)
        k = int(round(case["n_val"] * len(idx) / n))
        val.update(rng.choice(idx, k, replace=False).tolist())
    while len(val) < case["n_val"]:
        val.add(int(rng.integers(n)))
    while len(val) > case["n_val"]:
        val.remove(sorted(val)[-1])
    rows, diffs = [], []
    for i in range(n):
        qa, qf, md = qa_list[i], qf_list[i], meta[i]
        ctx = _ctx(machine, truth_m, qa, qf, md, (o_t, R_t))
        parts = fx.apply(eff, ctx)
        pts = true_points(machine, qa, qf, defects, parts, offsets, Roff, ctx)
        if visibility and eff is not None:
            pts0 = true_points(machine, qa, qf, defects, {}, offsets, Roff, ctx)
        meas = []
        for k, (p, R) in enumerate(pts):
            m = R_t.T @ (p - o_t)
            if "meas" in parts:
                m = parts["meas"](m, ctx)
            if visibility and eff is not None:
                m0 = R_t.T @ (pts0[k][0] - o_t)
                diffs.append(R_t @ (m - m0))
            d_m = np.linalg.norm(p - o_t) / 1000.0
            sig = (a + b * d_m) * factor
            m = m + rng.normal(0, sig, 3)
            Rm = Rotation.from_rotvec(rng.normal(0, ORI_NOISE * factor, 3)).as_matrix() @ R_t.T @ R
            meas.append((m, Rm))
        rows.append((qa, md, meas))
    cdir = os.path.join(outdir, "campaigns", name)
    os.makedirs(cdir, exist_ok=True)
    ids = [i for i in range(n) if i not in val]
    vals = sorted(val)
    header = _header(machine, F, (o_t, R_t), rng, tnames, priors, lay, (a, b))
    _write_csv(os.path.join(cdir, "data.csv"), header, machine, F, tnames, lay, [rows[i] for i in ids], ids)
    _write_csv(os.path.join(cdir, "val.csv"), header, machine, F, tnames, lay, [rows[i] for i in vals], vals)
    truth = dict(case=case, n_id=len(ids), n_val=len(vals), tracker=[*o_t.tolist(), *Rotation.from_matrix(R_t).as_rotvec().tolist()],
                 offsets={t: o.tolist() for t, o in zip(tnames, offsets)}, true_geometry=bool(defects))
    if visibility and eff is not None:
        truth["visibility"] = visibility_of(machine, qa_list, qf_list, ids, vals, offsets, o_t, diffs, (a, b))
    tmp = os.path.join(cdir, "truth.json.tmp")
    with open(tmp, "w") as f:
        json.dump(truth, f, indent=1, default=float)
    os.replace(tmp, os.path.join(cdir, "truth.json"))
    return truth


def _header(machine, F, tracker, rng, tnames, priors, lay, noise):
    o_t, R_t = tracker
    h = ["# hyperstat measurements, version 1", f"# mechanism: {machine.data.get('name', 'machine')}",
         f"# noise: {noise[0]:g} mm + {noise[1]:g} mm/m"]
    if F["tracker_header"]:
        rv = Rotation.from_matrix(R_t).as_rotvec() + rng.normal(0, 1e-3, 3)
        o = o_t + rng.normal(0, 1.0, 3)
        h.append("# tracker: " + " ".join(f"{x:.3f}" for x in o) + " " + " ".join(f"{x:.5f}" for x in rv))
    for t, p in zip(tnames, priors):
        h.append(("# target: " if t == "" else f"# target {t}: ") + " ".join(f"{x:.2f}" for x in p))
    if lay["six_d"]:
        h.append(f"# orientation noise: {ORI_NOISE * 1000:g} mrad")
    return h


def _conv(v, unit):
    return {"mm": v, "m": v / 1000.0, "rad": v, "deg": np.degrees(v)}[unit]


def _write_csv(path, header, machine, F, tnames, lay, rows, idx):
    pu = F["pos_unit"]
    cols = ["pose"] + [f"q{j}[{F['units'][j]}]" for j in machine.actuated]
    for t in tnames:
        sfx = f"_{t}" if t else ""
        cols += [f"x{sfx}[{pu}]", f"y{sfx}[{pu}]", f"z{sfx}[{pu}]"]
        if lay["six_d"] == "rotvec":
            cols += [f"rx{sfx}[rad]", f"ry{sfx}[rad]", f"rz{sfx}[rad]"]
        elif lay["six_d"] == "quat":
            cols += [f"quat_w{sfx}", f"quat_x{sfx}", f"quat_y{sfx}", f"quat_z{sfx}"]
    cols += ["time[s]", "session", "temperature[degC]", "payload[kg]"] + [f"dir{j}" for j in machine.actuated]
    lines = list(header) + [",".join(cols)]
    for k, (qa, md, meas) in zip(idx, rows):
        v = [f"P{k + 1}"] + [f"{_conv(qa[j], F['units'][j]):.10g}" for j in machine.actuated]
        for m, Rm in meas:
            v += [f"{_conv(x, pu):.10g}" for x in m]
            if lay["six_d"] == "rotvec":
                v += [f"{x:.10g}" for x in Rotation.from_matrix(Rm).as_rotvec()]
            elif lay["six_d"] == "quat":
                x, y, z, w = Rotation.from_matrix(Rm).as_quat()
                if w < 0:
                    x, y, z, w = -x, -y, -z, -w
                v += [f"{c:.12g}" for c in (w, x, y, z)]
        v += [f"{md['t']:.1f}", str(md["session"]), f"{md['T']:.3f}", f"{md['payload']:g}"]
        v += [f"{int(md['dir'][j])}" for j in machine.actuated]
        lines.append(",".join(v))
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(tmp, path)


# ---- visibility: own linearised rigid fit ------------------------------------------------------
_JAC = {}


def _jacobians(machine, qa_list, qf_list):
    key = (machine.path, len(qa_list), id(qa_list))
    if key not in _JAC:
        dl = list(machine.kin.defect_list)
        out = []
        for qa, qf in zip(qa_list, qf_list):
            To, dTo = machine.output_jacobian(qf if machine.parallel else qa, defects=dl)
            out.append((To, dTo[len(machine.actuated):]))
        _JAC[key] = (dl, out)
    return _JAC[key]


def visibility_of(machine, qa_list, qf_list, ids, vals, offsets, o_t, diffs, noise):
    """RMS of the held-out residual norms after the linearised rigid fit on the identification
    poses / RMS of the stated noise's 3-D norms."""
    dl, jac = _jacobians(machine, qa_list, qf_list)
    nt = len(offsets)
    nd = len(dl)
    ncol = nd + 6 + 3 * nt
    prior = np.array([1e-3 if c in "IJKG" else 0.5 for _, c in dl] + [20.0] * 3 + [0.02] * 3 + [5.0] * 3 * nt)
    D = np.array(diffs).reshape(len(qa_list), nt, 3)
    blocks = {}
    for i, (To, dTo) in enumerate(jac):
        A = np.zeros((3 * nt, ncol))
        sig = np.zeros(3 * nt)
        for k, o in enumerate(offsets):
            r = slice(3 * k, 3 * k + 3)
            p = To[:3, :3] @ o + To[:3, 3]
            for c, dT in enumerate(dTo):
                A[r, c] = dT[:3, :3] @ o + dT[:3, 3]
            A[r, nd:nd + 3] = np.eye(3)
            A[r, nd + 3:nd + 6] = -np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
            A[r, nd + 6 + 3 * k:nd + 9 + 3 * k] = To[:3, :3]
            sig[r] = noise[0] + noise[1] * np.linalg.norm(p - o_t) / 1000.0
        blocks[i] = (A, sig, D[i].reshape(-1))
    A = np.vstack([blocks[i][0] / blocks[i][1][:, None] for i in ids] + [np.diag(1 / prior)])
    y = np.concatenate([blocks[i][2] / blocks[i][1] for i in ids] + [np.zeros(ncol)])
    x = np.linalg.lstsq(A, y, rcond=None)[0]
    res, sg = [], []
    for i in vals:
        Ai, si, di = blocks[i]
        r = (di - Ai @ x).reshape(nt, 3)
        res += list(np.sum(r * r, axis=1))
        sg += list(3 * (si.reshape(nt, 3)[:, 0] ** 2))
    return float(np.sqrt(np.mean(res) / np.mean(sg)))


def generate(outdir, seed=0, names=None, visibility=True, log=print):
    paths = make_models(outdir)
    out = {}
    for case in CASES:
        if names and case["name"] not in names:
            continue
        t0 = time.process_time()
        tr = campaign(case, paths, outdir, seed, visibility)
        out[case["name"]] = tr
        log(f"{case['name']}: visibility {tr.get('visibility', '-')} ({time.process_time() - t0:.1f} s CPU)")
    return paths, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cases", default="")
    ap.add_argument("--no-visibility", action="store_true")
    a = ap.parse_args(argv)
    names = set(a.cases.split(",")) if a.cases else None
    generate(a.outdir, a.seed, names, not a.no_visibility)
    return 0


if __name__ == "__main__":
    sys.exit(main())
