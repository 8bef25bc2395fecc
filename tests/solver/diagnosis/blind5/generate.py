"""Campaign writer of the seventh blind generator: poses, metadata, tracker, targets, noise.

Units: mm, rad, degC, s.  Writes the measurement files of docs/identification.md ("Measurement
file") for a case of ``cases.py``, with its own kinematics (``kin.py``) and effects
(``effects.py``), and computes the case's visibility: the held-out RMS (3-D norms) that this
generator's own *linearised rigid fit* (admissible geometry defects, tracker frame, target offsets)
leaves of the noise-free effect, over the RMS of the stated noise (3-D).

    python -m tests.solver.diagnosis.blind5.generate OUTDIR [--seed 0] [--only CASE]
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

from . import effects as fx
from .kin import Model, log_rot, rot_vec

HERE = Path(__file__).resolve().parent
MODELS = HERE / "models"

#: family -> model file, output targets (tool/platform frame, mm) per layout, tracker distance (mm)
FAMILIES = {
    "tripteor_x7": {"model": "tripteor_x7.skel.json", "parallel": True, "tracker_r": 2600.0,
                    "centre": (0.0, 0.0, -900.0)},
    "hexapod": {"model": "hexapod.skel.json", "parallel": True, "tracker_r": 2400.0,
                "centre": (0.0, 0.0, 700.0)},
    "puma_like": {"model": "puma_like.skel.json", "parallel": False, "tracker_r": 2800.0,
                  "centre": (300.0, 0.0, 700.0)},
    "scara_like": {"model": "scara_like.skel.json", "parallel": False, "tracker_r": 2200.0,
                   "centre": (300.0, 0.0, 300.0)},
}

LAYOUTS = {
    "tripteor_x7": {"smr2": [(45.0, -10.0, -30.0), (-35.0, 40.0, 10.0)],
                    "smr3": [(50.0, 0.0, -25.0), (-30.0, 45.0, -5.0), (-20.0, -45.0, 30.0)],
                    "6d": [(15.0, -10.0, -30.0)]},
    "hexapod": {"smr2": [(170.0, 20.0, 25.0), (-90.0, 140.0, 25.0)],
                "smr3": [(180.0, 0.0, 25.0), (-90.0, 150.0, 25.0), (-90.0, -150.0, 25.0)],
                "6d": [(60.0, -40.0, 30.0)]},
    "puma_like": {"smr1": [(40.0, 25.0, 60.0)],
                  "smr3": [(70.0, 0.0, 40.0), (-35.0, 60.0, 40.0), (-35.0, -60.0, 40.0)],
                  "6d": [(20.0, -15.0, 50.0)]},
    "scara_like": {"smr2": [(90.0, 0.0, -20.0), (-50.0, 70.0, -20.0)],
                   "smr3": [(90.0, 0.0, -20.0), (-50.0, 70.0, -20.0), (-40.0, -80.0, -10.0)]},
}


def model_of(family):
    return Model(MODELS / FAMILIES[family]["model"])


def _actuated_box(model, parallel):
    box = {}
    for j in model.actuated:
        lo, hi = model.ranges[j]
        if model.kinds[j] == "P" and parallel:
            m, h = (lo + hi) / 2, (hi - lo) / 2
            lo, hi = m - 0.8 * h, m + 0.8 * h
        else:
            m, h = (lo + hi) / 2, (hi - lo) / 2
            lo, hi = m - 0.95 * h, m + 0.95 * h
        box[j] = (lo, hi)
    return box


def sample_poses(model, design, n, rng, parallel):
    """n assembled poses (qa dicts, nominal passive values) of a pose design."""
    box = _actuated_box(model, parallel)
    names = model.actuated
    out = []
    batch = []
    tries = 0
    while len(out) < n:
        tries += 1
        if tries > 50 * n:
            raise RuntimeError("cannot sample %d assembled poses of %s" % (n, model.name))
        if design == "lhs":
            # one Latin-hypercube batch, used in order
            if not batch:
                u = (np.argsort(rng.random((len(names), n)), axis=1).T + rng.random((n, len(names)))) / n
                batch = list(u)
            u = batch.pop()
        elif design == "edges":
            u = rng.random(len(names))
            outer = rng.random(len(names)) < 0.5
            u = np.where(outer, np.where(rng.random(len(names)) < 0.5, 0.06 * u, 1 - 0.06 * u), u)
        elif design == "clusters":
            k = len(out) % 5
            c = np.random.default_rng(1000 + k + 7 * len(names)).random(len(names))
            u = np.clip(c + rng.normal(0, 0.18, len(names)), 0, 1)
        else:
            raise ValueError(design)
        qa = {j: box[j][0] + float(ui) * (box[j][1] - box[j][0]) for j, ui in zip(names, u)}
        qp, fr, res = model.solve(qa)
        if res > 1e-8 or not model.in_range(qp, 0.02):
            continue
        out.append((qa, qp))
    return out


def noise_sigma(noise, m):
    """1-sigma per axis, mm, of the model 'a mm + b mm/m' at the point m (tracker frame, mm)."""
    return noise[0] + noise[1] * np.linalg.norm(m) / 1000.0


def _metadata(rng, n_all, model):
    """Time (s), temperature (degC), session, approach directions of each pose, in measuring order."""
    t = np.arange(n_all) * 75.0 + rng.uniform(0, 20, n_all)
    span = t[-1] + 1.0
    temp = 20.0 + 3.5 * np.sin(2 * np.pi * 1.6 * t / span + rng.uniform(0, 6.3)) + 2.5 * t / span \
        + rng.normal(0, 0.15, n_all)
    session = np.where(t < span / 2, 1, 2)
    dirs = {j: rng.choice([-1, 1], n_all) for j in model.actuated}
    return t, temp, session, dirs


def campaign(case, seed=0):
    """Build a case's campaign: rows of the identification and validation files and the truth."""
    fam = FAMILIES[case["family"]]
    model = model_of(case["family"])
    rng = np.random.default_rng(seed * 100003 + case["seed"])
    n_id, n_val = case["poses"]
    poses = sample_poses(model, case["design"], n_id + n_val, rng, fam["parallel"])
    order = rng.permutation(n_id + n_val)
    t, temp, session, dirs = _metadata(rng, n_id + n_val, model)
    is_val = np.zeros(n_id + n_val, bool)
    is_val[rng.choice(n_id + n_val, n_val, replace=False)] = True
    # tracker: on a circle around the machine, turned about the vertical (header: the same pose)
    az = rng.uniform(-np.pi, np.pi)
    c = np.asarray(fam["centre"])
    t_tr = c + np.array([fam["tracker_r"] * np.cos(az), fam["tracker_r"] * np.sin(az), rng.uniform(-300, 200)])
    t_tr = np.round(t_tr, 1)
    rz = round(float(rng.uniform(-np.pi, np.pi)), 4)
    r_tr = rot_vec([0.0, 0.0, rz])
    targets = [np.asarray(p) + rng.uniform(-3, 3, 3) for p in LAYOUTS[case["family"]][case["targets"]]]
    targets = [np.round(p, 2) for p in targets]
    sixd = case["targets"] == "6d"
    r_off = rot_vec(rng.normal(0, 0.2, 3)) if sixd else np.eye(3)
    effect = fx.make(case.get("effect"))
    noise = tuple(case["noise"])
    applied = noise[0] * case.get("understate", 1.0), noise[1] * case.get("understate", 1.0)
    rot_noise = case.get("rot_noise", 3e-5)

    rows = []  # per pose: dict
    for i_slot, (qa, qp0) in enumerate(poses):
        i = int(order[i_slot])  # measuring order
        ctx = {"qa": qa, "T": float(temp[i]), "t": float(t[i]), "session": int(session[i]),
               "dir": {j: int(dirs[j][i]) for j in model.actuated}, "model": model}
        if effect is not None:
            dq = effect.dq(ctx)
            qt = {j: qa[j] + dq.get(j, 0.0) for j in qa}
            ex = effect.extra(ctx) or None
        else:
            qt, ex = qa, None
        qp, fr, res = model.solve(qt, qp0=qp0, extra=ex)
        if res > 1e-8:
            raise RuntimeError("true machine does not assemble at a pose (%g)" % res)
        tout = fr[model.output]
        meas, clean, nominal, rots = [], [], [], []
        fr0 = model.frames(qa, qp0)[0]
        for k, o in enumerate(targets):
            p = tout[:3, :3] @ o + tout[:3, 3]
            if effect is not None:
                p = effect.base_point(ctx, p, k, fr)
            m = r_tr.T @ (p - t_tr)
            if effect is not None:
                m = effect.tracker_point(ctx, m)
            p0 = fr0[model.output][:3, :3] @ o + fr0[model.output][:3, 3]
            nominal.append(r_tr.T @ (p0 - t_tr))
            clean.append(m)
            sig = noise_sigma(applied, m)
            meas.append(m + rng.normal(0, sig, 3))
        if sixd:
            rm = r_tr.T @ tout[:3, :3] @ r_off
            rm = rot_vec(rng.normal(0, rot_noise * case.get("understate", 1.0), 3)) @ rm
            rots.append(log_rot(rm))
        rows.append({"qa": qa, "qp": qp0, "val": bool(is_val[i]), "t": float(t[i]), "T": float(temp[i]),
                     "session": int(session[i]), "dir": ctx["dir"], "meas": meas, "clean": clean,
                     "nominal": nominal, "rot": rots, "order": i})
    rows.sort(key=lambda r: r["order"])
    return {"case": case, "model": model, "rows": rows, "tracker": (t_tr, rz), "targets": targets,
            "sixd": sixd, "stated_noise": noise, "applied_noise": applied, "rot_noise": rot_noise,
            "effect": effect}


