"""Campaigns of the fifth blind generator: the cases, and the measurement files they give.

A campaign is one family, one case, one seed: a real machine (geometric errors, true masses,
a tracker), the poses a calibration engineer measures (identification and validation poses
interleaved in time over two sessions), the case's effects, the tracker's noise, and the
files ``hyperstat identify`` / ``diagnose`` read (docs/identification.md, "Measurement file").
A noise-free copy of the same campaign is written beside it (for the visibility check of the
scorer, never for the diagnosis).

Nothing is imported from hyperstat; hyperstat is only run as a command (``import-robot`` and
``build`` for the model files).
"""

from __future__ import annotations

import json
import os
import zlib
from dataclasses import dataclass, field

import numpy as np

from . import effects as fx
from . import geom
from .families import FAMILIES

UNDERSTATED_FACTOR = 1.6


@dataclass
class Case:
    family: str
    name: str
    category: str                   # none / understated / in / out
    make: object = None             # callable(fam) -> list of effects
    profile: str = "stable"         # temperature profile
    noise_factor: float = 1.0
    note: str = ""

    def effects(self, fam):
        return self.make(fam) if self.make else []


def _kr_cases():
    f = "kr_like"
    comp = [5e-11, 6e-11, 8e-11, 5e-10, 5e-10, 8e-10]   # net of the axis-2 balancer
    return [
        Case(f, "none", "none"),
        Case(f, "understated-noise", "understated", noise_factor=UNDERSTATED_FACTOR),
        Case(f, "eccentric-j1", "in", lambda m: [fx.Harmonic("1", 1, 9e-5)], note="1/rev of joint 1"),
        Case(f, "strain-wave-j2", "in", lambda m: [fx.Harmonic("2", 2, 9e-5)], note="2/rev of joint 2"),
        Case(f, "gear-stage-1.5-j1", "in", lambda m: [fx.Harmonic("1", 1.5, 9e-5)], note="3:2 stage on joint 1"),
        Case(f, "ratio-j3", "in", lambda m: [fx.Scale("3", 2.5e-4)]),
        Case(f, "compliance", "in", lambda m: [fx.Compliance(comp)]),
        Case(f, "backlash-j1", "in", lambda m: [fx.Backlash(["1"], [3e-4])]),
        Case(f, "gravity-backlash-j3-j5", "in", lambda m: [fx.GravitySide(["3", "5"], [3e-4, 4e-4])]),
        Case(f, "thermal", "in", lambda m: [fx.Thermal(1.15e-5)], profile="swing"),
        Case(f, "tracker-drift", "in", lambda m: [fx.TrackerDrift(0.08)]),
        Case(f, "upper-arm-bending", "in", lambda m: [fx.LinkBending((1, 2), 6e-11)]),
        Case(f, "pedestal-tilt", "in", lambda m: [fx.BaseTilt(1.2e-11, 2e-11)]),
        Case(f, "compliance+eccentric-j1", "in", lambda m: [fx.Compliance(comp), fx.Harmonic("1", 1, 9e-5)]),
        Case(f, "loose-nest-smr2", "out", lambda m: [fx.LooseNest("SMR2", 0.08)], note="the nest's magnet has failed: the ball rests on the lower rim"),
        Case(f, "cable-twist-j4-by-j5", "out", lambda m: [fx.CrossJoint("4", "5", 6e-4, "1-cos")]),
        Case(f, "arm-warm-up", "out", lambda m: [fx.WarmUpArm(0.09, 0.09, 2400.0)]),
        Case(f, "tracker-tripod-lean", "out", lambda m: [fx.TrackerTilt(7e-5, 3000.0)]),
        Case(f, "remastered-j3", "out", lambda m: [fx.SessionStep("3", 1.2e-4)], note="joint 3 re-mastered during the break (after a collision)"),
    ]


