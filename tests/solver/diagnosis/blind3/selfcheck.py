"""Self-checks of the fifth blind generator's kinematics against hyperstat, through documented
commands and files only (never hyperstat's code):

1. nominal forward kinematics: ``hyperstat simulate`` with zero tolerances and a negligible noise
   writes measured positions (tracker frame) for its own poses; this module recomputes them with
   its own kinematics (serial arms from their own DH / URDF parameters and joint map, parallel
   machines from the model file with its own loop closure);
2. the generator's real machines (geometric errors, for the Tripteor projected on the admissible
   subspace of its own stationarity analysis) are machines hyperstat's model can represent:
   ``hyperstat identify`` on a noise-free no-effect campaign leaves a residual at the files'
   rounding, and on the noisy one sigma near 1;
3. the Tripteor's own stationarity analysis gives 14 independent constraints (docs/tripteor_x7.md:
   constraint rank 14);
4. the closure Jacobian against central finite differences.

    python -m tests.solver.diagnosis.blind3.selfcheck --hyperstat .venv/bin/hyperstat --out out/blind3-selfcheck
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys

import numpy as np

from . import generator, geom


def _rows(path):
    with open(path) as fh:
        lines = [line for line in fh if not line.startswith("#")]
    rows = list(csv.reader(lines))
    return rows[0], rows[1:]


def check_fk(fam, hs, out):
    """Recompute hyperstat simulate's nominal positions with the generator's kinematics."""
    sim = os.path.join(out, f"sim_{fam.name}.csv")
    truth = os.path.join(out, f"sim_{fam.name}_truth.json")
    subprocess.run([hs, "simulate", fam.model_path, "--poses", "6", "--validation", "0", "--noise", "1e-9 mm + 0 mm/m",
                    "--angle-tolerance", "0", "--length-tolerance", "0", "--out", sim, "--truth", truth,
                    "--seed", "3", "--quiet"], check=True)
    with open(truth) as fh:
        t = json.load(fh)["truth"]
    r = geom.rotvec_to_matrix([t["tracker_rx"], t["tracker_ry"], t["tracker_rz"]])
    o = np.array([t["tracker_x"], t["tracker_y"], t["tracker_z"]])
    off = np.array([t["target_x"], t["target_y"], t["target_z"]])
    hdr, rows = _rows(sim)
    n = len(fam.actuated)
    worst = 0.0
    for row in rows:
        v = np.array([float(x) for x in row[1:1 + n]])
        units = [h[h.index("[") + 1:-1] for h in hdr[1:1 + n]]
        if fam.kind == "serial":
            if units[0] == "deg":          # controller joints through the joint map
                q = np.radians(np.array(fam.arm.sign) * v + np.array(fam.arm.offset_deg))
            else:
                q = v
            tt = fam.arm.tool(q)
        else:
            q = fam.full_q(v)
            q, _, res, st = fam.mech.solve(q)
            tt = st["frames"][fam.mech.output]
        p = tt[:3, :3] @ off + tt[:3, 3]
        meas = np.array([float(x) for x in row[1 + n:4 + n]])
        worst = max(worst, float(np.max(np.abs(r.T @ (p - o) - meas))))
    return worst


def check_identify(fam, hs, out):
    case = [c for c in generator.all_cases() if c.family == fam.name and c.name == "none"][0]
    camp = generator.generate(fam, case, 99, os.path.join(out, fam.name))
    res = {}
    for tag in ("nf", "data"):
        j = os.path.join(out, fam.name, f"identify_{tag}.json")
        subprocess.run([hs, "identify", fam.model_path, camp.files[tag], "--validation", camp.files[f"{tag}.validation"],
                        "--json", j, "--quiet"], check=True)
        with open(j) as fh:
            d = json.load(fh)
        res[tag] = {"rms_id_mm": d["identification"]["rms"], "rms_val_mm": d["validation"]["rms"],
                    "sigma": d["sigma"], "rank": d["rank"], "noise_rms_mm": d["noise_rms"],
                    "orientation_rms_rad": (d.get("orientation") or {}).get("identification", {}).get("rms")}
    return res


def check_jacobian(fam):
    m = fam.mech
    rng = np.random.default_rng(5)
    q = fam.random_pose(rng)
    while q is None:
        q = fam.random_pose(rng)
    st = m.evaluate(q)
    var = [("q", j) for j in m.joints]
    jac = m.closure_jacobian(st, var)
    worst = 0.0
    h = 1e-6
    for k, j in enumerate(m.joints):
        qp, qm = dict(q), dict(q)
        qp[j] += h
        qm[j] -= h
        fd = (m.closure_residual(m.evaluate(qp)) - m.closure_residual(m.evaluate(qm))) / (2 * h)
        worst = max(worst, float(np.max(np.abs(fd - jac[:, k]))))
    return worst


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--hyperstat", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--repo", default=".")
    args = ap.parse_args(argv)
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    hs = os.path.abspath(args.hyperstat) if os.path.exists(args.hyperstat) else args.hyperstat
    report = {}
    for name in ("kr_like", "lbr_like", "tripteor_x7", "hexapod"):
        fam = generator.load_family(name, os.path.join(out, "models"), hs, os.path.abspath(args.repo))
        r = {"fk_vs_simulate_max_mm": check_fk(fam, hs, out), "identify": check_identify(fam, hs, out)}
        if fam.kind == "parallel":
            r["closure_jacobian_fd_max"] = check_jacobian(fam)
            cfgs = fam.sample_configs(np.random.default_rng(12345), 16)
            pvars, basis = fam.mech.admissible_basis(cfgs)
            r["admissible"] = f"{basis.shape[1]} of {len(pvars)} placement perturbations ({len(pvars) - basis.shape[1]} constraints)"
        report[name] = r
        print(name, json.dumps(r, indent=1, default=float), flush=True)
    with open(os.path.join(out, "selfcheck.json"), "w") as fh:
        json.dump(report, fh, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
