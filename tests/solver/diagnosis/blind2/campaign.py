"""One campaign: a true machine, poses, metadata, the effect, the tracker; writes the engineer's files.

Units: mm, rad, kg, degC, s.  Noise: 1 sigma per axis 0.005 mm + 0.005 mm/m times the distance to the
tracker (the header states it; in the ``understated`` case the true noise is larger).
"""
from __future__ import annotations

import json
import os
import zlib
from dataclasses import dataclass

import numpy as np

from . import arms as A
from .effects import draw

N_ID, N_VAL = 100, 30
NOISE_A, NOISE_B = 0.005, 0.005        # mm, mm/m
POSE_DT = 40.0                         # s between poses


@dataclass
class Variant:
    arm: str
    design: str          # "full" or "short2"
    masses: bool         # link masses in the URDF given to import-robot
    targets: int         # 1 or 3 reflectors
    payload: bool        # payload changes between poses (payload[kg] column)

    @property
    def label(self) -> str:
        return f"{self.arm}-{self.design}-{'mass' if self.masses else 'nomass'}-{self.targets}t-{'pay' if self.payload else 'nopay'}"


def seed_of(*parts) -> int:
    return zlib.crc32("|".join(map(str, parts)).encode())


def draw_poses(arm, design, n, rng):
    lim = arm.designs[design]
    geo = A.nominal_geometry(arm)
    out = []
    floor = 150.0 if arm.size_class != "light" else 60.0
    while len(out) < n:
        q = np.array([rng.uniform(lo, hi) for lo, hi in lim])
        F = A.frames(geo, q)
        if F[6][2, 3] < floor or F[4][2, 3] < floor:
            continue
        out.append(q)
    return np.array(out)


def _rot_about(R, c):
    """4x4 rotation R about the point c."""
    return A.hom(R, c - R @ c)


def true_points(case, par, arm, geo, q, meta, offsets):
    """Base-frame positions (n_targets x 3) of the reflectors for the recorded joint values q of one pose."""
    pay = meta["payload"]
    qt = q.copy()
    # ---------- joint-level effects (the load side of each joint) ----------
    if case in ("compliance", "backlash-gravity", "load-hysteresis"):
        tau = A.gravity_torque(arm, geo, q, pay)
        if case == "compliance":
            qt = qt + np.array(par["compliance_rad_per_Nmm"]) * tau
        elif case == "backlash-gravity":
            qt = qt + 0.5 * np.array(par["beta_rad"]) * np.sign(tau)
        else:
            tmax = np.array(meta["tau_max"])
            qt = qt - np.array(meta["dir"]) * np.array(par["h_rad"]) * np.abs(tau) / np.maximum(tmax, 1e-9)
    if case == "backlash":
        qt = qt - 0.5 * np.array(par["beta_rad"]) * np.array(meta["dir"])
    if case in ("angle-harmonic-1", "angle-harmonic-2", "harmonic3-short", "stage-4.6"):
        j = par["joint"]
        qt[j] += par["amp"] * np.sin(par["order"] * q[j] + par["phase"])
    if case == "angle-scale":
        qt[par["joint"]] += par["scale"] * q[par["joint"]]
    if case == "cubic-joint2":
        lo, hi = meta["range2"]
        u = (q[1] - 0.5 * (lo + hi)) / (0.5 * (hi - lo))
        qt[1] += par["amp"] * u ** 3
    if case == "wrist-coupling":
        qt[5] += par["ratio"] * q[4]
    # ---------- deformations of the placements ----------
    hook = None
    grow = 1.0
    if case == "thermal":
        grow = 1.0 + par["alpha"] * (meta["temperature"] - 20.0)

        def hook(i, T, P):
            P = P.copy()
            P[:3, 3] *= grow
            return P
    if case == "warmup":
        dT = par["dT"] * (1.0 - np.exp(-meta["time"] / par["tau_s"]))

        def hook(i, T, P):
            if i in (2, 3, 4):           # the upper arm (to joint 3) and the forearm (to joints 4, 5)
                P = P.copy()
                P[:3, 3] *= 1.0 + par["alpha"] * dT
            return P
    if case == "beam-bending":
        hook = _beam_hook(arm, geo, qt, pay, par)
        meta["_mag"] = abs(hook.theta)
    F = A.frames(geo, qt, hook)
    tool = F[6]
    pts = []
    for off in offsets:
        off = np.array(off, float) * grow
        p = tool[:3, :3] @ off + tool[:3, 3]
        if case == "tool-sag":
            axis = tool[:3, :3] @ off
            L = np.linalg.norm(off)
            axis = axis / L
            g = np.array([0.0, 0.0, -1.0])
            gperp = g - (g @ axis) * axis            # unit gravity across the rod (|.| = sin of its angle)
            d = par["F_N"] * L ** 3 / (3 * par["EI_Nmm2"]) + par["w_N_per_mm"] * L ** 4 / (8 * par["EI_Nmm2"])
            p = p + d * gperp
            meta["_mag"] = max(meta.get("_mag", 0.0), d * np.linalg.norm(gperp))
        pts.append(p)
    pts = np.array(pts)
    # ---------- rigid-body motions of the whole arm ----------
    if case == "base-tilt":
        cs = A.body_coms(arm, F)
        pc = tool[:3, :3] @ np.array(arm.payload_com) + tool[:3, 3]
        g = np.array([0.0, 0.0, -A.G])
        M = sum(np.cross(c, arm.masses[i][0] * g) for i, c in enumerate(cs)) + np.cross(pc, pay * g)
        M[2] = 0.0                                   # the overturning moment about the floor's origin
        R = A.rotvec(par["tilt_rad_per_Nmm"] * M)
        meta["_mag"] = par["tilt_rad_per_Nmm"] * np.linalg.norm(M)
        pts = pts @ R.T
    if case == "bearing-wobble":
        ph = par["order"] * q[0] + par["phase"]
        R = A.rotvec(par["eps_rad"] * np.array([np.cos(ph), np.sin(ph), 0.0]))
        c = np.array([0.0, 0.0, geo.placements[0][2, 3]])
        pts = (pts - c) @ R.T + c
    return pts