def _lbr_cases():
    f = "lbr_like"
    comp = [2e-9, 3e-9, 3e-9, 4e-9, 8e-9, 8e-9, 1e-8]
    a = ["lbr_a%d" % i for i in range(1, 8)]
    return [
        Case(f, "none", "none"),
        Case(f, "understated-noise", "understated", noise_factor=UNDERSTATED_FACTOR),
        Case(f, "compliance", "in", lambda m: [fx.Compliance(comp)]),
        Case(f, "strain-wave-j4", "in", lambda m: [fx.Harmonic(a[3], 2, 1.2e-4)]),
        Case(f, "eccentric-j1", "in", lambda m: [fx.Harmonic(a[0], 1, 1.1e-4)]),
        Case(f, "encoder-scale-j2", "in", lambda m: [fx.Scale(a[1], 3e-4)]),
        Case(f, "stand-tilt", "in", lambda m: [fx.BaseTilt(7e-10, 9e-10)]),
        Case(f, "thermal", "in", lambda m: [fx.Thermal(2.3e-5)], profile="swing"),
        Case(f, "tracker-drift", "in", lambda m: [fx.TrackerDrift(0.05)]),
        Case(f, "compliance+strain-wave-j4", "in", lambda m: [fx.Compliance(comp), fx.Harmonic(a[3], 2, 1.2e-4)]),
        Case(f, "cable-pull", "out", lambda m: [fx.CablePull(30.0, (-600.0, -500.0, 0.0), [1e-8, 1.5e-8, 1.5e-8, 2e-8, 3e-8, 3e-8, 4e-8])]),
        Case(f, "probe-roll-readout", "out", lambda m: [fx.RollReadout(2.5e-4)]),
        Case(f, "zero-drift-j4", "out", lambda m: [fx.ZeroDrift(a[3], 2.5e-4, 1800.0)]),
        Case(f, "loose-probe-adapter", "out", lambda m: [fx.ProbeSag("TMAC", 0.04)]),
    ]


def _tx_cases():
    f = "tripteor_x7"
    return [
        Case(f, "none", "none"),
        Case(f, "understated-noise", "understated", noise_factor=UNDERSTATED_FACTOR),
        Case(f, "leg-thermal", "in", lambda m: [fx.LegThermal(1.15e-5)], profile="swing"),
        Case(f, "lead-error-43", "in", lambda m: [fx.ScrewPitch("43", 9e-4)], note="a replacement screw whose lead differs from the declared one"),
        Case(f, "screw-periodic-41", "in", lambda m: [fx.ScrewPeriodic("41", 0.02, 20.0)]),
        Case(f, "bowed-guides-41-43", "in", lambda m: [fx.GuideBow("41", 0.05, 1), fx.GuideBow("43", 0.05, -1)],
             note="the two UPR legs' bars, one batch, mounted mirror-wise: both bow toward the same side of the machine"),
        Case(f, "joint-clearance", "in", lambda m: [fx.JointClearance({"41": 0.03, "42": 0.06, "43": 0.03})]),
        Case(f, "gantry-tilt", "in", lambda m: [fx.BaseTilt(1.5e-10, 2.5e-10)]),
        Case(f, "nut-backlash-42", "in", lambda m: [fx.Backlash(["42"], [0.04])]),
        Case(f, "compliance", "in", lambda m: [fx.Compliance([4e-5, 4e-5, 4e-5, 3e-9, 3e-9])]),
        Case(f, "thermal", "in", lambda m: [fx.Thermal(1.15e-5)], profile="swing"),
        Case(f, "eccentric-c-axis", "in", lambda m: [fx.Harmonic("6", 1, 2e-4)]),
        Case(f, "leg-thermal+screw-periodic-41", "in",
             lambda m: [fx.LegThermal(1.15e-5), fx.ScrewPeriodic("41", 0.02, 20.0)], profile="swing"),
        Case(f, "spindle-warm-up", "out", lambda m: [fx.SpindleGrowth(0.08, 2100.0)]),
        Case(f, "hose-drag-a-by-c", "out", lambda m: [fx.CrossJoint("7", "6", 3e-4, "sin")]),
        Case(f, "screw-self-heating", "out", lambda m: [fx.ScrewSelfHeat(7.0)]),
        Case(f, "loose-nest-smr2", "out", lambda m: [fx.LooseNest("SMR2", 0.08)], note="the nest's magnet has failed: the ball rests on the lower rim"),
    ]


