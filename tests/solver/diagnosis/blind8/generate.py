"""Campaign generation of the tenth blind generator (``blind8``): families, pose designs, metadata,
tracker, targets, noise, CSV files, and the visibility line (own linearised rigid fit).

Units: mm, rad inside; the files state theirs (``q1[m]``, ``q6[deg]``, ``x[m]`` ...); degC, kg, s.

    python -m tests.solver.diagnosis.blind8.generate OUTDIR [--seed 0] [--cases a,b] [--no-visibility]
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

from .effects import apply
from .machine import HERE, Machine, rotvec_to_R, write_variant

MODELS = os.path.join(HERE, "models")

# Each family: base model file, its variants (name -> how to write it), the true masses used for the
# gravity loads (whatever the file declares), joint column units, position unit, noise (a mm + b mm/m),
# the share of each actuated range the poses use, payloads (kg).
FAMILIES = {
    "tx7": dict(base="tx7.skel.json", variants={"tx7": {}, "tx7_m": {"moving_mass": 70.0}},
                truth="tx7_m", units={"41": "mm", "42": "mm", "43": "mm", "6": "deg", "7": "deg"},
                pos="mm", noise=(0.006, 0.002), share=0.82, payloads=(0.0, 8.0, 20.0)),
    "hexa": dict(base="hexa.skel.json", variants={"hexa": {}, "hexa_m": {"moving_mass": 40.0}},
                 truth="hexa_m", units={}, pos="mm", noise=(0.003, 0.004), share=0.8,
                 payloads=(0.0, 10.0, 25.0)),
    "gantry": dict(base="gantry5_m.skel.json",
                   variants={"gantry_m": {"screw_lead": 20.0}, "gantry": {"screw_lead": 20.0, "drop_masses": True}},
                   truth="gantry_m", units={"1": "m", "2": "m", "3": "m", "4": "deg", "5": "deg"},
                   pos="m", noise=(0.005, 0.003), share=0.9, payloads=(0.0, 10.0, 25.0)),
    "desk": dict(base="desk6r.skel.json", variants={"desk": {}, "desk_m": {"desk_masses": True}},
                 truth="desk_m", units={}, pos="mm", noise=(0.010, 0.006), share=0.85,
                 payloads=(0.0, 0.5, 1.0)),
}
# The true machine's own geometry: every defect the model file lists drawn at random (1 sigma: axis
# tilts and turns 3e-4 rad, origin shifts 0.2 mm) on the serial arms and the hexapod (any defect
# assembles there); the Tripteor X7 is over-constrained: its defects are drawn (same scales) in the
# subspace that keeps its loops closed to first order at 7 of the campaign's poses (null space of the
# closure residual's derivative once the passive joints have taken their part); the second-order
# remainder leaves the loops open by up to a few 1e-5 mm (closed by least squares), far below the noise.
TRUE_DEFECTS = {"gantry": (3e-4, 0.2), "desk": (3e-4, 0.2), "hexa": (3e-4, 0.2), "tx7": (3e-4, 0.2)}
CLOSE_TOL = {"tx7": 5e-5}  # mm (closure residual accepted: 1/100 of the noise), else 1e-7
MAXIT = {"tx7": 8}  # Gauss-Newton iterations: the loops cannot close below the remainder, stop early
_nullcache = {}


def closable_basis(m, full, key, scales):
    """Basis (scaled defect coordinates) of the defects that keep the loops closed to first order at
    7 poses spread through the campaign."""
    if key not in _nullcache:
        defs, pas = list(m.kin.defect_list), list(m.kin.passive)
        rows = []
        for k in range(0, len(full), max(1, len(full) // 7)):
            _, _, dr, _ = m.kin.derivatives(full[k], pas + defs)
            A, B = dr[:, :len(pas)], dr[:, len(pas):]
            rows.append((np.eye(A.shape[0]) - A @ np.linalg.pinv(A)) @ B)
        S = np.vstack(rows) * scales[None, :]
        _, sv, vt = np.linalg.svd(S)
        rank = int((sv > 1e-8 * sv[0]).sum())
        _nullcache[key] = vt[rank:].T
    return _nullcache[key]
DESK_MASSES = {"1": 1.6, "2": 1.9, "3": 1.1, "4": 0.6, "5": 0.35, "6": 0.15}  # kg
LEAD = {"gantry": 20.0}  # mm, declared in the gantry's model file (metadata.screw_lead)

# Target layouts: name -> (list of (label, offset mm), six_d, orientation format)
TARGETS = {
    "plate3": ([("P1", (180.0, 0.0, 40.0)), ("P2", (-90.0, 156.0, 40.0)), ("P3", (-90.0, -156.0, 40.0))], False, None),
    "stylus6d": ([("T", (0.0, 30.0, 260.0))], True, "quat"),
    "smr1": ([("S", (25.0, -15.0, 45.0))], False, None),
    "far6d": ([("T", (60.0, -40.0, 420.0))], True, "rotvec_deg"),
    "wide2": ([("L", (220.0, 0.0, 30.0)), ("R", (-220.0, 0.0, 30.0))], False, None),
    "bar2": ([("A", (0.0, 90.0, 40.0)), ("B", (0.0, -90.0, 40.0))], False, None),
    "nose1": ([("N", (0.0, 0.0, 55.0))], False, None),
    "grip6d": ([("T", (15.0, 0.0, 45.0))], True, "rotvec_deg"),
    "tri3": ([("K1", (40.0, 0.0, 30.0)), ("K2", (-20.0, 35.0, 30.0)), ("K3", (-20.0, -35.0, 30.0))], False, None),
}
ROT_OFFSET = np.array([0.05, -0.03, 0.08])  # rad, the 6-D target's rotation in the output frame
ORIENT_NOISE = 0.03e-3  # rad (1 sigma per axis)
TIME_PER_POSE = 75.0  # s
VIS_LINE = 0.6

_machines = {}
_posecache = {}


def model_path(outdir, variant):
    return os.path.join(outdir, "models", variant + ".skel.json")


def make_models(outdir):
    """Write every family's model variants into OUTDIR/models (deterministic)."""
    os.makedirs(os.path.join(outdir, "models"), exist_ok=True)
    for fam, F in FAMILIES.items():
        src = os.path.join(MODELS, F["base"])
        for v, how in F["variants"].items():
            how = dict(how)
            masses = None
            if how.pop("desk_masses", False):
                masses = desk_masses(src)
            write_variant(src, model_path(outdir, v), masses=masses, **how)