def _fmt(v):
    return repr(float(v))


def write_files(camp, outdir):
    """Write DATA.csv and VAL.csv of a campaign; returns their paths."""
    case, model = camp["case"], camp["model"]
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    names = ["SMR%d" % (k + 1) for k in range(len(camp["targets"]))]
    multi = len(names) > 1
    head = ["# hyperstat measurements, version 1", "# mechanism: %s" % model.name,
            "# noise: %g mm + %g mm/m" % camp["stated_noise"]]
    if camp["sixd"]:
        head.append("# orientation noise: %g mrad" % (camp["rot_noise"] * 1000.0))
    t_tr, rz = camp["tracker"]
    head.append("# tracker: %g %g %g 0 0 %g" % (t_tr[0], t_tr[1], t_tr[2], rz))
    for n, o in zip(names, camp["targets"]):
        head.append(("# target %s: %g %g %g" % (n, *o)) if multi else ("# target: %g %g %g" % tuple(o)))
    cols = ["pose"] + ["q%s[%s]" % (j, "rad" if model.kinds[j] == "R" else "mm") for j in model.actuated]
    cols += ["temperature[degC]", "time[s]", "session"] + ["dir%s" % j for j in model.actuated]
    for n in names:
        cols += (["x_%s[mm]" % n, "y_%s[mm]" % n, "z_%s[mm]" % n] if multi else ["x[mm]", "y[mm]", "z[mm]"])
    if camp["sixd"]:
        cols += ["rx[rad]", "ry[rad]", "rz[rad]"]
    paths = {}
    for part, val in (("data", False), ("val", True)):
        lines = list(head) + [",".join(cols)]
        k = 0
        for r in camp["rows"]:
            if r["val"] != val:
                continue
            k += 1
            v = ["%s%d" % ("V" if val else "P", k)] + [_fmt(r["qa"][j]) for j in model.actuated]
            v += ["%.3f" % r["T"], "%.1f" % r["t"], str(r["session"])] + [str(r["dir"][j]) for j in model.actuated]
            for m in r["meas"]:
                v += [_fmt(x) for x in m]
            for rv in r["rot"]:
                v += [_fmt(x) for x in rv]
            lines.append(",".join(v))
        p = outdir / ("%s.csv" % part)
        tmp = p.with_suffix(".tmp")
        tmp.write_text("\n".join(lines) + "\n")
        os.replace(tmp, p)
        paths[part] = p
    return paths