def _hx_cases():
    f = "hexapod"
    return [
        Case(f, "none", "none"),
        Case(f, "understated-noise", "understated", noise_factor=UNDERSTATED_FACTOR),
        Case(f, "leg-thermal", "in", lambda m: [fx.LegThermal(1.15e-5)], profile="swing"),
        Case(f, "screw-periodic-35", "in", lambda m: [fx.ScrewPeriodic("35", 0.035, 5.0)]),
        Case(f, "joint-clearance", "in",
             lambda m: [fx.JointClearance({j: 0.05 for j in ("31", "32", "33", "34", "35", "36")})]),
        Case(f, "table-tilt", "in", lambda m: [fx.BaseTilt(5e-10, 7e-10)]),
        Case(f, "nut-backlash-34", "in", lambda m: [fx.Backlash(["34"], [0.05])]),
        Case(f, "compliance", "in", lambda m: [fx.Compliance([1e-4] * 6)]),
        Case(f, "thermal", "in", lambda m: [fx.Thermal(1.15e-5)], profile="swing"),
        Case(f, "tracker-drift", "in", lambda m: [fx.TrackerDrift(0.04)]),
        Case(f, "leg-thermal+screw-periodic-35", "in",
             lambda m: [fx.LegThermal(1.15e-5), fx.ScrewPeriodic("35", 0.035, 5.0)], profile="swing"),
        Case(f, "platform-bending", "out", lambda m: [fx.PlatformBend("PROBE", 1e-6)]),
        Case(f, "encoder-slip-32", "out", lambda m: [fx.SlipStep("32", 0.035)], note="the coupling of leg 32's motor slipped once"),
        Case(f, "screw-self-heating", "out", lambda m: [fx.ScrewSelfHeat(9.0)]),
        Case(f, "stand-creep", "out", lambda m: [fx.BaseCreep(8e-5)]),
    ]


def all_cases():
    return _kr_cases() + _lbr_cases() + _tx_cases() + _hx_cases()


# ---------------------------------------------------------------------- campaigns
def campaign_seed(family, case, seed):
    return zlib.crc32(f"blind3/{family}/{case}/{seed}".encode()) & 0x7FFFFFFF


def machine_seed(family, seed):
    return zlib.crc32(f"blind3-machine/{family}/{seed}".encode()) & 0x7FFFFFFF


@dataclass
class Campaign:
    family: str
    case: Case
    seed: int
    files: dict = field(default_factory=dict)
    truth: dict = field(default_factory=dict)


