"""Blind campaign generator for hyperstat's diagnosis (issue 28, item 7).

Written without reading hyperstat's diagnosis or effects code, and importing nothing from
hyperstat.  It draws a true machine (our arms of ``kinematics``, our placement errors), poses
of our own designs, a laser tracker, the case's effects (``effects``) and metadata, and writes
what a calibration engineer would hand over: the arm's URDF (with or without ``<inertial>``)
and measurement files in the format of docs/identification.md (identification and
validation), plus ``truth.json`` (what was simulated, never read by hyperstat).

    python -m tests.solver.diagnosis.blind.generator CASE ARM SEED OUTDIR

Tracker: placed ``arm.tracker_distance`` from the base axis, turned about the vertical at
random and tilted by up to 10 mrad; it reports each reflector's position in its own frame,
``p_tracker = R^T (p_world - t)``, with Gaussian noise of 1 sigma per axis
``f (a + b d)`` (a = 5 um, b = 5 um/m, d the tracker-reflector distance; f = 1 except in the
understated-noise cases); the header states ``a + b d``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sys
import zlib
from typing import Dict, List

import numpy as np

from . import effects as fx
from .cases import CASE_BY_NAME, DESIGNS, Case
from .kinematics import Arm, Geometry, exp_so3, frames, get_arm, log_so3, points, write_urdf

NOISE_A = 5e-6   # m, 1 sigma per axis
NOISE_B = 5e-6   # m per m of distance
N_ID, N_VAL = 100, 30
PAYLOADS = {"ind6": [0.0, 8.0, 16.0], "cobot6": [0.0, 5.0, 10.0]}
TARGETS_ONE = {"ind6": [[0.06, -0.04, 0.09]], "cobot6": [[0.05, 0.04, 0.08]]}
TARGETS_THREE = [[0.08, 0.0, 0.06], [-0.04, 0.07, 0.06], [-0.04, -0.07, 0.09]]
TARGET_EXTENSION = [[0.04, 0.03, 0.50]]


def campaign_seed(case: str, arm: str, seed: int) -> int:
    return zlib.crc32(f"blind28/{case}/{arm}/{seed}".encode())


@dataclasses.dataclass
class Campaign:
    case: Case
    arm: Arm
    arm_key: str
    seed: int
    q: np.ndarray                # (K, 6) commanded joint values, rad (K = N_ID + N_VAL, time order)
    is_val: np.ndarray           # (K,) bool
    meta: Dict[str, np.ndarray]  # payload, temperature, time, session, dirs
    targets: np.ndarray          # (T, 3) m, true offsets in tool0
    tracker_R: np.ndarray
    tracker_t: np.ndarray
    geom: Geometry
    change: fx.Change
    specs: list
    size: str
    measured: np.ndarray         # (K, T, 3) m in the tracker frame, NaN where lost
    clean: np.ndarray            # (K, T, 3) m, noise-free with the effect
    rigid: np.ndarray            # (K, T, 3) m, noise-free without the effect
    sigma_header: np.ndarray     # (K, T) m per axis, the header's model
    sigma_true: np.ndarray       # (K, T)
    ctx: fx.Context


# --------------------------------------------------------------------------- poses

def sample_poses(arm: Arm, arm_key: str, design: str, k: int, rng: np.random.Generator) -> np.ndarray:
    """``k`` poses uniform in the design's joint windows, kept when the flange is above
    z = -0.3 m (base frame), the wrist centre is 0.3 m or more from the base axis and the
    tool is at least 0.25 m from the shoulder (no self-collision in this crude sense)."""
    box = np.array(DESIGNS[design][arm_key])
    out = []
    geom = Geometry.nominal(arm.n)
    while len(out) < k:
        q = rng.uniform(box[:, 0], box[:, 1], size=(4 * k, arm.n))
        fr = frames(arm, geom, q)
        wrist = fr[5][:, :3, 3]
        tool = fr[7][:, :3, 3]
        shoulder = fr[2][:, :3, 3]
        ok = (tool[:, 2] > -0.3) & (np.hypot(wrist[:, 0], wrist[:, 1]) > 0.3) & \
             (np.linalg.norm(tool - shoulder, axis=1) > 0.25)
        out.extend(q[ok])
    return np.array(out[:k])


# --------------------------------------------------------------------------- metadata

def make_meta(case: Case, arm_key: str, k: int, rng: np.random.Generator) -> Dict[str, np.ndarray]:
    """Metadata in time order: 130 poses about 70 s apart (2.5 h), payload changed twice,
    the tracker re-set once (session 2 from the middle on), approach directions at random."""
    t = np.cumsum(rng.uniform(55.0, 85.0, size=k))
    meta: Dict[str, np.ndarray] = {"time": t}
    if case.payload:
        blocks = list(PAYLOADS[arm_key])
        rng.shuffle(blocks)
        edges = np.sort(rng.choice(np.arange(30, k - 30), size=2, replace=False))
        p = np.empty(k)
        p[:edges[0]], p[edges[0]:edges[1]], p[edges[1]:] = blocks
        meta["payload"] = p
    else:
        meta["payload"] = np.zeros(k)
    tau = t[-1] / 2.0
    if case.temperature == "arm":
        # the upper arm warms from 20 to ~36 degC as its motor heats (first-order lag)
        meta["temperature"] = 20.0 + 16.0 * (1 - np.exp(-t / tau)) + rng.normal(0, 0.2, k)
    else:
        # the workshop warms from 17 to ~27-29 degC through the day (also recorded when unused)
        meta["temperature"] = 17.0 + 12.0 * (1 - np.exp(-t / tau)) + rng.normal(0, 0.2, k)
    meta["session"] = np.where(np.arange(k) < k // 2, 1, 2)
    meta["dirs"] = rng.choice([-1.0, 1.0], size=(k, 6))
    return meta


# --------------------------------------------------------------------------- tracker

def place_tracker(arm: Arm, rng: np.random.Generator):
    az = rng.uniform(-0.7, 0.7)
    d = arm.tracker_distance * rng.uniform(0.95, 1.05)
    t = np.array([d * math.cos(az), d * math.sin(az), rng.uniform(-0.2, 0.4)])
    yaw = rng.uniform(-math.pi, math.pi)
    tilt = rng.uniform(-0.01, 0.01, size=2)
    r = exp_so3(np.array([0.0, 0.0, yaw])) @ exp_so3(np.array([tilt[0], tilt[1], 0.0]))
    return r, t


def to_tracker(r: np.ndarray, t: np.ndarray, p_world: np.ndarray) -> np.ndarray:
    return np.einsum("ji,ktj->kti", r, p_world - t)


# --------------------------------------------------------------------------- build

def build(case_name: str, arm_key: str, seed: int, geometry_errors: bool = True, noise: bool = True) -> Campaign:
    """The campaign of (case, arm, seed).  ``geometry_errors=False`` and ``noise=False`` are for
    the self-checks only (the nominal machine, exact measurements)."""
    case = CASE_BY_NAME[case_name]
    if arm_key not in case.arms:
        raise ValueError(f"case {case_name} does not run on {arm_key}")
    arm = get_arm(arm_key)
    rng = np.random.default_rng(campaign_seed(case_name, arm_key, seed))
    geom = Geometry.random(rng, arm.n)
    if not geometry_errors:
        geom = Geometry.nominal(arm.n)
    k = N_ID + N_VAL
    q = sample_poses(arm, arm_key, case.design, k, rng)
    is_val = np.zeros(k, bool)
    is_val[rng.choice(k, size=N_VAL, replace=False)] = True
    meta = make_meta(case, arm_key, k, rng)
    if case.extension:
        targets = np.array(TARGET_EXTENSION)
    else:
        targets = np.array(TARGETS_THREE if case.targets == 3 else TARGETS_ONE[arm_key])
    tr, tt = place_tracker(arm, rng)
    specs, size = case.effects(arm_key, rng)
    ctx = fx.Context(arm, geom, q, meta["payload"], meta["temperature"], meta["dirs"], meta["session"], len(targets))
    change = fx.apply(ctx, specs)

    rigid = measure_clean(arm, geom, q, targets, tr, tt, fx.Change.empty(k))
    clean = measure_clean(arm, geom, q, targets, tr, tt, change)
    dist = np.linalg.norm(clean, axis=2)
    sig_h = NOISE_A + NOISE_B * dist
    sig_t = case.noise_factor * sig_h
    meas = clean + rng.normal(size=clean.shape) * sig_t[:, :, None] * (1.0 if noise else 0.0)
    if len(targets) > 1:
        lost = rng.random(size=dist.shape) < 0.03
        lost[lost.all(axis=1)] = False
        meas[lost] = np.nan
    return Campaign(case, arm, arm_key, seed, q, is_val, meta, targets, tr, tt, geom, change, specs, size,
                    meas, clean, rigid, sig_h, sig_t, ctx)


def measure_clean(arm: Arm, geom: Geometry, q: np.ndarray, targets: np.ndarray, tr, tt, change: fx.Change) -> np.ndarray:
    """Noise-free tracker-frame positions (K, T, 3) of the reflectors on the true machine."""
    k = len(q)
    fr = frames(arm, geom, q + change.dq, deform=change.deform, scale=change.scale)
    off = np.broadcast_to(targets, (k,) + targets.shape).copy()
    if change.target_scale is not None:
        off = off * change.target_scale[:, None, None]
    if change.target_shift is not None:
        off = off + change.target_shift[:, None, :]
    pw = points(fr[-1], off)
    if change.world_shift is not None:
        pw = pw + change.world_shift[:, None, :]
    return to_tracker(tr, tt, pw)


# --------------------------------------------------------------------------- files

def target_names(n: int) -> List[str]:
    return [f"SMR{i + 1}" for i in range(n)]


def write_csv(c: Campaign, path: str, rows: np.ndarray, label: str) -> None:
    """One measurement file (docs/identification.md) of the poses ``rows`` (indices)."""
    case, arm = c.case, c.arm
    lu, au = case.units
    lf = 1000.0 if lu == "mm" else 1.0
    af = 1.0 if au == "rad" else 180.0 / math.pi
    rng = np.random.default_rng(campaign_seed(case.name, c.arm_key, c.seed) + 7)
    lines = ["# hyperstat measurements, version 1",
             f"# mechanism: {arm.name}{'' if case.masses else '_nomass'}",
             "# noise: 0.005 mm + 0.005 mm/m",
             f"# blind28 generator: case {case.name}, arm {c.arm_key}, seed {c.seed} ({label})"]
    if lu == "mm":
        # rough tracker pose in the base frame (its frame's origin and rotation vector), as a
        # user would read it off the set-up: within ~20 mm and ~10 mrad
        tp = c.tracker_t * 1000.0 + rng.normal(0, 20.0, 3)
        rv = log_so3(c.tracker_R @ exp_so3(rng.normal(0, 0.01, 3)))
        lines.append("# tracker: " + " ".join(f"{v:.1f}" for v in tp) + " " + " ".join(f"{v:.3f}" for v in rv))
    names = target_names(len(c.targets))
    for i, tg in enumerate(c.targets):
        prior = np.round(tg * 1000.0 + rng.uniform(-2, 2, 3))
        if len(c.targets) == 1:
            lines.append("# target: " + " ".join(f"{v:.0f}" for v in prior))
        else:
            lines.append(f"# target {names[i]}: " + " ".join(f"{v:.0f}" for v in prior))
    cols = ["pose"] + [f"q{j.name}[{au}]" for j in arm.joints]
    if len(c.targets) == 1:
        cols += [f"x[{lu}]", f"y[{lu}]", f"z[{lu}]"]
    else:
        for n in names:
            cols += [f"x_{n}[{lu}]", f"y_{n}[{lu}]", f"z_{n}[{lu}]"]
    extra = []
    if case.payload:
        extra.append("payload[kg]")
    if case.temperature:
        extra.append("temperature[degC]")
    if case.time:
        extra.append("time[s]")
    if case.session:
        extra.append("session")
    if case.dirs:
        extra += [f"dir{j.name}" for j in arm.joints]
    lines.append(",".join(cols + extra))
    prefix = "V" if label == "validation" else "P"
    fmt_len = "{:.6f}" if lu == "mm" else "{:.9f}"
    for n, i in enumerate(rows):
        vals = [f"{prefix}{n + 1}"] + [f"{v * af:.10f}" for v in c.q[i]]
        for t in range(len(c.targets)):
            p = c.measured[i, t]
            vals += ["", "", ""] if np.isnan(p).any() else [fmt_len.format(v * lf) for v in p]
        if case.payload:
            vals.append(f"{c.meta['payload'][i]:.1f}")
        if case.temperature:
            vals.append(f"{c.meta['temperature'][i]:.2f}")
        if case.time:
            vals.append(f"{c.meta['time'][i]:.0f}")
        if case.session:
            vals.append(f"{int(c.meta['session'][i])}")
        if case.dirs:
            vals += [f"{int(d):d}" for d in c.meta["dirs"][i]]
        lines.append(",".join(vals))
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(tmp, path)


def noise_rms(sig: np.ndarray, rows: np.ndarray) -> float:
    """RMS of the 3-D noise norm (m) over the observations of ``rows``: sqrt(mean 3 sigma^2)."""
    s = sig[rows].ravel()
    return float(np.sqrt(np.mean(3 * s ** 2)))


def write(c: Campaign, outdir: str, analysis: bool = True) -> Dict[str, str]:
    """URDF, identification and validation files and truth.json in ``outdir``."""
    os.makedirs(outdir, exist_ok=True)
    urdf = os.path.join(outdir, f"{c.arm_key}{'' if c.case.masses else '_nomass'}.urdf")
    write_urdf(c.arm, urdf, with_masses=c.case.masses)
    ident = np.flatnonzero(~c.is_val)
    val = np.flatnonzero(c.is_val)
    data = os.path.join(outdir, "data.csv")
    valf = os.path.join(outdir, "data.validation.csv")
    write_csv(c, data, ident, "identification")
    write_csv(c, valf, val, "validation")
    eff = (c.clean - c.rigid)
    truth = {
        "case": c.case.name, "category": c.case.category, "rule": c.case.rule, "arm": c.arm_key, "seed": c.seed,
        "effects": _jsonable(c.specs), "size": c.size, "noise_factor": c.case.noise_factor,
        "masses_declared": c.case.masses, "targets": len(c.targets), "design": c.case.design,
        "truth": c.case.truth, "truth_order": c.case.truth_order, "accept": list(c.case.accept),
        "accept_order": c.case.accept_order, "family": list(c.case.family),
        "noise_rms_header_val_um": noise_rms(c.sigma_header, val) * 1e6,
        "noise_rms_true_val_um": noise_rms(c.sigma_true, val) * 1e6,
        "effect_rms_raw_um": float(np.sqrt(np.mean(np.sum(eff ** 2, axis=2)))) * 1e6,
        "joint_span_rad": [float(np.ptp(c.q[:, j])) for j in range(c.arm.n)],
        "tracker_t_mm": (c.tracker_t * 1000).tolist(), "tracker_rotvec": log_so3(c.tracker_R).tolist(),
        "targets_mm": (c.targets * 1000).tolist(),
    }
    if analysis:
        from .rigid import visibility
        truth.update(visibility(c))
    with open(os.path.join(outdir, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    return {"urdf": urdf, "data": data, "validation": valf}


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return x


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 4:
        print(__doc__.strip().splitlines()[0])
        print("usage: python -m tests.solver.diagnosis.blind.generator CASE ARM SEED OUTDIR")
        return 2
    case, arm, seed, out = argv[0], argv[1], int(argv[2]), argv[3]
    files = write(build(case, arm, seed), out)
    print("\n".join(f"{k}: {v}" for k, v in files.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