# ----------------------------------------------------------------------------- visibility
def rigid_columns(camp, rows, null_space):
    """Linearised rigid model's columns (tracker frame, targets, admissible geometry) at rows."""
    model = camp["model"]
    t_tr, rz = camp["tracker"]
    r_tr = rot_vec([0, 0, rz])
    nt = len(camp["targets"])
    blocks = []
    for r in rows:
        pth, pq, cth, cq = model.geometry_jacobian(r["qa"], r["qp"], camp["targets"])
        g = pth - pq @ np.linalg.pinv(cq) @ cth if cq.size else pth
        g = g @ null_space
        fr = model.frames(r["qa"], r["qp"])[0]
        rout = fr[model.output][:3, :3]
        for k in range(nt):
            m = r["nominal"][k]
            cols = []
            for e in np.eye(3):
                cols.append(-np.cross(e, m))
            for e in np.eye(3):
                cols.append(-r_tr.T @ e)
            tg = np.zeros((3, 3 * nt))
            tg[:, 3 * k:3 * k + 3] = r_tr.T @ rout
            blocks.append(np.hstack([np.column_stack(cols), tg, r_tr.T @ g[3 * k:3 * k + 3]]))
    return np.vstack(blocks)


def admissible_null_space(camp, k=10):
    """Element-defect directions that keep every loop closed (to first order) at k poses."""
    model = camp["model"]
    ne = 6 * len(model.elements)
    if not model.passive:
        return np.eye(ne)
    stack = []
    for r in camp["rows"][:k]:
        _, _, cth, cq = model.geometry_jacobian(r["qa"], r["qp"], camp["targets"][:1])
        proj = np.eye(cq.shape[0]) - cq @ np.linalg.pinv(cq)
        stack.append(proj @ cth)
    a = np.vstack(stack)
    u, s, vt = np.linalg.svd(a, full_matrices=True)
    tol = 1e-4 * s[0]
    rank = int(np.sum(s > tol))
    return vt[rank:].T