def desk_masses(src):
    """The desk arm's link masses; each body's centre of mass at home midway between its joint's
    origin and the next joint's (the tool's for the last)."""
    m = Machine(src)
    T, jf = m.serial_frames({n: 0.0 for n in m.actuated})
    names = [e.name for e in m.elements if e.kind == "joint"]
    out = {}
    for i, j in enumerate(names):
        o = jf[j][:3, 3]
        nxt = jf[names[i + 1]][:3, 3] if i + 1 < len(names) else T[:3, 3]
        out[j] = {"mass": DESK_MASSES[j], "com": [float(x) for x in 0.5 * (o + nxt)]}
    return out


def machine(outdir, variant):
    key = (outdir, variant)
    if key not in _machines:
        _machines[key] = Machine(model_path(outdir, variant))
    return _machines[key]


# ---- pose designs ------------------------------------------------------------------------------------
def design_u(design, n, dim, rng):
    """Normalised actuated coordinates (n x dim) in [-1, 1], in the order they are measured."""
    if design == "sobol":
        import warnings
        from scipy.stats import qmc
        with warnings.catch_warnings():  # n is not a power of 2: the balance is not needed here
            warnings.simplefilter("ignore")
            s = qmc.Sobol(dim, scramble=True, seed=rng).random(n)
        return 2 * s - 1
    if design == "boundary":
        u = rng.uniform(-1, 1, (n, dim))
        for k in range(n):
            for j in rng.choice(dim, size=min(dim, 1 + (k % 2)), replace=False):
                u[k, j] = rng.choice([-1.0, 1.0]) * rng.uniform(0.95, 1.0)
        return _tour(u)
    if design == "spiral":
        t = np.linspace(0, 1, n)
        f = rng.uniform(1.7, 6.3, dim)
        ph = rng.uniform(0, 2 * np.pi, dim)
        r = 0.25 + 0.75 * t
        return np.clip(r[:, None] * np.cos(2 * np.pi * f[None, :] * t[:, None] + ph) +
                       rng.normal(0, 0.03, (n, dim)), -1, 1)
    if design == "levels":
        lv = np.array([-1.0, -0.5, 0.0, 0.5, 1.0])
        u = lv[rng.integers(0, 5, (n, dim))] + rng.normal(0, 0.02, (n, dim))
        order = np.lexsort(tuple(u[:, j] for j in range(dim - 1, -1, -1)))
        return np.clip(u[order], -1, 1)
    raise ValueError(design)