def _beam_hook(arm, geo, qt, pay, par):
    """The upper arm (link 2, from joint 2 to joint 3 along its z) as an Euler-Bernoulli cantilever."""
    F0 = A.frames(geo, qt)
    L = np.linalg.norm(geo.placements[2][:3, 3])
    # loads in the frame of link 2
    R2 = F0[1][:3, :3]
    g = np.array([0.0, 0.0, -A.G])
    m2 = arm.masses[1][0]
    w = (R2.T @ (m2 * g))[0] / L                          # own weight across the beam, N/mm (along local x)
    pe = F0[2][:3, 3]                                     # the elbow
    cs = A.body_coms(arm, F0)
    pc = F0[6][:3, :3] @ np.array(arm.payload_com) + F0[6][:3, 3]
    Fw = sum(arm.masses[b][0] * g for b in range(2, 6)) + pay * g
    Mw = sum(np.cross(cs[b] - pe, arm.masses[b][0] * g) for b in range(2, 6)) + np.cross(pc - pe, pay * g)
    Fx = (R2.T @ Fw)[0]
    My = (R2.T @ Mw)[1]                                   # couple about the joint axis (y) at the end
    EI = par["EI_Nmm2"]
    theta = (w * L ** 3 / 6 + Fx * L ** 2 / 2 + My * L) / EI
    v = (w * L ** 4 / 8 + Fx * L ** 3 / 3 + My * L ** 2 / 2) / EI
    end = np.array([0.0, 0.0, L])
    B = A.hom(None, end + np.array([v, 0.0, 0.0])) @ A.hom(A.rot_axis([0, 1, 0], theta)) @ A.hom(None, -end)

    def hook(i, T, P):
        return B @ P if i == 2 else P
    hook.theta = theta
    return hook