def generate(fam, case, seed, outdir):
    """Write one campaign's files into outdir; returns the Campaign."""
    os.makedirs(outdir, exist_ok=True)
    # one real machine (geometry, masses, tracker) and one pose design per family and seed:
    # every case of that seed is the same machine with another effect
    n = fam.n_id + fam.n_val
    cache = fam.__dict__.setdefault("_seed_cache", {})
    if seed not in cache:
        mrng = np.random.default_rng(machine_seed(fam.name, seed))
        machine = fam.draw_machine(mrng)
        q_all = fam.design(mrng, n, machine["tracker"])
        val_idx = set(mrng.choice(n, fam.n_val, replace=False).tolist())
        cache[seed] = (machine, q_all, val_idx)
    machine, q_all, val_idx = cache[seed]
    prior_rng = np.random.default_rng(machine_seed(fam.name, seed) + 1)
    # the case: effects, metadata profile, noise
    rng = np.random.default_rng(campaign_seed(fam.name, case.name, seed))
    meta = fam.metadata(rng, n, case.profile)
    dirs = fam.directions(q_all, meta["order"])
    effs = case.effects(fam)
    for e in effs:
        e.draw(fam, machine, rng)
    for e in effs:
        e.prepare(fam, machine, q_all, meta)
    pose_rngs = [np.random.default_rng(campaign_seed(fam.name, case.name, seed) * 1000 + k) for k in range(n)]
    noise_rng = np.random.default_rng(campaign_seed(fam.name, case.name, seed) + 7)
    loss_rng = np.random.default_rng(machine_seed(fam.name, seed) + 3)

    t_tr = machine["tracker"]
    obs_true, obs_noisy = [], []
    for k in range(n):
        pose = {"index": k, "time": meta["time"][k], "temperature": meta["temperature"][k],
                "payload": meta["payload"][k], "session": meta["session"][k], "dir": dirs[k],
                "rng": pose_rngs[k]}
        q = np.array(q_all[k], dtype=float)
        dq = np.zeros(len(q))
        for e in effs:
            d = e.joint_error(fam, machine, q, pose)
            if d is not None:
                dq += d
        qt = q + dq
        post = {}
        for e in effs:
            p = e.post(fam, machine, qt, pose)
            if p:
                for key, val in p.items():
                    if key in post:
                        raise ValueError("two effects deform the same link")
                    post[key] = val
        t_out = fam.output_pose(machine, qt, post=post or None, key=k)
        offs = {name: off.copy() for name, (off, _, _) in fam.targets.items()}
        roffs = {name: (r.copy() if r is not None else None) for name, (_, _, r) in fam.targets.items()}
        for e in effs:
            offs, roffs = e.offsets(fam, machine, qt, pose, t_out, offs, roffs)
        pts = {name: t_out[:3, :3] @ offs[name] + t_out[:3, 3] for name in fam.targets}
        rots = {name: (t_out[:3, :3] @ roffs[name] if roffs[name] is not None else None) for name in fam.targets}
        for e in effs:
            pts, rots = e.world(fam, machine, qt, pose, t_out, pts, rots)
        pts = {name: t_tr[:3, :3].T @ (v - t_tr[:3, 3]) for name, v in pts.items()}
        rots = {name: (t_tr[:3, :3].T @ r if r is not None else None) for name, r in rots.items()}
        for e in effs:
            pts, rots = e.tracker(fam, machine, pose, pts, rots)
        # target visibility: nests facing away from the tracker, and random beam breaks
        if len(fam.targets) > 1:
            t_nom = fam.output_pose(machine, q, key=k)
            vis = fam.visible(t_nom, t_tr[:3, 3]) if fam.kind == "serial" else [True] * len(fam.targets)
            vis = [v and loss_rng.uniform() > fam.loss_rate for v in vis]
            if not any(vis):
                vis[0] = True
        else:
            vis = [True]
        true_k, noisy_k = {}, {}
        for (name, p), v in zip(pts.items(), vis):
            if not v:
                true_k[name] = noisy_k[name] = None
                continue
            pn = fam.add_noise(noise_rng, p, case.noise_factor)
            r = rots[name]
            rn = None
            if r is not None:
                rn = geom.rotvec_to_matrix(noise_rng.normal(0, fam.orient_noise * case.noise_factor, 3)) @ r
            true_k[name] = (p, r)
            noisy_k[name] = (pn, rn)
        obs_true.append(true_k)
        obs_noisy.append(noisy_k)

    # files
    tracker_prior = np.concatenate([t_tr[:3, 3] + prior_rng.uniform(-40, 40, 3),
                                    geom.matrix_to_rotvec(t_tr[:3, :3]) + prior_rng.uniform(-0.01, 0.01, 3)])
    target_priors = {name: off + prior_rng.uniform(-3, 3, 3) for name, (off, _, _) in fam.targets.items()}
    order = sorted(range(n), key=lambda i: meta["time"][i])
    id_rows = [i for i in order if i not in val_idx]
    val_rows = [i for i in order if i in val_idx]
    files = {}
    for tag, obs in (("data", obs_noisy), ("nf", obs_true)):
        for part, rows in (("", id_rows), (".validation", val_rows)):
            path = os.path.join(outdir, f"{tag}{part}.csv")
            write_csv(path, fam, rows, q_all, meta, dirs, obs, tracker_prior, target_priors)
            files[f"{tag}{part}"] = path
    truth = {
        "family": fam.name, "kind": fam.kind, "case": case.name, "category": case.category, "seed": seed,
        "noise_factor": case.noise_factor, "profile": case.profile, "note": case.note,
        "effects": [e.describe() for e in effs],
        "truth": merge_truth([t for e in effs if e.kind == "in" for t in e.truth()]),
        "cover": sorted({c for e in effs for c in e.cover}),
        "noise": {"a_mm": fam.noise_a, "b_mm_per_m": fam.noise_b, "orientation_rad": fam.orient_noise,
                  "radial_ratio": fam.radial_ratio},
        "poses": {"identification": len(id_rows), "validation": len(val_rows)},
        "targets": list(fam.targets),
    }
    with open(os.path.join(outdir, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1, default=float)
    return Campaign(fam.name, case, seed, files, truth)


def merge_truth(items):
    """One truth per library effect (and order): the joints of several effects of one name
    (a bowed guide on each leg) are united."""
    out = []
    for t in items:
        for u in out:
            if u["effect"] == t["effect"] and u.get("order") == t.get("order"):
                u["joints"] = sorted(set(u["joints"]) | set(t["joints"]))
                break
        else:
            out.append({"effect": t["effect"], "joints": list(t["joints"]), "order": t.get("order")})
    return out


def _f(x, digits=9):
    return f"{x:.{digits}f}"


def write_csv(path, fam, rows, q_all, meta, dirs, obs, tracker_prior, target_priors):
    lu = fam.length_unit
    scale = 1000.0 if lu == "m" else 1.0
    lines = ["# hyperstat measurements, version 1", f"# mechanism: {fam.mech_name()}",
             f"# noise: {fam.noise_a:g} mm + {fam.noise_b:g} mm/m"]
    if fam.six_d:
        lines.append(f"# orientation noise: {fam.orient_noise * 1000:g} mrad")
    lines.append("# tracker: " + " ".join(f"{v:.6g}" for v in tracker_prior))
    names = list(fam.targets)
    multi = len(names) > 1
    for name in names:
        tag = f"target {name}" if multi else "target"
        lines.append(f"# {tag}: " + " ".join(f"{v:.4g}" for v in target_priors[name]))
    cols = ["pose"] + fam.controller_columns()
    for name in names:
        sfx = f"_{name}" if multi else ""
        cols += [f"x{sfx}[{lu}]", f"y{sfx}[{lu}]", f"z{sfx}[{lu}]"]
        if fam.six_d:
            if fam.kind == "serial":
                cols += [f"quat_w{sfx}", f"quat_x{sfx}", f"quat_y{sfx}", f"quat_z{sfx}"]
            else:
                cols += [f"rx{sfx}[deg]", f"ry{sfx}[deg]", f"rz{sfx}[deg]"]
    cols += ["time[s]", "temperature[degC]", "payload[kg]", "session"] + [f"dir{j}" for j in fam.actuated]
    lines.append(",".join(cols))
    for k, i in enumerate(rows, start=1):
        vals = [f"P{k}"] + [_f(v) for v in fam.controller_values(q_all[i])]
        for name in names:
            o = obs[i][name]
            if o is None:
                vals += [""] * (3 + (4 if fam.six_d and fam.kind == "serial" else 3 if fam.six_d else 0))
                continue
            p, r = o
            digits = 9 if lu == "m" else 6
            vals += [_f(x / scale, digits) for x in p]
            if fam.six_d:
                if fam.kind == "serial":
                    vals += [_f(x, 12) for x in geom.matrix_to_quaternion(r)]
                else:
                    vals += [_f(np.degrees(x), 9) for x in geom.matrix_to_rotvec(r)]
        vals += [f"{meta['time'][i]:.1f}", f"{meta['temperature'][i]:.3f}", f"{meta['payload'][i]:g}",
                 str(int(meta["session"][i]))] + [str(int(d)) for d in dirs[i]]
        lines.append(",".join(vals))
    with open(path + ".part", "w") as fh:
        fh.write("\n".join(lines) + "\n")
    os.replace(path + ".part", path)


def load_family(name, workdir, hyperstat, repo="."):
    os.makedirs(workdir, exist_ok=True)
    fam = FAMILIES[name]()
    if fam.kind == "parallel":
        fam.prepare(workdir, hyperstat, repo)
    else:
        fam.prepare(workdir, hyperstat)
    return fam