def _tour(u):
    """Greedy nearest-neighbour order (a realistic path through the poses)."""
    left = list(range(len(u)))
    order = [left.pop(0)]
    while left:
        d = [np.linalg.norm(u[i] - u[order[-1]]) for i in left]
        order.append(left.pop(int(np.argmin(d))))
    return u[order]


def poses(outdir, fam, variant, design, n, seed):
    """Commanded actuated values (list of dicts) of a design, parallel poses closed and inside every
    passive range; with the nominal full joint values (parallel) cached."""
    key = (fam, design, n, seed)
    if key in _posecache:
        return _posecache[key]
    F = FAMILIES[fam]
    m = machine(outdir, F["truth"])
    rng = np.random.default_rng([seed, n, sum(map(ord, design)), sum(map(ord, fam))])
    names = m.actuated
    out, full = [], []
    u = design_u(design, n, len(names), rng)
    for k in range(n):
        uk = u[k].copy()
        for _ in range(40):
            qa = {}
            for j, x in zip(names, uk):
                lo, hi = m.ranges[j]
                qa[j] = 0.5 * (lo + hi) + F["share"] * 0.5 * (hi - lo) * x
            if not m.parallel:
                out.append(qa)
                full.append(None)
                break
            q, r = m.kin.solve_path(qa)
            if r < 1e-8 and m.kin.passive_inside(q, 0.02):
                out.append(qa)
                full.append(q)
                break
            uk = 0.85 * uk + rng.normal(0, 0.05, len(uk))
        else:
            raise RuntimeError(f"{fam}/{design}: pose {k} does not assemble")
    _posecache[key] = (out, full)
    return out, full


