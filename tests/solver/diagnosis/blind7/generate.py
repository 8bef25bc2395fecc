"""Campaign generation of the ninth blind generator (directory ``blind7``): families, pose
designs, metadata, tracker, targets, noise, CSV files and the visibility fit.  numpy only.

Units: mm, rad, °C, s, kg inside; the files state theirs.
``python -m tests.solver.diagnosis.blind7.generate OUTDIR [--seed 0] [--jobs 2] [--cases a,b]``
"""
from __future__ import annotations

import argparse
import json
import os
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from . import effects as fx
from .cases import CASES
from .kin import Model, R_to_rotvec, rotvec_to_R

HERE = os.path.dirname(os.path.abspath(__file__))
MODELS = os.path.join(HERE, "models")
VIS_LINE = 0.6

# family: model stem, joint column units, position unit, noise (mm, mm/m), poses id/val,
# share of each actuated range used, payload levels (kg), tool length along output z (mm)
FAMILIES = {
    "tx7": dict(model="tx7", junit={"41": "mm", "42": "mm", "43": "mm", "6": "rad", "7": "rad"},
                punit="mm", noise=(0.004, 0.003), n=(40, 16), share=0.8, payload=(0, 6, 15),
                pkm=True, mech="tripteor_x7"),
    "hexa": dict(model="hexa", junit={j: "mm" for j in ("31", "32", "33", "34", "35", "36")},
                 punit="mm", noise=(0.004, 0.003), n=(30, 12), share=0.85, payload=(0, 12, 30),
                 pkm=True, mech="hexapod"),
    "puma": dict(model="puma", junit={str(j): "deg" for j in range(1, 7)}, punit="mm",
                 noise=(0.010, 0.004), n=(40, 16), share=0.8, payload=(0, 2.5, 5), pkm=False,
                 mech="puma560_like"),
    "denso": dict(model="denso", junit={str(j): "deg" for j in range(1, 7)}, punit="m",
                  noise=(0.008, 0.004), n=(40, 16), share=0.8, payload=(0, 2, 4), pkm=False,
                  mech="denso_like"),
    "scara": dict(model="scara", junit={"1": "rad", "2": "rad", "3": "mm", "4": "rad"}, punit="mm",
                  noise=(0.006, 0.003), n=(40, 16), share=0.85, payload=(0, 1.5, 3), pkm=False,
                  mech="scara"),
}

# target layouts: offsets in the output frame (mm); "6d" marks one target with orientation
TARGETS = {
    "smr1": [[15.0, -10.0, 30.0]],
    "smr2long": [[20.0, 12.0, 35.0], [-18.0, 25.0, 290.0]],  # two reflectors on a long tool
    "smr3": [[70.0, -15.0, 40.0], [-45.0, 60.0, 55.0], [-20.0, -70.0, 90.0]],
    "6d": [[10.0, 20.0, 60.0]],
    "6dtcp": [[80.0, -55.0, 170.0]],  # 6-D target at an offset TCP
}
ROT_OFFSET = np.array([0.15, -0.2, 0.3])
ORIENT_NOISE = 2.5e-5  # rad, 1 sigma per axis


_MODEL_CACHE = {}


def rotvec_to_R4(v):
    T = np.eye(4)
    T[:3, :3] = rotvec_to_R(v)
    return T


def model(stem):
    if stem not in _MODEL_CACHE:
        _MODEL_CACHE[stem] = Model(os.path.join(MODELS, stem + ".skel.json"))
    return _MODEL_CACHE[stem]


# --- pose designs (normalised u in [-1, 1] per actuated joint) -------------------------------