#: prior scales of the rigid fit's parameters (a ridge that keeps the linearised fit physical: without
#: it, near-degenerate combinations with coefficients of 1e5 absorb anything on a serial arm)
PRIOR_ROT, PRIOR_LEN = 2e-3, 1.0  # rad, mm (geometry); the tracker and targets: 2e-2 rad, 10 mm


def rigid_fit(camp, rows_fit, e_fit, rows_pred):
    """This generator's linearised rigid fit: weighted (stated noise) least squares with a ridge of
    the prior scales; returns the prediction at rows_pred (mm, stacked x, y, z per point)."""
    ns = admissible_null_space(camp)
    a_fit = rigid_columns(camp, rows_fit, ns)
    a_pred = rigid_columns(camp, rows_pred, ns)
    w = np.concatenate([np.repeat([1.0 / noise_sigma(camp["stated_noise"], m) for m in r["nominal"]], 3)
                        for r in rows_fit])
    nt = len(camp["targets"])
    ne = ns.shape[0] // 6
    d_inv = np.tile(np.r_[[1.0 / PRIOR_ROT] * 3, [1.0 / PRIOR_LEN] * 3], ne)
    pen = np.zeros((6 + 3 * nt + ns.shape[0], a_fit.shape[1]))
    pen[:3, :3] = np.eye(3) / 2e-2
    pen[3:6, 3:6] = np.eye(3) / 10.0
    pen[6:6 + 3 * nt, 6:6 + 3 * nt] = np.eye(3 * nt) / 10.0
    pen[6 + 3 * nt:, 6 + 3 * nt:] = d_inv[:, None] * ns
    lhs = np.vstack([a_fit * w[:, None], pen])
    rhs = np.r_[e_fit * w, np.zeros(pen.shape[0])]
    coef = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    return a_fit @ coef, a_pred @ coef, w


def visibility(camp):
    """Noise-free effect's held-out 3-D RMS after this generator's rigid fit / stated noise 3-D RMS.

    Returns (visibility, held-out RMS mm, noise RMS mm)."""
    rows = camp["rows"]
    rid = [r for r in rows if not r["val"]]
    rval = [r for r in rows if r["val"]]
    e_id = np.concatenate([np.concatenate([c - m for c, m in zip(r["clean"], r["nominal"])]) for r in rid])
    e_val = np.concatenate([np.concatenate([c - m for c, m in zip(r["clean"], r["nominal"])]) for r in rval])
    _, pred, _ = rigid_fit(camp, rid, e_id, rval)
    res = (e_val - pred).reshape(-1, 3)
    held = float(np.sqrt(np.mean(np.sum(res ** 2, axis=1))))
    sig = np.array([noise_sigma(camp["stated_noise"], m) for r in rval for m in r["nominal"]])
    noise_rms = float(np.sqrt(np.mean(3 * sig ** 2)))
    return held / noise_rms, held, noise_rms


def write_campaign(case, outdir, seed=0, with_visibility=True):
    camp = campaign(case, seed)
    paths = write_files(camp, outdir)
    vis = visibility(camp) if (with_visibility and camp["effect"] is not None) else (0.0, 0.0, 0.0)
    truth = {"case": case["id"], "family": case["family"], "kind": case["kind"],
             "effect": case.get("effect"), "truth": case.get("truth"), "joints": case.get("joints"),
             "understate": case.get("understate", 1.0), "visibility": vis[0],
             "heldout_rms_mm": vis[1], "noise_rms_mm": vis[2], "seed": seed}
    (Path(outdir) / "truth.json").write_text(json.dumps(truth, indent=1, default=float))
    return paths, truth


def main(argv=None):
    from .cases import CASES
    ap = argparse.ArgumentParser()
    ap.add_argument("outdir")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", default=None)
    a = ap.parse_args(argv)
    for case in CASES:
        if a.only and case["id"] != a.only:
            continue
        _, tr = write_campaign(case, Path(a.outdir) / case["id"], a.seed)
        print("%-28s %-12s %-8s vis %.2f (held-out %.4f mm, noise %.4f mm)"
              % (case["id"], case["family"], case["kind"], tr["visibility"], tr["heldout_rms_mm"],
                 tr["noise_rms_mm"]))


if __name__ == "__main__":
    main()
