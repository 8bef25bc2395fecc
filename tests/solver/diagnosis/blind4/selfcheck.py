"""Self-checks of the sixth blind generator's own kinematics (numbers recorded in RULES.md).

    python -m tests.solver.diagnosis.blind4.selfcheck --hyperstat .venv/bin/hyperstat --out out/blind4-check

1. its forward kinematics and loop closure on each family's model file, with the defects, tracker and
   target of `hyperstat simulate --truth`, against simulate's noise-free positions (noise 1e-9 mm);
2. the imported serial models (zero defects) against the DH tables and the URDF computed directly;
3. the URDF masses it uses against the ones `import-robot` wrote (com, base frame at home);
4. gravity loads by virtual work (twists) against finite differences of the potential energy, the
   passive joints re-solved (Tripteor X7, PAL5);
5. its own stationarity check on the Tripteor: the rank of the defect directions that open a loop
   (docs/tripteor_x7.md: constraint rank 14: 12 forced defects and 2 relations);
6. the rigid columns of the visibility line (cached placements, passive joints to first order)
   against a full nonlinear re-assembly with each defect moved (central differences), 12 poses.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess

import numpy as np

from . import robots
from .generator import DEG, Design, Machine, forced_basis
from .kinematics import G_ACC, rotvec_to_matrix, target_point


def _read_sim(path):
    lines = [l.strip() for l in open(path) if l.strip() and not l.startswith("#")]
    hdr = lines[0].split(",")
    rows = [l.split(",") for l in lines[1:]]
    return hdr, rows


def simulate_check(hyperstat, machine, work):
    csv = os.path.join(work, f"{machine.family}.sim.csv")
    tj = os.path.join(work, f"{machine.family}.truth.json")
    subprocess.run([hyperstat, "simulate", machine.path, "--poses", "12", "--validation", "0",
                    "--noise", "1e-9 mm + 0 mm/m", "--out", csv, "--truth", tj, "--quiet"], check=True)
    tr = json.load(open(tj))["truth"]
    hdr, rows = _read_sim(csv)
    k = machine.kin
    r = rotvec_to_matrix([tr["tracker_rx"], tr["tracker_ry"], tr["tracker_rz"]])
    o = np.array([tr["tracker_x"], tr["tracker_y"], tr["tracker_z"]])
    tgt = [tr["target_x"], tr["target_y"], tr["target_z"]]
    worst = 0.0
    na = len(k.actuated)
    for row in rows:
        vals = dict(zip(hdr, row))
        if machine.family == "pal5":
            j = [float(vals[f"J{i}[deg]"]) for i in range(1, 6)]
            q = np.array([j[0], j[1], j[2] - j[1], j[3] + 0.5, -j[4]]) * DEG  # the joint map
        else:
            q = []
            for c in hdr[1:1 + na]:
                v = float(vals[c])
                q.append(v * DEG if c.endswith("[deg]") else v)
            q = np.array(q)
        meas = np.array([float(vals[c]) for c in ("x[mm]", "y[mm]", "z[mm]")])
        qq, fk, rn, ok = k.assemble(q, tr)
        t, _ = k.frame_of(fk, k.output)
        worst = max(worst, float(np.max(np.abs(r.T @ (target_point(t, tgt) - o) - meas))))
    return worst, len(rows)


def second_method_check(machine, rng, n=50):
    k = machine.kin
    worst = 0.0
    for _ in range(n):
        q = np.array([rng.uniform(*k.elements[k.elem_by_name[nm]].rng) for nm in k.actuated])
        qq, fk, rn, ok = k.assemble(q)
        t, _ = k.frame_of(fk, k.output)
        if machine.family == "pal5":
            t2 = robots.dh_forward(robots.PAL5_DH, q, 1000.0)
        elif machine.family == "ow6":
            t2 = robots.dh_forward(robots.OW6_DH, q, 1.0)
        else:
            t2 = robots.urdf_forward(q)
        worst = max(worst, float(np.max(np.abs(t[:3, 3] - t2[:3, 3]))),
                    1000.0 * float(np.max(np.abs(t[:3, :3] - t2[:3, :3]))))
    return worst


def mass_check(machine):
    decl = machine.kin.model["metadata"]["masses"]
    k = machine.kin
    fk = k.forward(k.home)
    worst = 0.0
    for n, m, c in machine.body_masses:
        t = fk["P"][k.elem_by_name[n]]
        cw = t[:3, :3] @ c + t[:3, 3]
        worst = max(worst, float(np.max(np.abs(cw - np.array(decl[n]["com"])))), abs(m - decl[n]["mass"]))
    return worst


def gravity_check(machine, rng, n=4):
    """tau from twists vs -dV/dq by central differences (passive joints re-solved)."""
    k = machine.kin
    poses = machine.sample_poses(rng, n)
    worst = 0.0
    for q in poses:
        qq, fk, rn, ok = k.assemble(q)
        tau = k.gravity_loads(fk, machine.point_masses(fk, 20.0))

        def potential(qa):
            q2, fk2, _, _ = k.assemble(qa, q_start=qq)
            return sum(m * G_ACC * c[2] for m, c, _ in machine.point_masses(fk2, 20.0))
        fd = np.zeros(len(q))
        for i in range(len(q)):
            h = 1e-5 if k.elements[k.elem_by_name[k.actuated[i]]].jtype == "R" else 1e-3
            e = np.zeros(len(q))
            e[i] = h
            fd[i] = -(potential(q + e) - potential(q - e)) / (2 * h)
        worst = max(worst, float(np.max(np.abs(tau - fd) / (np.abs(fd).max() + 1e-12))))
    return worst


def columns_check(machine, n_params=25):
    """Max relative difference between the visibility line's columns and a nonlinear re-assembly."""
    machine.cfg = dict(machine.cfg, poses=(8, 4))
    d = Design(machine, 3)
    k = machine.kin
    rng = np.random.default_rng(5)
    names = k.param_names
    pick = rng.choice(len(names), size=min(n_params, len(names)), replace=False)
    offs = list(machine.cfg["targets"].values())
    worst, scale = 0.0, np.abs(d.columns[:, :, :len(names)]).max()
    for i in range(d.n):
        for c in pick:
            nm = names[c]
            h = 1e-5 if nm[1] in "IJKG" else 1e-3
            col = []
            for sgn in (1, -1):
                g = dict(d.geometry)
                g[nm] += sgn * h
                q, fk, rn, ok = k.assemble(d.poses[i], g)
                t, _ = k.frame_of(fk, k.output)
                col.append(np.concatenate([d.r_trk.T @ target_point(t, o) for o in offs]))
            fd = (col[0] - col[1]) / (2 * h)
            worst = max(worst, float(np.max(np.abs(fd - d.columns[i][:, c]))) / scale)
    return worst


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--hyperstat", default=".venv/bin/hyperstat")
    ap.add_argument("--out", default="out/blind4-check")
    a = ap.parse_args(argv)
    repo = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", "..", ".."))
    paths = robots.prepare_models(a.hyperstat, repo, os.path.join(a.out, "models"))
    machines = {f: Machine(f, p) for f, p in paths.items()}
    rng = np.random.default_rng(7)
    res = {}
    for fam, m in machines.items():
        w, n = simulate_check(a.hyperstat, m, os.path.join(a.out, "models"))
        res[f"{fam}: own FK and closure vs simulate, noise-free, max |diff| (mm), {n} poses"] = w
    for fam in ("pal5", "ow6", "xa6"):
        res[f"{fam}: imported model vs the DH table / URDF directly, 50 poses, max |diff| (mm; rotation x1000)"] = \
            second_method_check(machines[fam], rng)
    res["xa6: URDF masses vs import-robot's metadata.masses, max |diff| (mm, kg)"] = mass_check(machines["xa6"])
    for fam in ("tx7", "pal5", "hexa"):
        res[f"{fam}: gravity loads, twists vs finite differences of the potential, max relative diff"] = \
            gravity_check(machines[fam], rng)
    for fam in ("tx7", "hexa", "ow6"):
        res[f"{fam}: visibility columns vs nonlinear re-assembly (25 defects, 12 poses), max diff / max column"] = \
            columns_check(Machine(fam, paths[fam]))
    v = forced_basis(machines["tx7"])
    res["tx7: rank of the defect directions that open a loop (own stationarity check; docs: 14)"] = int(v.shape[0])
    v = forced_basis(machines["hexa"])
    res["hexa: rank of the defect directions that open a loop (expected 0: not over-constrained)"] = int(v.shape[0])
    for kk, vv in res.items():
        print(f"{kk}: {vv:.3g}" if isinstance(vv, float) else f"{kk}: {vv}")
    with open(os.path.join(a.out, "selfcheck.json"), "w") as f:
        json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
