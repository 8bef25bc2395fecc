"""Blind closure calibration set: models, true machines and tracker campaigns (mm, rad).

Does NOT import hyperstat.  Usage (from the repository root):

    python -m tests.solver.calibration.blind_closure.generate --out DIR [--only NAME ...]

writes DIR/<campaign>/{data.csv, val.csv, truth.json} and the model files next to this script
(`models/*.skel.json`, deterministic: regenerated identically).  Seeded and deterministic.
"""
import argparse
import hashlib
import json
import math
import os
import sys

import numpy as np

from . import kin
from . import mechanisms as M

HERE = os.path.dirname(os.path.abspath(__file__))
MODELS = os.path.join(HERE, "models")

# defect scales: origin shift (mm), axis tilt (rad)
SIZES = {"small": (0.03, 2e-4), "normal": (0.15, 1e-3), "large": (0.4, 2.5e-3)}

# name, mechanism, noise used (mm, 1 sigma per axis), noise stated, n_id, n_val, defect size, region
CAMPAIGNS = [
    ("fourbar_a", "fourbar", 0.005, 0.005, 40, 20, "normal", ("full",)),
    ("fourbar_b", "fourbar", 0.02, 0.02, 15, 10, "small", ("arc", 0.0, 0.3)),
    ("fourbar_c", "fourbar", 0.002, 0.002, 100, 30, "large", ("full",)),
    ("fourbar_d", "fourbar", 0.05, 0.05, 60, 20, "normal", ("arc", 1.5, 0.6)),
    ("slidercrank_a", "slidercrank", 0.005, 0.005, 40, 20, "normal", ("full",)),
    ("slidercrank_b", "slidercrank", 0.01, 0.01, 25, 15, "normal", ("between", 160.0, 168.5)),
    ("slidercrank_c", "slidercrank", 0.002, 0.002, 80, 25, "large", ("full",)),
    ("slidercrank_d", "slidercrank", 0.03, 0.03, 20, 10, "small", ("between", 120.0, 140.0)),
    ("fivebar_a", "fivebar", 0.005, 0.005, 60, 20, "normal", ("box", 1.0)),
    ("fivebar_b", "fivebar", 0.02, 0.02, 30, 15, "small", ("box", 0.5)),
    ("fivebar_c", "fivebar", 0.002, 0.002, 150, 30, "large", ("box", 1.0)),
    ("watt6_a", "watt6", 0.005, 0.005, 60, 20, "normal", ("full",)),
    ("watt6_b", "watt6", 0.01, 0.01, 30, 15, "normal", ("arc", -1.0, 0.5)),
    ("watt6_c", "watt6", 0.02, 0.02, 120, 30, "large", ("full",)),
    ("watt6_d", "watt6", 0.002, 0.002, 20, 10, "small", ("arc", 0.5, 0.25)),
    ("bennett_a", "bennett", 0.005, 0.005, 40, 20, "normal", ("full",)),
    ("bennett_b", "bennett", 0.02, 0.02, 20, 10, "normal", ("between", 0.6, 1.1)),
    ("bennett_c", "bennett", 0.002, 0.002, 100, 30, "large", ("full",)),
    ("bennett_d", "bennett", 0.05, 0.05, 60, 20, "small", ("between", 1.2, 1.8)),
    ("spherical_a", "spherical", 0.005, 0.005, 40, 20, "normal", ("full",)),
    ("spherical_b", "spherical", 0.01, 0.01, 25, 15, "normal", ("arc", 0.5, 0.5)),
    ("spherical_c", "spherical", 0.002, 0.002, 80, 25, "large", ("full",)),
    ("rsur_a", "rsur", 0.005, 0.005, 40, 20, "normal", ("full",)),
    ("rsur_b", "rsur", 0.02, 0.02, 60, 20, "large", ("full",)),
    ("rsur_c", "rsur", 0.002, 0.002, 25, 15, "small", ("arc", 0.0, 0.5)),
    # unsound: the header states a noise 5-20 x smaller than the one used
    ("fourbar_u", "fourbar", 0.02, 0.002, 40, 20, "normal", ("full",)),
    ("slidercrank_u", "slidercrank", 0.03, 0.005, 40, 20, "normal", ("full",)),
    ("watt6_u", "watt6", 0.04, 0.002, 60, 20, "normal", ("full",)),
    ("bennett_u", "bennett", 0.025, 0.004, 40, 20, "normal", ("full",)),
    ("rsur_u", "rsur", 0.05, 0.005, 40, 20, "large", ("full",)),
]

