"""Generator of blind closure set 2 (mm, rad).  Imports no hyperstat code.

    /work/main/.venv/bin/python -m tests.solver.calibration.blind_closure2.generate [--out DIR] [--only NAME]

Writes the seven model files next to this file (bc2_*.skel.json) and, per campaign, into DIR
(default: campaigns/ next to this file): NAME.csv (identification poses), NAME.validation.csv
(held-out poses), NAME.truth.json (defects, tracker, reflector, noise, noise-free positions).
Deterministic: every campaign has its own seed.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

from .kin import Mechanism, kabsch, rotvec_to_R
from .mechanisms import MECHANISMS, OVER_CONSTRAINED, truth_defects

HERE = os.path.dirname(os.path.abspath(__file__))
ANG_PER_MM = 6e-3          # angular defect scale: 0.5 mm <-> 3e-3 rad
COND_MIN = 0.02            # sigma_min / sigma_max of the passive closure Jacobian, along the whole path
CLOSURE_TOL = 1e-9         # mm and rad, at every generated pose
N_VALIDATION = 30

# name, mechanism, true noise sigma per axis (mm), identification poses, defect scale (mm), understatement factor, seed
CAMPAIGNS = [
    ("fb_a", "five_bar_prrrp", 0.010, 60, 0.10, 1, 101),
    ("fb_b", "five_bar_prrrp", 0.003, 40, 0.50, 1, 102),
    ("fb_c", "five_bar_prrrp", 0.040, 120, 0.02, 1, 103),
    ("fb_d", "five_bar_prrrp", 0.020, 25, 0.30, 1, 104),
    ("fb_e", "five_bar_prrrp", 0.005, 20, 0.01, 1, 105),
    ("fb_u", "five_bar_prrrp", 0.020, 60, 0.20, 10, 106),
    ("r3_a", "rpr3", 0.005, 80, 0.20, 1, 201),
    ("r3_b", "rpr3", 0.020, 50, 0.50, 1, 202),
    ("r3_c", "rpr3", 0.040, 30, 0.05, 1, 203),
    ("r3_d", "rpr3", 0.010, 120, 0.003, 1, 204),
    ("r3_e", "rpr3", 0.003, 100, 0.50, 1, 205),
    ("r3_u", "rpr3", 0.010, 80, 0.30, 5, 206),
    ("st_a", "stephenson3", 0.010, 40, 0.20, 1, 301),
    ("st_b", "stephenson3", 0.003, 20, 0.05, 1, 302),
    ("st_c", "stephenson3", 0.020, 80, 0.50, 1, 303),
    ("st_u", "stephenson3", 0.030, 50, 0.10, 15, 304),
    ("tc_a", "triple_crank", 0.005, 30, 0.30, 1, 401),
    ("tc_b", "triple_crank", 0.020, 60, 0.01, 1, 402),
    ("tc_c", "triple_crank", 0.010, 100, 0.50, 1, 403),
    ("sp_a", "spherical_5bar", 0.010, 60, 0.30, 1, 501),
    ("sp_b", "spherical_5bar", 0.005, 100, 0.10, 1, 502),
    ("sp_c", "spherical_5bar", 0.030, 40, 0.50, 1, 503),
    ("sp_u", "spherical_5bar", 0.020, 80, 0.30, 20, 504),
    ("r2_a", "rpr2", 0.003, 50, 0.20, 1, 601),
    ("r2_b", "rpr2", 0.020, 30, 0.40, 1, 602),
    ("r2_c", "rpr2", 0.010, 90, 0.002, 1, 603),
    ("s8_a", "spatial8r", 0.010, 80, 0.30, 1, 701),
    ("s8_b", "spatial8r", 0.040, 120, 0.50, 1, 702),
    ("s8_c", "spatial8r", 0.005, 60, 0.05, 1, 703),
    ("s8_u", "spatial8r", 0.010, 100, 0.20, 8, 704),
]


def model_path(key):
    return os.path.join(HERE, "bc2_%s.skel.json" % key)


def write_models():
    for key, f in MECHANISMS.items():
        mdl = f()[0]
        text = json.dumps(mdl, indent=1, sort_keys=False) + "\n"
        p = model_path(key)
        if not os.path.exists(p) or open(p).read() != text:
            with open(p, "w") as fh:
                fh.write(text)


def draw_poses(true_m, nom_m, q_true_home, q_nom_home, n, rng, max_draws=20000):
    """Random actuated values in the actuated box; kept when both machines follow them from home."""
    lo = np.array([true_m.joints[i][3][0] for i in true_m.a_idx])
    hi = np.array([true_m.joints[i][3][1] for i in true_m.a_idx])
    out = []
    rejected = {}
    draws = 0
    while len(out) < n and draws < max_draws:
        draws += 1
        qa = lo + (hi - lo) * rng.uniform(0, 1, lo.size)
        q, info = true_m.follow(q_true_home, qa, cond_min=COND_MIN)
        if not info["ok"]:
            key = info["reason"].split(" (")[0].split(" at ")[0]
            rejected[key] = rejected.get(key, 0) + 1
            continue
        pe, re = true_m.closure_error(q)
        if pe > CLOSURE_TOL or re > CLOSURE_TOL:
            rejected["closure"] = rejected.get("closure", 0) + 1
            continue
        qn, ninfo = nom_m.follow(q_nom_home, qa, cond_min=COND_MIN)
        if not ninfo["ok"]:
            rejected["nominal machine: " + ninfo["reason"].split(" (")[0].split(" at ")[0]] = rejected.get("nominal", 0) + 1
            continue
        # same branch: the true and nominal passive joints stay close (defects are small)
        if np.max(np.abs((q - qn)[true_m.p_idx] * true_m.p_scale)) > 0.05:
            rejected["branch"] = rejected.get("branch", 0) + 1
            continue
        out.append((qa, q, info["min_cond"], qn))
    if len(out) < n:
        raise RuntimeError("only %d of %d poses after %d draws (%s)" % (len(out), n, draws, rejected))
    return out, draws, rejected


def fmt(v):
    return repr(float(v))


def write_csv(path, mdl, act_names, act_types, rows, noise_stated, tracker_prior, target_prior):
    lines = ["# hyperstat measurements, version 1",
             "# mechanism: %s" % mdl["name"],
             "# noise: %s mm + 0 mm/m" % fmt(noise_stated),
             "# tracker: %s" % " ".join(fmt(v) for v in tracker_prior),
             "# target: %s" % " ".join(fmt(v) for v in target_prior)]
    cols = ["pose"] + ["q%s[%s]" % (n, "rad" if t == "R" else "mm") for n, t in zip(act_names, act_types)] + ["x[mm]", "y[mm]", "z[mm]"]
    lines.append(",".join(cols))
    for name, qa, p in rows:
        lines.append(",".join([name] + [fmt(v) for v in qa] + [fmt(v) for v in p]))
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def generate(camp, out_dir):
    name, key, sigma, n_id, scale, under, seed = camp
    rng = np.random.default_rng(seed)
    mdl = json.load(open(model_path(key)))
    defects = truth_defects(key, rng, scale, scale * ANG_PER_MM)
    nom = Mechanism(mdl)
    true = Mechanism(mdl, defects)
    qn_home, rn = nom.assemble_home()
    qt_home, rt = true.assemble_home()
    assert rn < 1e-9 and rt < 1e-9, (rn, rt)
    assert np.max(np.abs((qt_home - qn_home)[true.p_idx] * true.p_scale)) < 0.05, "true home left the nominal home's branch"
    poses, draws, rejected = draw_poses(true, nom, qt_home, qn_home, n_id + N_VALIDATION, rng)
    # reflector offset in the output frame, tracker pose in the base frame
    target = rng.uniform(-40.0, 40.0, 3)
    pts = np.array([true.tool_point(q, target) for _, q, _, _ in poses])
    nom_pts = np.array([nom.tool_point(p[3], target) for p in poses])
    Rk, tk = kabsch(nom_pts, pts)
    effect_reg = float(np.sqrt(np.mean(np.sum((nom_pts @ Rk.T + tk - pts) ** 2, 1))))
    centre = pts.mean(0)
    d = rng.normal(size=3)
    d[2] = abs(d[2]) * 0.3
    t_pos = centre + 2500.0 * d / np.linalg.norm(d)
    rv = rng.normal(size=3)
    rv = rv / np.linalg.norm(rv) * rng.uniform(0.2, 0.6)
    R_trk = rotvec_to_R(rv)
    noise = rng.normal(size=pts.shape) * sigma
    meas = (pts - t_pos) @ R_trk + noise  # tracker coordinates: p_trk = R^T (p_base - t)
    tracker_prior = list(np.round(t_pos, 0)) + list(np.round(rv, 2))
    target_prior = list(np.round(target, 0))
    act_names = [true.joints[i][0] for i in true.a_idx]
    act_types = [true.joints[i][1] for i in true.a_idx]
    stated = sigma / under
    id_rows = [("P%d" % (k + 1), poses[k][0], meas[k]) for k in range(n_id)]
    val_rows = [("V%d" % (k + 1), poses[n_id + k][0], meas[n_id + k]) for k in range(N_VALIDATION)]
    os.makedirs(out_dir, exist_ok=True)
    write_csv(os.path.join(out_dir, name + ".csv"), mdl, act_names, act_types, id_rows, stated, tracker_prior, target_prior)
    write_csv(os.path.join(out_dir, name + ".validation.csv"), mdl, act_names, act_types, val_rows, stated, tracker_prior, target_prior)
    # self-checks on the stored poses
    max_pe = max_re = 0.0
    for _, q, _, _ in poses:
        pe, re = true.closure_error(q)
        max_pe, max_re = max(max_pe, pe), max(max_re, re)
    truth = {
        "campaign": name, "mechanism": key, "model_file": os.path.basename(model_path(key)),
        "model_name": mdl["name"], "over_constrained": OVER_CONSTRAINED[key],
        "units": {"length": "mm", "angle": "rad"},
        "seed": seed, "noise_sigma_per_axis_mm": sigma, "noise_stated_mm": stated, "understatement": under,
        "sound": under == 1, "defect_scale_mm": scale, "defect_scale_rad": scale * ANG_PER_MM,
        "defects": defects,
        "tracker": {"position_mm": list(map(float, t_pos)), "rotvec_rad": list(map(float, rv)),
                    "convention": "p_tracker = R(rotvec)^T (p_base - position)"},
        "target_mm": list(map(float, target)),
        "actuated": act_names,
        "identification": [{"pose": r[0], "actuated": list(map(float, poses[k][0])), "joints": list(map(float, poses[k][1])),
                            "position_base_mm": list(map(float, pts[k])), "min_condition": poses[k][2]}
                           for k, r in enumerate(id_rows)],
        "validation": [{"pose": r[0], "actuated": list(map(float, poses[n_id + k][0])), "joints": list(map(float, poses[n_id + k][1])),
                        "position_base_mm": list(map(float, pts[n_id + k])), "min_condition": poses[n_id + k][2]}
                       for k, r in enumerate(val_rows)],
        "self_checks": {"max_closure_position_mm": max_pe, "max_closure_rotation_rad": max_re,
                        "home_closure_residual": rt, "draws": draws, "rejected": rejected,
                        "min_condition_along_paths": min(p[2] for p in poses),
                        "noise_rms_realised_mm": float(np.sqrt(np.mean(noise ** 2))),
                        "defect_effect_registered_rms_mm": effect_reg,
                        "noise_3d_rms_mm": math.sqrt(3.0) * sigma},
    }
    with open(os.path.join(out_dir, name + ".truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1)
    return truth


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default=os.path.join(HERE, "campaigns"))
    ap.add_argument("--only", default=None)
    a = ap.parse_args(argv)
    write_models()
    for camp in CAMPAIGNS:
        if a.only and camp[0] != a.only:
            continue
        t = generate(camp, a.out)
        sc = t["self_checks"]
        print("%-5s %-15s noise %.3f mm (stated %.4g) poses %3d+%d scale %.3f mm (effect %.4f mm registered): closure %.1e mm %.1e rad, cond >= %.3f, draws %d %s"
              % (camp[0], camp[1], camp[2], t["noise_stated_mm"], camp[3], N_VALIDATION, camp[4], sc["defect_effect_registered_rms_mm"], sc["max_closure_position_mm"],
                 sc["max_closure_rotation_rad"], sc["min_condition_along_paths"], sc["draws"], sc["rejected"] or ""))
        sys.stdout.flush()


if __name__ == "__main__":
    main()