def design_stream(design, n, rng):
    if design == "lhs":  # Latin hypercube blocks of 16
        while True:
            B = 16
            cols = [(rng.permutation(B) + rng.random(B)) / B * 2 - 1 for _ in range(n)]
            for i in range(B):
                yield np.array([c[i] for c in cols])
    elif design == "clusters":  # a tour through 5 regions, Gaussian around each centre
        centres = rng.uniform(-0.7, 0.7, (5, n))
        while True:
            for c in centres:
                for _ in range(10):
                    yield np.clip(c + rng.normal(0, 0.28, n), -1, 1)
    elif design == "lissajous":  # a slow path, incommensurate frequencies per joint
        f = 0.037 * (1 + np.arange(n) * 0.618) + rng.uniform(0, 0.01, n)
        ph = rng.uniform(0, 2 * np.pi, n)
        k = 0
        while True:
            yield np.clip(np.sin(2 * np.pi * f * k + ph) * 0.97 + rng.normal(0, 0.05, n), -1, 1)
            k += 1
    elif design == "tilts":  # hexapod: legs out of phase around the platform -> large tilts
        ang = np.arange(n) * 2 * np.pi / n
        while True:
            psi = rng.uniform(0, 2 * np.pi)
            A = rng.uniform(0.4, 0.95)
            yield np.clip(A * np.cos(ang - psi) + rng.uniform(-0.3, 0.3) + rng.normal(0, 0.08, n), -1, 1)
    else:
        raise ValueError(design)


def draw_poses(M, fam, design, N, rng):
    share = fam["share"]
    mids = {j: 0.5 * sum(M.joints[j].range) for j in M.actuated}
    half = {j: 0.5 * (M.joints[j].range[1] - M.joints[j].range[0]) * share for j in M.actuated}
    poses = []
    tries = 0
    for u in design_stream(design, len(M.actuated), rng):
        tries += 1
        if tries > 40 * N:
            raise RuntimeError("pose design yields too few assemblable poses")
        qa = {j: mids[j] + half[j] * u[i] for i, j in enumerate(M.actuated)}
        if fam["pkm"]:
            q, r = M.solve_path(qa)
            if r > 1e-8 or not M.passive_inside(q, 0.02):
                continue
        else:
            q = dict(qa)
        poses.append(q)
        if len(poses) == N:
            return poses


# --- metadata ---------------------------------------------------------------------------------

