"""Self-checks of the seventh blind generator (no diagnose run).  Units: mm, rad.

    python -m tests.solver.diagnosis.blind5.selfcheck --hyperstat PATH [--quick]

1. its forward kinematics against the positions ``hyperstat simulate`` writes for the nominal
   model (defect tolerances 0, noise 1e-9 mm): a comparison of outputs, after removing the constant
   offset the header's rounded tracker pose leaves;
2. its own standard-DH product against the imported model files (PUMA-like, SCARA-like);
3. its rigid fit: a pure geometric change (a constant joint offset) and a tracker shift have
   visibility ~0, so the visibility measures what a rigid model cannot absorb;
4. no-effect data against the noise: this generator's rigid fit of a noisy no-effect campaign leaves
   a weighted residual of sigma ~1, and ``hyperstat identify`` (its output read) gives sigma ~1;
5. effect magnitudes: the joint changes applied (max |dq|) against the case's parameters, and the
   noise applied in understated campaigns against the header's.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from . import effects as fx
from .cases import CASES, _c
from .generate import FAMILIES, MODELS, campaign, model_of, rigid_fit, visibility, write_files
from .kin import rot_vec

ROBOTS = Path(__file__).resolve().parent / "robots"


def check_fk_against_simulate(exe, family, tmp):
    model = model_of(family)
    out = Path(tmp) / ("%s_sim.csv" % family)
    subprocess.run([exe, "simulate", str(MODELS / FAMILIES[family]["model"]), "--poses", "8", "--validation", "0",
                    "--noise", "1e-9 mm + 0 mm/m", "--angle-tolerance", "0", "--length-tolerance", "0",
                    "--out", str(out), "--quiet"], check=True)
    head, rows = {}, []
    for line in out.read_text().splitlines():
        if line.startswith("#"):
            if ":" in line:
                k, v = line[1:].split(":", 1)
                head[k.strip()] = v.strip()
        elif not rows:
            rows.append(line.split(","))
        else:
            rows.append(line.split(","))
    cols = rows[0]
    tr = [float(x) for x in head["tracker"].split()]
    tg = np.array([float(x) for x in head["target"].split()])
    r_tr, t_tr = rot_vec(tr[3:]), np.array(tr[:3])
    diffs = []
    for r in rows[1:]:
        qa = {}
        for j in model.actuated:
            for c, v in zip(cols, r):
                if c.startswith("q%s[" % j):
                    qa[j] = float(v)
        qp, fr, res = model.solve(qa)
        t = fr[model.output]
        m = r_tr.T @ (t[:3, :3] @ tg + t[:3, 3] - t_tr)
        meas = np.array([float(r[cols.index(c)]) for c in ("x[mm]", "y[mm]", "z[mm]")])
        diffs.append(m - meas)
    d = np.array(diffs)
    off = d.mean(axis=0)
    return float(np.abs(d - off).max()), off


def dh_fk(rows, q):
    t = np.eye(4)
    for (typ, a, alpha, d, theta), qi in zip(rows, q):
        th, dd = (theta + qi, d) if typ == "R" else (theta, d + qi)
        c, s, ca, sa = np.cos(th), np.sin(th), np.cos(alpha), np.sin(alpha)
        t = t @ np.array([[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0, sa, ca, dd], [0, 0, 0, 1]])
    return t


def check_dh(family, rows, rng):
    model = model_of(family)
    worst = 0.0
    for _ in range(20):
        q = [rng.uniform(*model.ranges[j]) for j in model.actuated]
        fr = model.frames(dict(zip(model.actuated, q)), np.zeros(0))[0]
        worst = max(worst, float(np.abs(fr[model.output] - dh_fk(rows, q))[:3].max()))
    return worst


PUMA_DH = [("R", 0, np.pi / 2, 660, 0), ("R", 431.8, 0, 0, 0), ("R", 20.3, -np.pi / 2, 150.05, 0),
           ("R", 0, np.pi / 2, 431.8, 0), ("R", 0, -np.pi / 2, 0, 0), ("R", 0, 0, 56.25, 0)]
SCARA_DH = [("R", 350, 0, 420, 0), ("R", 300, np.pi, 0, 0), ("P", 0, 0, 0, 0), ("R", 0, 0, 60, 0)]


class _Offset(fx.Effect):
    name = "constant-offset"

    def dq(self, ctx):
        return {self.p["joint"]: self.p["v"]}


class _Shift(fx.Effect):
    name = "tracker-shift"

    def tracker_point(self, ctx, m):
        return m + np.array([0.05, -0.04, 0.03])


def check_rigid_absorbs(family, joint, v):
    case = _c("chk_off", family, "in", None, None, poses=(30, 12))
    camp = campaign(case, 0)
    out = []
    for eff in (_Offset(joint=joint, v=v), _Shift()):
        camp2 = campaign(dict(case), 0)
        camp2["effect"] = eff
        # rebuild the clean points with the effect (same poses, no noise needed for visibility)
        model = camp2["model"]
        t_tr, rz = camp2["tracker"]
        r_tr = rot_vec([0, 0, rz])
        for r in camp2["rows"]:
            ctx = {"qa": r["qa"], "T": r["T"], "t": r["t"], "session": r["session"], "dir": r["dir"], "model": model}
            dq = eff.dq(ctx)
            qt = {j: r["qa"][j] + dq.get(j, 0.0) for j in r["qa"]}
            qp, fr, res = model.solve(qt, qp0=r["qp"])
            t = fr[model.output]
            r["clean"] = [eff.tracker_point(ctx, r_tr.T @ (t[:3, :3] @ o + t[:3, 3] - t_tr)) for o in camp2["targets"]]
        out.append(visibility(camp2)[0])
    return out


def check_noise_fit(case):
    """This generator's rigid fit of the noisy campaign: weighted residual sigma (id rows)."""
    camp = campaign(case, 0)
    rows = [r for r in camp["rows"] if not r["val"]]
    e = np.concatenate([np.concatenate([m - n for m, n in zip(r["meas"], r["nominal"])]) for r in rows])
    fit, _, w = rigid_fit(camp, rows, e, rows[:1])
    res = (e - fit) * w
    return float(np.sqrt(np.mean(res ** 2))), camp


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--hyperstat", required=True, help="the hyperstat executable")
    ap.add_argument("--quick", action="store_true", help="skip hyperstat identify")
    a = ap.parse_args(argv)
    rng = np.random.default_rng(5)
    with tempfile.TemporaryDirectory() as tmp:
        print("1. forward kinematics against hyperstat simulate (nominal model, 8 poses):")
        for fam in FAMILIES:
            worst, off = check_fk_against_simulate(a.hyperstat, fam, tmp)
            print("   %-12s max deviation %.2e mm after the header's constant offset (%.4f %.4f %.4f mm)"
                  % (fam, worst, *off))
        print("2. own DH product against the model files: PUMA-like %.2e mm, SCARA-like %.2e mm (max entry)"
              % (check_dh("puma_like", PUMA_DH, rng), check_dh("scara_like", SCARA_DH, rng)))
        print("3. rigid fit absorbs geometry: visibility of (constant joint offset, tracker shift of 0.07 mm):")
        for fam, j, v in (("tripteor_x7", "42", 0.1), ("hexapod", "33", 0.1), ("puma_like", "2", 5e-4),
                          ("scara_like", "1", 5e-4)):
            print("   %-12s joint %s %+g: %.3f, %.3f" % (fam, j, v, *check_rigid_absorbs(fam, j, v)))
        print("4. no-effect and understated campaigns: this generator's rigid fit, weighted sigma (id rows);"
              " hyperstat identify's sigma:")
        for case in CASES:
            if case["kind"] not in ("none", "under"):
                continue
            s, camp = check_noise_fit(case)
            line = "   %-16s own fit sigma %.3f (applied/stated %.2f)" % (case["id"], s, case["understate"])
            if not a.quick and case["family"] != "hexapod":
                d = Path(tmp) / case["id"]
                p = write_files(camp, d)
                subprocess.run([a.hyperstat, "identify", str(MODELS / FAMILIES[case["family"]]["model"]),
                                str(p["data"]), "--validation", str(p["val"]), "--json", str(d / "id.json"),
                                "--quiet"], check=True)
                j = json.loads((d / "id.json").read_text())
                line += "; identify sigma %.3f, validation RMS %.4f mm, noise RMS %.4f mm" % (
                    j["sigma"], j["validation"]["rms"], j["noise_rms"] or float("nan"))
            print(line, flush=True)
        print("5. effect magnitudes (max |dq| applied over the campaign's poses):")
        for case in CASES:
            eff = fx.make(case["effect"]) if case["effect"] else None
            if eff is None or not case["effect"].get("effect") in (
                    "leg-thermal", "screw-pitch", "screw-periodic", "angle-scale", "angle-harmonic", "backlash",
                    "cable-drag", "quadratic-lead", "cross-coupling", "warm-up-drift", "gear-dent"):
                continue
            camp = campaign(case, 0)
            mx = {}
            for r in camp["rows"]:
                ctx = {"qa": r["qa"], "T": r["T"], "t": r["t"], "session": r["session"], "dir": r["dir"],
                       "model": camp["model"]}
                for j, v in eff.dq(ctx).items():
                    mx[j] = max(mx.get(j, 0.0), abs(v))
            print("   %-20s %s" % (case["id"], ", ".join("%s: %.3g" % kv for kv in sorted(mx.items()))))


if __name__ == "__main__":
    main()