SEED_BASE = 20261130
MARGIN = 0.02  # rad or mm-fraction kept off the declared range ends


def seed_of(name):
    return SEED_BASE + int(hashlib.sha256(name.encode()).hexdigest()[:8], 16) % 100000


def model_path(mech):
    return os.path.join(MODELS, "%s.skel.json" % mech)


def write_models(write=False):
    """Build the models; write them (--write-models) or check that the committed files are
    exactly what the builders give (self-check: the model files are reproducible)."""
    os.makedirs(MODELS, exist_ok=True)
    out = {}
    for name in M.BUILDERS:
        m, fam = M.build(name)
        text = json.dumps(m, indent=1, sort_keys=False) + "\n"
        p = model_path(name)
        if write:
            with open(p, "w") as f:
                f.write(text)
        else:
            with open(p) as f:
                old = f.read()
            if old != text:
                raise RuntimeError("%s differs from what the builder gives: run --write-models" % p)
        out[name] = (json.loads(text), fam)
    return out


def r12(x):
    return float("%.12g" % x)


def sample_poses(mech, region, n, rng):
    """Actuated vectors (rounded as written), in the order followed from home."""
    act = mech.act
    lo = np.array([mech.joints[i][3][0] for i in act])
    hi = np.array([mech.joints[i][3][1] for i in act])
    home = mech.home[act]
    kind = region[0]
    if kind == "full":
        a, b = lo + MARGIN, hi - MARGIN
    elif kind == "arc":
        a, b = np.array([region[1] - region[2]]), np.array([region[1] + region[2]])
    elif kind == "between":
        a, b = np.array([region[1]]), np.array([region[2]])
    elif kind == "box":
        f = region[1]
        a, b = home + f * (lo + MARGIN - home), home + f * (hi - MARGIN - home)
    a, b = np.maximum(a, lo), np.minimum(b, hi)
    X = rng.uniform(a, b, size=(n, len(act)))
    X = np.vectorize(r12)(X)
    if len(act) == 1:
        X = X[np.argsort(X[:, 0])]
    else:  # greedy nearest-neighbour tour from home, in range-normalised units
        span = hi - lo
        left = list(range(n))
        cur = home
        order = []
        while left:
            d = [np.linalg.norm((X[k] - cur) / span) for k in left]
            k = left.pop(int(np.argmin(d)))
            order.append(k)
            cur = X[k]
        X = X[order]
    return X


def follow_checked(mech, nom, X):
    """Follow the true machine from its home through X; self-checks. Returns joint vectors."""
    q = mech.home.copy()
    q, nr, ok = mech.solve(q)
    if not ok:
        raise RuntimeError("true home does not assemble (%.3g)" % nr)
    qn = nom.solve(nom.home.copy())[0]
    out, checks = [], {"max_closure_mm": 0.0, "max_closure_rad": 0.0, "max_step_jump_rad": 0.0,
                       "max_true_vs_nominal_passive": 0.0, "min_sv_ratio": 1.0}
    for x in X:
        q, wr, wj, ok = mech.continue_to(q, x)
        if not ok:
            raise RuntimeError("true machine does not assemble at %s" % (x,))
        qn, _, _, okn = nom.continue_to(qn, x)
        if not okn:
            raise RuntimeError("nominal machine does not assemble at %s" % (x,))
        r = mech.residual(q)
        pos, rot = closure_parts(mech, r)
        checks["max_closure_mm"] = max(checks["max_closure_mm"], pos)
        checks["max_closure_rad"] = max(checks["max_closure_rad"], rot)
        checks["max_step_jump_rad"] = max(checks["max_step_jump_rad"], wj)
        dp = np.abs(q[mech.pas] - qn[nom.pas]) if mech.pas else np.zeros(1)
        checks["max_true_vs_nominal_passive"] = max(checks["max_true_vs_nominal_passive"], float(dp.max()))
        checks["min_sv_ratio"] = min(checks["min_sv_ratio"], mech.passive_jacobian_sv(q))
        out.append(q.copy())
    return out, checks