def generate(case, variant: Variant, seed: int, noise_free: bool = False):
    """Return the campaign (dict of arrays) for one case, variant and seed."""
    arm = A.ARMS[variant.arm]
    rng = np.random.default_rng(seed_of(case, variant.label, seed))
    geo = A.perturbed_geometry(arm, rng)
    par = draw(case, arm, rng)
    n = N_ID + N_VAL
    q = draw_poses(arm, variant.design, n, rng)
    t = POSE_DT * np.arange(n)
    if case == "thermal":
        temp = par["t_mean"] + par["t_amp"] * np.sin(2 * np.pi * 1.5 * t / t[-1] + par["phase"]) + rng.normal(0, 0.1, n)
    else:
        temp = 20.0 + 0.2 * np.sin(2 * np.pi * t / t[-1]) + rng.normal(0, 0.05, n)
    pay = rng.choice(arm.payload_values, n) if variant.payload else np.zeros(n)
    dirs = rng.choice([-1.0, 1.0], (n, 6))
    session = np.where(np.arange(n) < n // 2, 1, 2)
    offsets = arm.targets1 if variant.targets == 1 else arm.targets3
    # true reflector offsets differ from the nominal ones by up to 0.5 mm (nests, SMR centring)
    offsets_true = [np.array(o) + rng.uniform(-0.5, 0.5, 3) for o in offsets]
    lim2 = arm.designs[variant.design][1]
    tau_max = np.max(np.abs([A.gravity_torque(arm, geo, q[k], arm.payload_values[-1]) for k in range(0, n, 10)]), axis=0)
    tp, trv = arm.tracker
    Rt = A.rotvec(trv)
    tt = np.array(tp, float)
    pts = np.zeros((n, len(offsets), 3))
    mags = []
    pts0 = np.zeros_like(pts)                # the same machine without the effect (self-checks)
    for k in range(n):
        meta = {"payload": pay[k], "dir": dirs[k], "temperature": temp[k], "time": t[k], "range2": lim2,
                "tau_max": tau_max}
        pts[k] = true_points(case, par, arm, geo, q[k], meta, offsets_true)
        mags.append(meta.get("_mag", 0.0))
        pts0[k] = true_points("none", par, arm, geo, q[k], meta, offsets_true)
    # measurement in the tracker frame
    meas = (pts - tt) @ Rt          # R^T (p - t) for each row
    if case == "tracker-drift":
        meas[session == 2] += np.array(par["drift_mm"])
    dist_m = np.linalg.norm(pts - tt, axis=2) / 1e3
    sigma = NOISE_A + NOISE_B * dist_m
    factor = par.get("noise_factor", 1.0)
    noise = rng.normal(size=meas.shape) * (factor * sigma)[..., None]     # drawn always: same stream
    if not noise_free:
        meas = meas + noise
    val = np.zeros(n, bool)
    val[rng.choice(n, N_VAL, replace=False)] = True
    return {"arm": arm, "geo": geo, "par": par, "q": q, "t": t, "temp": temp, "payload": pay, "dirs": dirs,
            "session": session, "meas": meas, "magnitude": float(np.max(mags)), "points": pts, "points_rigid": pts0, "val": val, "offsets": offsets, "sigma": sigma,
            "tracker": (tt + rng.uniform(-20, 20, 3), np.array(trv) + rng.uniform(-0.01, 0.01, 3))}


def write_csv(path, c, rows, arm):
    names = ["SMR1", "SMR2", "SMR3"][: len(c["offsets"])]
    lines = ["# hyperstat measurements, version 1", f"# mechanism: {arm.name}",
             f"# noise: {NOISE_A} mm + {NOISE_B} mm/m"]
    tp, trv = c["tracker"]
    lines.append("# tracker: " + " ".join(f"{v:.3f}" for v in tp) + " " + " ".join(f"{v:.4f}" for v in trv))
    if len(names) == 1:
        lines.append("# target: " + " ".join(f"{v:.1f}" for v in c["offsets"][0]))
    else:
        for nm, o in zip(names, c["offsets"]):
            lines.append(f"# target {nm}: " + " ".join(f"{v:.1f}" for v in o))
    head = ["pose"] + [f"qj{i+1}[rad]" for i in range(6)]
    if len(names) == 1:
        head += ["x[mm]", "y[mm]", "z[mm]"]
    else:
        for nm in names:
            head += [f"x_{nm}[mm]", f"y_{nm}[mm]", f"z_{nm}[mm]"]
    head += ["temperature[degC]", "payload[kg]", "time[s]", "session"] + [f"dirj{i+1}" for i in range(6)]
    lines.append(",".join(head))
    for k in rows:
        vals = [f"P{k+1}"] + [repr(float(v)) for v in c["q"][k]]
        vals += [repr(float(v)) for v in c["meas"][k].ravel()]
        vals += [f"{c['temp'][k]:.3f}", f"{c['payload'][k]:g}", f"{c['t'][k]:g}", str(int(c["session"][k]))]
        vals += [str(int(d)) for d in c["dirs"][k]]
        lines.append(",".join(vals))
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    os.replace(tmp, path)


def write_campaign(outdir, case, variant: Variant, seed: int, model_path: str, noise_free=False):
    """Write ident.csv and val.csv (the engineer's files) and truth.json; return the campaign dict."""
    os.makedirs(outdir, exist_ok=True)
    c = generate(case, variant, seed, noise_free=noise_free)
    idx = np.arange(len(c["q"]))
    sfx = ".nf" if noise_free else ""
    write_csv(os.path.join(outdir, f"ident{sfx}.csv"), c, idx[~c["val"]], c["arm"])
    write_csv(os.path.join(outdir, f"val{sfx}.csv"), c, idx[c["val"]], c["arm"])
    truth = {"case": case, "variant": variant.label, "seed": seed, "model": model_path,
             "params": {k: (np.asarray(v).tolist() if isinstance(v, (np.ndarray, list)) else v) for k, v in c["par"].items()},
             "noise_rms_stated_mm": float(np.sqrt(3 * np.mean(c["sigma"] ** 2)))}
    with open(os.path.join(outdir, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1, default=float)
    return c