# ---- metadata -------------------------------------------------------------------------------------------
def metadata(n, payloads, names, overshoot, qas, rng):
    """time[s], session (3), temperature[degC], payload[kg], dir<j> per pose."""
    b1, b2 = int(0.4 * n), int(0.7 * n)
    rows = []
    t_abs = 0.0
    pl = list(payloads)
    for k in range(n):
        if k == b1:
            t_abs += 6 * 3600.0
        if k == b2:
            t_abs += 18 * 3600.0
        t_abs += TIME_PER_POSE
        if k < b1:
            s, t = 1, k * TIME_PER_POSE
            T = 20.5 + 2.5 * (1 - np.exp(-t / 2400.0))
        elif k < b2:
            s, t = 2, (k - b1) * TIME_PER_POSE
            T = 23.2 - 1.8 * (1 - np.exp(-t / 3000.0)) + 0.2 * np.sin(2 * np.pi * t / 1800.0)
        else:
            s, t = 3, (k - b2) * TIME_PER_POSE
            T = 18.6 + 1.2 * t / max(1.0, (n - b2) * TIME_PER_POSE)
        T += rng.normal(0, 0.04)
        if k % 4 == 0:
            payload = pl[(k // 4) % len(pl)]
            if (k // 4) % len(pl) == len(pl) - 1:
                rng.shuffle(pl)
        d = {}
        for j in names:
            if overshoot:
                d[j] = float(rng.choice([-1.0, 1.0]))
            else:
                prev = qas[k - 1][j] if k else qas[k][j] - 1.0
                d[j] = 1.0 if qas[k][j] >= prev else -1.0
        rows.append(dict(time=t_abs, session=s, T=float(T), payload=float(payload), dir=d))
    return rows


# ---- one campaign -----------------------------------------------------------------------------------------
def campaign(outdir, case, seed, visibility=True):
    """Generate the case's files into OUTDIR/campaigns/<name>/; return its truth dict."""
    fam = case["family"]
    F = FAMILIES[fam]
    cdir = os.path.join(outdir, "campaigns", case["name"])
    os.makedirs(cdir, exist_ok=True)
    rng = np.random.default_rng([seed, sum(ord(c) * (i + 1) for i, c in enumerate(case["name"]))])
    m = machine(outdir, F["truth"])
    names = m.actuated
    n_id, n_val = case["poses"]
    n = n_id + n_val
    qas, full = poses(outdir, fam, F["truth"], case["design"], n, case.get("pose_seed", 0))
    meta = metadata(n, F["payloads"], names, case.get("overshoot", False), qas, rng)
    if case.get("select") == "random":
        val_idx = set(rng.choice(n, n_val, replace=False).tolist())
    else:  # systematic: evenly spaced through the time line
        val_idx = set(np.round(np.linspace(1, n - 2, n_val)).astype(int).tolist())
    # targets (jittered) and tracker
    layout, six_d, ofmt = TARGETS[case["targets"]]
    targets = [(lab, np.asarray(off) + rng.uniform(-2, 2, 3)) for lab, off in layout]
    nominal = [m.pose(qa, init=(m.passive_vector(f) if f else None))[0] for qa, f in zip(qas, full)]
    centre = np.mean([T[:3, 3] for T in nominal], axis=0)
    geo = None
    if fam in TRUE_DEFECTS:
        sr, sl = TRUE_DEFECTS[fam]
        if fam == "tx7":
            sc = np.array([sr if c in "IJKG" else sl for _, c in m.kin.defect_list])
            Nb = closable_basis(m, full, (fam, case["design"], n, case.get("pose_seed", 0)), sc)
            vals = sc * (Nb @ rng.normal(0, 1, Nb.shape[1]))
            geo = {d: float(v) for d, v in zip(m.kin.defect_list, vals)}
        else:
            geo = {d: float(rng.normal(0, sr if d[1] in "IJKG" else sl)) for d in m.kin.defect_list}
        base_rows = []  # the true machine without the effect
        for qa, f in zip(qas, full):
            Tb, _, r = m.pose(qa, init=(m.passive_vector(f) if f else None), defects=geo,
                              maxit=MAXIT.get(fam, 60))
            if r > CLOSE_TOL.get(fam, 1e-7):
                raise RuntimeError(f"{case['name']}: the true geometry does not close ({r})")
            base_rows.append(Tb)
    else:
        base_rows = nominal
    dist = rng.uniform(2500.0, 4000.0) * (1.3 if fam == "gantry" else 1.0)
    az = rng.uniform(0, 2 * np.pi)
    o_tr = centre + np.array([dist * np.cos(az), dist * np.sin(az), rng.uniform(-400, 400)])
    rv_tr = np.array([rng.normal(0, 0.015), rng.normal(0, 0.015), rng.uniform(-np.pi, np.pi)])
    R_tr = rotvec_to_R(rv_tr)
    a, b = F["noise"]
    factor = case.get("noise_factor", 1.0)
    # effect per pose
    rows_pts, rows_rot, sig, diffs = [], [], [], []
    eff, par = case.get("effect", "none"), case.get("params", {})
    for k in range(n):
        qa, md = qas[k], meta[k]
        ctx = dict(qa=qa, T=md["T"], payload=md["payload"], dir=md["dir"], session=md["session"],
                   ranges=m.ranges)
        needs_gravity = eff in ("compliance", "link-bending", "backlash-gravity", "joint-clearance",
                                "base-deformation", "ram-bending", "belt-load")
        if m.parallel:
            ctx["qfull"] = full[k]
            ctx["frames"] = m.kin.frames(full[k])[2]
        else:
            ctx["frames"] = m.serial_frames(qa)[1]
        if needs_gravity:
            ctx["tau"], ctx["M"] = m.gravity(qa, full[k], md["payload"])
        pert = apply(eff, par, ctx)
        q_true = dict(qa)
        for j, v in pert.dq.items():
            q_true[j] = q_true[j] + v
        if m.parallel:
            Tt, _, r = m.pose(q_true, init=m.passive_vector(full[k]), defects=geo, maxit=MAXIT.get(fam, 60))
            if r > CLOSE_TOL.get(fam, 1e-7):
                raise RuntimeError(f"{case['name']}: pose {k} did not close ({r})")
        else:
            Tt, _ = m.serial_frames(q_true, pert.post, geo)
        pts, rots, dd = [], [], []
        for lab, off in targets:
            p_true = (pert.E @ np.append(Tt[:3, :3] @ off + Tt[:3, 3], 1.0))[:3]
            p_nom = base_rows[k][:3, :3] @ off + base_rows[k][:3, 3]  # the same machine, no effect
            m_true = pert.meas_scale * (R_tr.T @ (p_true - o_tr)) + pert.meas_shift
            m_nom = R_tr.T @ (p_nom - o_tr)
            dd.append(R_tr @ (m_true - m_nom))
            pts.append(m_true)
            rots.append(R_tr.T @ pert.E_rot @ Tt[:3, :3] @ rotvec_to_R(ROT_OFFSET))
        s_k = [a + b * np.linalg.norm(p) / 1000.0 for p in pts]
        rows_pts.append(pts)
        rows_rot.append(rots)
        sig.append(s_k)
        diffs.append(dd)
    # noise
    meas = []
    for k in range(n):
        pk = [p + rng.normal(0, factor * s, 3) for p, s in zip(rows_pts[k], sig[k])]
        rk = [rotvec_to_R(rng.normal(0, factor * ORIENT_NOISE, 3)) @ R for R in rows_rot[k]] if six_d else None
        meas.append((pk, rk))
    truth = dict(case)
    truth["tracker"] = [float(x) for x in np.concatenate([o_tr, rv_tr])]
    truth["true_defects"] = None if geo is None else {f"{e}.{c}": v for (e, c), v in geo.items()}
    truth["targets_true"] = {lab: [float(x) for x in off] for lab, off in targets}
    cm = dict(case, mech=m.data["name"])
    write_csv(os.path.join(cdir, "data.csv"), cm, F, m.types, names, qas, meta, meas, targets, o_tr, rv_tr, rng,
              [k for k in range(n) if k not in val_idx], six_d, ofmt)
    write_csv(os.path.join(cdir, "val.csv"), cm, F, m.types, names, qas, meta, meas, targets, o_tr, rv_tr, rng,
              sorted(val_idx), six_d, ofmt)
    if visibility and eff != "none":
        truth["visibility"] = visibility_of(outdir, case, m, qas, full, targets, diffs, sig, val_idx,
                                             o_tr)
    else:
        truth["visibility"] = None
    truth["model"] = model_path(outdir, case["model"])
    with open(os.path.join(cdir, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    return truth


def _fmt_joint(j, v, unit, typ):
    if unit == "deg":
        return f"q{j}[deg]", np.degrees(v)
    if unit == "m":
        return f"q{j}[m]", v / 1000.0
    return (f"q{j}[rad]" if typ == "R" else f"q{j}[mm]"), v


def write_csv(path, case, F, types, names, qas, meta, meas, targets, o_tr, rv_tr, rng, idx, six_d, ofmt):
    m_unit = F["pos"]
    mech = case["mech"]
    scale = 1000.0 if m_unit == "m" else 1.0
    a, b = F["noise"]
    lines = ["# hyperstat measurements, version 1", f"# mechanism: {mech}",
             f"# noise: {a} mm + {b} mm/m"]
    if six_d:
        lines.append(f"# orientation noise: {ORIENT_NOISE * 1000:.3f} mrad")
    if m_unit == "mm":  # the tracker prior's unit is not stated for files in metres: left out there
        tr = np.concatenate([o_tr + rng.normal(0, 1.0, 3), rv_tr + rng.normal(0, 1e-3, 3)])
        lines.append("# tracker: " + " ".join(f"{x:.6f}" for x in tr))
    multi = len(targets) > 1
    for lab, off in targets:
        pr = off + rng.uniform(-1.5, 1.5, 3)
        lines.append((f"# target {lab}: " if multi else "# target: ") + " ".join(f"{x:.3f}" for x in pr))
    cols = ["pose"]
    for j in names:
        cols.append(_fmt_joint(j, 0.0, F["units"].get(j), types[j])[0])
    cols += ["time[s]", "session", "temperature[degC]", "payload[kg]"] + [f"dir{j}" for j in names]
    for lab, _ in targets:
        sfx = f"_{lab}" if multi else ""
        cols += [f"x{sfx}[{m_unit}]", f"y{sfx}[{m_unit}]", f"z{sfx}[{m_unit}]"]
        if six_d:
            cols += ([f"quat_w{sfx}", f"quat_x{sfx}", f"quat_y{sfx}", f"quat_z{sfx}"] if ofmt == "quat"
                     else [f"rx{sfx}[deg]", f"ry{sfx}[deg]", f"rz{sfx}[deg]"])
    lines.append(",".join(cols))
    from scipy.spatial.transform import Rotation
    for k in idx:
        md = meas[k]
        row = [f"P{k + 1}"]
        for j in names:
            row.append(repr(float(_fmt_joint(j, qas[k][j], F["units"].get(j), types[j])[1])))
        row += [f"{meta[k]['time']:.1f}", str(meta[k]["session"]), f"{meta[k]['T']:.3f}",
                f"{meta[k]['payload']:g}"] + [f"{int(meta[k]['dir'][j]):d}" for j in names]
        for t, p in enumerate(md[0]):
            row += [repr(float(x / scale)) for x in p]
            if six_d:
                R = md[1][t]
                if ofmt == "quat":
                    x, y, z, w = Rotation.from_matrix(R).as_quat()
                    row += [repr(float(v)) for v in (w, x, y, z)]
                else:
                    row += [repr(float(v)) for v in np.degrees(Rotation.from_matrix(R).as_rotvec())]
        lines.append(",".join(row))
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(tmp, path)


# ---- visibility: own linearised rigid fit ------------------------------------------------------------------
_jaccache = {}


def visibility_of(outdir, case, m, qas, full, targets, diffs, sig, val_idx, o_tr):
    """RMS of the held-out 3-D residual norms after a weighted ridge fit of the rigid model
    (defects of the model file, tracker frame, target offsets) on the identification poses, over the
    RMS of the stated noise's 3-D norms (sqrt(3) sigma).  Positions only."""
    defects = list(m.kin.defect_list)
    key = (case["family"], case["design"], len(qas), case.get("pose_seed", 0))
    if key not in _jaccache:
        jac = []
        for k, qa in enumerate(qas):
            q = full[k] if m.parallel else qa
            To, dTo = m.output_jacobian(q, defects)
            jac.append((To, dTo[len(m.actuated):]))
        _jaccache[key] = jac
    jac = _jaccache[key]
    nd, nt = len(defects), len(targets)
    prior = [1e-3 if c in "IJKG" else 0.5 for _, c in defects] + [20.0] * 3 + [0.02] * 3 + [5.0] * (3 * nt)
    P = np.diag(1.0 / np.asarray(prior) ** 2)

    def rows(k):
        To, dTo = jac[k]
        out = []
        for t, (lab, off) in enumerate(targets):
            p = To[:3, :3] @ off + To[:3, 3]
            J = np.zeros((3, nd + 6 + 3 * nt))
            for i, D in enumerate(dTo):
                J[:, i] = D[:3, :3] @ off + D[:3, 3]
            J[:, nd:nd + 3] = np.eye(3)
            J[:, nd + 3:nd + 6] = -np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
            J[:, nd + 6 + 3 * t:nd + 9 + 3 * t] = To[:3, :3]
            out.append((J, diffs[k][t], sig[k][t]))
        return out

    A = np.zeros((P.shape[0], P.shape[0]))
    g = np.zeros(P.shape[0])
    for k in range(len(qas)):
        if k in val_idx:
            continue
        for J, d, s in rows(k):
            A += J.T @ J / s ** 2
            g += J.T @ d / s ** 2
    x = np.linalg.solve(A + P, g)
    r2, s2 = [], []
    for k in sorted(val_idx):
        for J, d, s in rows(k):
            r2.append(np.sum((d - J @ x) ** 2))
            s2.append(3 * s ** 2)
    return float(np.sqrt(np.mean(r2) / np.mean(s2)))


def generate(outdir, seed=0, names=None, visibility=True, log=sys.stdout):
    from .cases import CASES
    make_models(outdir)
    out = []
    for c in CASES:
        if names and c["name"] not in names:
            continue
        t = campaign(outdir, c, seed, visibility)
        if log:
            v = t["visibility"]
            print(f"{c['name']:24s} {c['kind']:5s} {c.get('effect', '-'):20s} vis "
                  f"{'-' if v is None else f'{v:.3f}'}", file=log, flush=True)
        out.append(t)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("outdir")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cases", default=None)
    ap.add_argument("--no-visibility", action="store_true")
    a = ap.parse_args(argv)
    generate(a.outdir, a.seed, a.cases.split(",") if a.cases else None, not a.no_visibility)


if __name__ == "__main__":
    main()