def closure_parts(mech, r):
    """Closure residual split: position (mm) and rotation-matrix entries (rad-like)."""
    pos, rot = 0.0, 0.0
    k = 0
    while k < len(r):
        pos = max(pos, float(np.abs(r[k:k + 3]).max()))
        rot = max(rot, float(np.abs(r[k + 3:k + 12]).max()) / mech.L)
        k += 12
    return pos, rot


def tracker_of(rng):
    d = rng.uniform(1500, 3000)
    az = rng.uniform(-math.pi, math.pi)
    o = np.array([d * math.cos(az), d * math.sin(az), rng.uniform(-200, 800)])
    rv = rng.normal(size=3)
    rv *= rng.uniform(0.2, 0.6) / np.linalg.norm(rv)
    return o, rv


def to_tracker(P, o, rv):
    R = kin.rotvec(rv)
    return (np.asarray(P) - o) @ R  # R^T (p - o), row-wise


def write_csv(path, mname, sigma_stated, tr_hdr, tg_hdr, mech, X, meas):
    cols = []
    for i in mech.act:
        nm, typ = mech.joints[i][0], mech.joints[i][1]
        cols.append("q%s[%s]" % (nm, "rad" if typ == "R" else "mm"))
    with open(path, "w") as f:
        f.write("# hyperstat measurements, version 1\n")
        f.write("# mechanism: %s\n" % mname)
        f.write("# noise: %s mm + 0 mm/m\n" % repr(sigma_stated))
        f.write("# tracker: %s\n" % " ".join("%.6f" % v for v in tr_hdr))
        f.write("# target: %s\n" % " ".join("%.4f" % v for v in tg_hdr))
        f.write("pose,%s,x[mm],y[mm],z[mm]\n" % ",".join(cols))
        for k, (x, p) in enumerate(zip(X, meas)):
            f.write("P%d,%s,%s\n" % (k + 1, ",".join(repr(float(v)) for v in x),
                                      ",".join("%.9f" % v for v in p)))