def metadata(M, fam, poses, rng):
    N = len(poses)
    dt = 90.0
    half = N // 2
    meta = []
    heat = {j: 0.0 for j in M.actuated}
    last = {j: poses[0][j] - rng.choice([-1, 1]) * 1e-3 for j in M.actuated}
    levels = fam["payload"]
    pay = levels[0]
    for k, q in enumerate(poses):
        s = 1 if k < half else 2
        kk = k if s == 1 else k - half
        t = kk * dt
        if s == 1:
            T = 19.0 + 4.0 * (1 - np.exp(-t / 3000.0)) + 0.3 * np.sin(2 * np.pi * t / 2100.0)
        else:
            T = 23.5 - 3.0 * (1 - np.exp(-t / 2500.0)) + 0.25 * np.sin(2 * np.pi * t / 1500.0)
        T += rng.normal(0, 0.05)
        if k % 6 == 0:
            pay = levels[(k // 6) % len(levels)]
        d = {}
        move = {}
        for j in M.actuated:
            mv = q[j] - last[j]
            d[j] = 1 if mv >= 0 else -1
            move[j] = abs(mv)
            heat[j] = heat[j] * np.exp(-dt / 1800.0) + abs(mv)
            last[j] = q[j]
        meta.append(dict(k=k, session=s, time=(0 if s == 1 else 86400.0) + t, t_op=k * dt, T=float(T),
                         payload=float(pay), dir=d, hist={"heat": dict(heat), "move": move}))
    return meta


# --- gravity ------------------------------------------------------------------------------------

def gravity_funcs(M, q, payload):
    """Generalized gravity forces (-dV/dq, N mm or N) and the base moment (N mm) at pose q."""
    md = M.data["metadata"]
    masses = md.get("masses")
    moving = md.get("moving_mass")
    home = {n: (M.joints[n].home if M.joints[n].home is not None else 0.0) for n in M.joints}
    if masses:
        _, _, jf_home = M.frames(home)

    def bodies(qq):
        F, _, jf = M.frames(qq)
        out = []
        To = F[M.output]
        if masses:
            for j, b in masses.items():
                c = np.append(np.asarray(b["com"], float), 1.0)
                cq = jf[j] @ np.linalg.solve(jf_home[j], c)
                out.append((b["mass"], cq[:3]))
        if moving:
            c = np.append(np.asarray(md.get("com", [0, 0, 0]), float), 1.0)
            out.append((moving, (To @ c)[:3]))
        out.append((payload, To[:3, 3]))
        return out

    def V(qq):
        return sum(m * fx.G * c[2] for m, c in bodies(qq))

    def grav():
        tau = {}
        init = np.array([q[n] for n in M.passive])
        for j in M.actuated:
            h = 1e-5 if M.joints[j].type == "R" else 1e-3
            vals = []
            for s in (1, -1):
                qa = {a: q[a] for a in M.actuated}
                qa[j] += s * h
                qq = M.solve(qa, init=init)[0] if M.closing else dict(qa)
                vals.append(V(qq))
            tau[j] = -(vals[0] - vals[1]) / (2 * h)
        return tau

    def moment():
        Mo = np.zeros(3)
        for m, c in bodies(q):
            Mo += np.cross(c, np.array([0, 0, -m * fx.G]))
        return Mo
    return grav, moment


# --- one campaign ---------------------------------------------------------------------------

def tracker_pose(M, poses, rng):
    P = np.array([M.output_pose(q)[:3, 3] for q in poses])
    c = P.mean(0)
    ang = rng.uniform(0, 2 * np.pi)
    dist = rng.uniform(2200, 3400)
    o = c + np.array([dist * np.cos(ang), dist * np.sin(ang), rng.uniform(-300, 300)])
    rv = np.array([rng.normal(0, 0.02), rng.normal(0, 0.02), rng.uniform(-np.pi, np.pi)])
    return o, rotvec_to_R(rv), rv


def measure(M, case, q, meta, ctx_extra, offsets, rot_off, six_d, with_effect=True):
    """Noise-free measurement of one pose: list of tracker-frame points, and orientations."""
    eff = None
    ctx = dict(q={j: q[j] for j in M.actuated}, T=meta["T"], payload=meta["payload"], dir=meta["dir"],
               t_op=meta["t_op"], session=meta["session"], k=meta["k"], hist=meta["hist"], **ctx_extra)
    if with_effect and case.get("effect"):
        eff = fx.EFFECTS[case["effect"]](ctx, case["params"])
    qq = dict(q)
    if eff is not None and eff.dq:
        qa = {j: q[j] + eff.dq.get(j, 0.0) for j in M.actuated}
        if M.closing:
            qq, r = M.solve(qa, init=np.array([q[n] for n in M.passive]))
            assert r < 1e-8
        else:
            qq = dict(qa)
    To = M.output_pose(qq)
    if eff is not None and eff.out_rot is not None:
        To = To @ rotvec_to_R4(np.array([0.0, 0.0, eff.out_rot(ctx)]))
    o, R = ctx_extra["tracker_o"], ctx_extra["tracker_R"]
    pts, rots = [], []
    for off in offsets:
        off = np.asarray(off, float)
        if eff is not None and eff.target_scale is not None:
            off = eff.target_scale(off, ctx)
        p = To[:3, :3] @ off + To[:3, 3]
        if eff is not None and eff.point is not None:
            p = eff.point(p, ctx)
        m = R.T @ (p - o)
        if eff is not None and eff.meas is not None:
            m = eff.meas(m, ctx)
        pts.append(m)
        if six_d:
            rots.append(R.T @ To[:3, :3] @ rot_off)
    return pts, rots, ctx


def rigid_jacobian(M, q, offsets, o, R):
    """d(tracker-frame points)/d(defects, tracker 6, target offsets) at pose q (nominal geometry);
    the passive joints follow the closures (implicit differentiation, least squares)."""
    nd = len(M.defect_list)
    var = list(M.defect_list) + (list(M.passive) if M.closing else [])
    r0, To, dr, dTo = M.derivatives(q, var, h=1e-6)
    offs = [np.asarray(t, float) for t in offsets]
    P = np.array([[(dT[:3, :3] @ t + dT[:3, 3]) for dT in dTo] for t in offs])  # (nt, nvar, 3)
    P = P.transpose(0, 2, 1).reshape(3 * len(offs), len(var))
    Pd = P[:, :nd]
    if M.closing:
        Px = P[:, nd:]
        Pd = Pd - Px @ (np.linalg.pinv(dr[:, nd:]) @ dr[:, :nd])
    nt = len(offs)
    rows = []
    for t in range(nt):
        p = To[:3, :3] @ offs[t] + To[:3, 3]
        m = R.T @ (p - o)
        Jd = R.T @ Pd[3 * t:3 * t + 3]
        Jtr = np.hstack([-np.cross(np.eye(3), m), -R.T])  # rotation (about tracker axes), origin
        Jt = np.zeros((3, 3 * nt))
        Jt[:, 3 * t:3 * t + 3] = R.T @ To[:3, :3]
        rows.append(np.hstack([Jd, Jtr, Jt]))
    return np.vstack(rows), nd


def visibility(M, Js, nd, signal, sig, idx_id, idx_val, nt):
    """Rigid linearised refit of the effect's signal (id poses), RMS on held-out / sqrt(3) sigma."""
    ncol = Js[0].shape[1]
    prior = np.concatenate([[1e-3 if c in "IJKG" else 0.5 for (_, c) in M.defect_list],
                            [0.02] * 3, [20.0] * 3, [5.0] * (3 * nt)])
    A = np.vstack([Js[k] / sig[k] for k in idx_id])
    b = np.concatenate([signal[k] / sig[k] for k in idx_id])
    Ah = np.vstack([A, np.diag(1.0 / prior)])
    bh = np.concatenate([b, np.zeros(ncol)])
    x = np.linalg.lstsq(Ah, bh, rcond=None)[0]
    res = [signal[k] - Js[k] @ x for k in idx_val]
    norms = np.concatenate([np.linalg.norm(r.reshape(-1, 3), axis=1) for r in res])
    s3 = np.array([np.sqrt(3) * sig[k] for k in idx_val for _ in range(nt)])
    return float(np.sqrt(np.mean(norms ** 2)) / np.sqrt(np.mean(s3 ** 2)))


def campaign(case, outdir, seed=0, vis=True):
    fam = FAMILIES[case["family"]]
    rng = np.random.default_rng([seed, abs(hash_name(case["name"]))])
    M = model(case["model"])
    nid, nval = fam["n"]
    N = nid + nval
    poses = draw_poses(M, fam, case["design"], N, rng)
    meta = metadata(M, fam, poses, rng)
    o, R, rv = tracker_pose(M, poses, rng)
    six_d = case["targets"].startswith("6d")
    offsets = [np.asarray(t, float) + rng.uniform(-3, 3, 3) for t in TARGETS[case["targets"]]]
    rot_off = rotvec_to_R(ROT_OFFSET)
    a, b = fam["noise"]
    factor = case.get("factor", 1.0)
    rows, sig, signal = [], [], []
    for k, q in enumerate(poses):
        grav, moment = gravity_funcs(M, q, meta[k]["payload"])
        extra = dict(tracker_o=o, tracker_R=R, grav=grav, moment=moment)
        pts, rots, _ = measure(M, case, q, meta[k], extra, offsets, rot_off, six_d)
        if case.get("effect"):
            p0, _, _ = measure(M, case, q, meta[k], extra, offsets, rot_off, six_d, with_effect=False)
            signal.append(np.concatenate(pts) - np.concatenate(p0))
        d = np.linalg.norm(pts[0]) / 1000.0
        s = a + b * d
        sig.append(s)
        noisy = [p + rng.normal(0, s * factor, 3) for p in pts]
        nrots = [rotvec_to_R(rng.normal(0, ORIENT_NOISE * factor, 3)) @ Rm for Rm in rots]
        rows.append((noisy, nrots))
    order = rng.permutation(N)
    idx_val = sorted(order[:nval])
    idx_id = sorted(order[nval:])
    vis_value = None
    if vis and case.get("effect"):
        Js = []
        for q in poses:
            J, nd = rigid_jacobian(M, q, offsets, o, R)
            Js.append(J)
        vis_value = visibility(M, Js, nd, signal, sig, idx_id, idx_val, len(offsets))
    # files
    cdir = os.path.join(outdir, case["name"])
    os.makedirs(cdir, exist_ok=True)
    tr_err = rng.normal(0, 1.5, 3)
    rv_err = rv + rng.normal(0, 2e-3, 3)
    head = ["# hyperstat measurements, version 1", f"# mechanism: {fam['mech']}",
            f"# noise: {a} mm + {b} mm/m",
            "# tracker: " + " ".join(f"{v:.4f}" for v in np.concatenate([o + tr_err, rv_err]))]
    names = ["SMR%d" % (i + 1) for i in range(len(offsets))]
    for i, off in enumerate(offsets):
        prior = off + rng.uniform(-2, 2, 3)
        if len(offsets) == 1:
            head.append("# target: " + " ".join(f"{v:.3f}" for v in prior))
        else:
            head.append(f"# target {names[i]}: " + " ".join(f"{v:.3f}" for v in prior))
    if six_d:
        head.append(f"# orientation noise: {ORIENT_NOISE * 1000:.3f} mrad")
    pu = fam["punit"]
    cols = ["pose"] + [f"q{j}[{fam['junit'][j]}]" for j in M.actuated]
    if len(offsets) == 1:
        cols += [f"x[{pu}]", f"y[{pu}]", f"z[{pu}]"]
    else:
        for nm in names:
            cols += [f"x_{nm}[{pu}]", f"y_{nm}[{pu}]", f"z_{nm}[{pu}]"]
    if six_d:
        cols += ["rx[rad]", "ry[rad]", "rz[rad]"]
    cols += ["time[s]", "session", "temperature[degC]", "payload[kg]"] + [f"dir{j}" for j in M.actuated]

    def line(k):
        q = poses[k]
        mt = meta[k]
        vals = [f"P{k + 1}"]
        for j in M.actuated:
            u = fam["junit"][j]
            vals.append(repr(float(np.degrees(q[j]) if u == "deg" else q[j])))
        noisy, nrots = rows[k]
        for p in noisy:
            vals += [repr(float(v / 1000.0 if pu == "m" else v)) for v in p]
        for Rm in nrots:
            vals += [repr(float(v)) for v in R_to_rotvec(Rm)]
        vals += [f"{mt['time']:.1f}", str(mt["session"]), f"{mt['T']:.3f}", f"{mt['payload']:g}"]
        vals += [str(mt["dir"][j]) for j in M.actuated]
        return ",".join(vals)
    for fname, idx in (("data.csv", idx_id), ("val.csv", idx_val)):
        tmp = os.path.join(cdir, fname + ".tmp")
        with open(tmp, "w") as f:
            f.write("\n".join(head + [",".join(cols)] + [line(k) for k in idx]) + "\n")
        os.replace(tmp, os.path.join(cdir, fname))
    truth = dict(case)
    truth["visibility"] = vis_value
    truth["model_file"] = os.path.join(MODELS, case["model"] + ".skel.json")
    truth["tracker"] = list(map(float, np.concatenate([o, rv])))
    truth["offsets"] = [list(map(float, t)) for t in offsets]
    with open(os.path.join(cdir, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1, default=float)
    return case["name"], vis_value


def hash_name(s):
    h = 0
    for ch in s:
        h = (h * 131 + ord(ch)) % 2_147_483_647
    return h


def _one(args):
    return campaign(*args)


def generate(outdir, seed=0, jobs=2, names=None, vis=True):
    cases = [c for c in CASES if names is None or c["name"] in names]
    os.makedirs(outdir, exist_ok=True)
    args = [(c, outdir, seed, vis) for c in cases]
    if jobs > 1:
        with ProcessPoolExecutor(jobs) as ex:
            return dict(ex.map(_one, args))
    return dict(map(_one, args))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("outdir")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cases")
    ap.add_argument("--no-visibility", action="store_true")
    a = ap.parse_args(argv)
    res = generate(a.outdir, a.seed, a.jobs, a.cases.split(",") if a.cases else None, not a.no_visibility)
    for n, v in res.items():
        print(n, "-" if v is None else f"{v:.3f}")


if __name__ == "__main__":
    main()