def generate_campaign(spec, models, outdir):
    name, mname, s_used, s_stated, n_id, n_val, size, region = spec
    rng = np.random.default_rng(seed_of(name))
    m, fam = models[mname]
    so, st = SIZES[size]
    nom = kin.Mechanism(m)
    for attempt in range(20):
        defs = M.true_defects(mname, m, fam, rng, so, st)
        lim_o = max(abs(v) for k, v in defs.items() if k[1] in "abc")
        lim_t = max((abs(v) for k, v in defs.items() if k[1] in "IJKG"), default=0.0)
        true = kin.Mechanism(m, defs)
        Xid = sample_poses(nom, region, n_id, rng)
        Xval = sample_poses(nom, region, n_val, rng)
        try:
            if lim_o > 0.5 or lim_t > 3e-3:
                raise RuntimeError("defect beyond 0.5 mm / 3e-3 rad")
            qid, cid = follow_checked(true, nom, Xid)
            qval, cval = follow_checked(true, nom, Xval)
        except RuntimeError as e:
            print("  %s attempt %d rejected: %s" % (name, attempt, e), file=sys.stderr)
            continue
        break
    else:
        raise RuntimeError("%s: no admissible true machine" % name)
    checks = {k: (max(cid[k], cval[k]) if k != "min_sv_ratio" else min(cid[k], cval[k])) for k in cid}
    ok = (checks["max_closure_mm"] < 1e-9 and checks["max_closure_rad"] < 1e-9
          and checks["max_step_jump_rad"] < 0.3 and checks["max_true_vs_nominal_passive"] < 0.1
          and checks["min_sv_ratio"] > 1e-4)
    if not ok:
        raise RuntimeError("%s: self-check failed %s" % (name, checks))
    target = np.array([12.0, -8.0, 25.0]) + rng.uniform(-3, 3, 3)
    o, rv = tracker_of(rng)
    tr_hdr = np.concatenate([o + rng.normal(0, 5.0, 3), rv + rng.normal(0, 0.01, 3)])
    tg_hdr = target + rng.uniform(-2, 2, 3)

    def positions(qs):
        Pb = np.array([true.tool(q, target)[0] for q in qs])
        return Pb, to_tracker(Pb, o, rv)

    Pb_id, Pt_id = positions(qid)
    Pb_val, Pt_val = positions(qval)
    meas_id = Pt_id + rng.normal(0, s_used, Pt_id.shape)
    meas_val = Pt_val + rng.normal(0, s_used, Pt_val.shape)
    d = os.path.join(outdir, name)
    os.makedirs(d, exist_ok=True)
    write_csv(os.path.join(d, "data.csv"), m["name"], s_stated, tr_hdr, tg_hdr, nom, Xid, meas_id)
    write_csv(os.path.join(d, "val.csv"), m["name"], s_stated, tr_hdr, tg_hdr, nom, Xval, meas_val)
    truth = {
        "units": {"length": "mm", "angle": "rad"},
        "campaign": name, "mechanism": mname, "model_file": os.path.relpath(model_path(mname), HERE),
        "overconstrained": M.OVERCONSTRAINED[mname],
        "noise_used_mm": s_used, "noise_stated_mm": s_stated, "sound": s_used == s_stated,
        "n_id": n_id, "n_val": n_val, "defect_size": size, "region": list(region),
        "seed": seed_of(name),
        "defects": defs,
        "tracker_in_base": {"origin_mm": o.tolist(), "rotvec_rad": rv.tolist(),
                            "convention": "p_base = R(rotvec) p_tracker + origin"},
        "target_in_output_mm": target.tolist(),
        "self_checks": checks,
        "identification": {"actuated": Xid.tolist(), "joints": [q.tolist() for q in qid],
                           "tracker_mm": Pt_id.tolist(), "base_mm": Pb_id.tolist(),
                           "measured_mm": meas_id.tolist()},
        "validation": {"actuated": Xval.tolist(), "joints": [q.tolist() for q in qval],
                       "tracker_mm": Pt_val.tolist(), "base_mm": Pb_val.tolist(),
                       "measured_mm": meas_val.tolist()},
    }
    with open(os.path.join(d, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    return truth


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--write-models", action="store_true", help="(re)write models/*.skel.json")
    a = ap.parse_args(argv)
    models = write_models(a.write_models)
    os.makedirs(a.out, exist_ok=True)
    for spec in CAMPAIGNS:
        if a.only and spec[0] not in a.only:
            continue
        t = generate_campaign(spec, models, a.out)
        c = t["self_checks"]
        print("%-15s %-11s noise %.3g/%.3g mm  %3d+%2d poses  closure %.1e mm %.1e rad  jump %.3f  "
              "vs-nominal %.3f  sv %.2g" % (spec[0], spec[1], spec[2], spec[3], spec[4], spec[5],
                                            c["max_closure_mm"], c["max_closure_rad"],
                                            c["max_step_jump_rad"], c["max_true_vs_nominal_passive"],
                                            c["min_sv_ratio"]))


if __name__ == "__main__":
    main()
