"""Generate, run and judge the blind2 campaigns through hyperstat's command line only.

    python -m tests.solver.diagnosis.blind2.score --hyperstat .venv/bin/hyperstat --out DIR --seeds 2 [--jobs 2]
        [--cases a,b] [--limit N]

Writes DIR/rates.md and DIR/campaigns.json.  Units: mm, rad.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import glob
import hashlib
import json
import os
import subprocess
import sys
import time

from . import arms as A
from .campaign import write_campaign
from .cases import campaign_list
from .effects import CASES
from .judge import judge, multi_target_consistent, VISIBLE

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_SEEDS = 2
TIMEOUT = 600


def code_hash():
    h = hashlib.sha256()
    for p in sorted(glob.glob(os.path.join(HERE, "*.py"))):
        h.update(os.path.basename(p).encode())
        with open(p, "rb") as fh:
            h.update(fh.read())
    return h.hexdigest()


def git_head():
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], cwd=HERE, capture_output=True, text=True).stdout.strip()
    except OSError:
        return "unknown"


def import_models(hyperstat, outdir):
    """URDFs written by arms.py, imported with `hyperstat import-robot` (with and without <inertial>)."""
    os.makedirs(os.path.join(outdir, "models"), exist_ok=True)
    paths = {}
    for arm in A.ARMS.values():
        for mass in (True, False):
            stem = os.path.join(outdir, "models", f"{arm.name}-{'mass' if mass else 'nomass'}")
            with open(stem + ".urdf", "w") as fh:
                fh.write(A.urdf_text(arm, mass))
            r = subprocess.run([hyperstat, "import-robot", stem + ".urdf", "--out", stem + ".skel.json", "--quiet"],
                               capture_output=True, text=True)
            if r.returncode != 0:
                raise SystemExit(f"import-robot failed on {stem}.urdf: {r.stderr.strip()}")
            paths[(arm.name, mass)] = stem + ".skel.json"
    return paths


def run(cmd):
    t0 = time.time()
    try:
        env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT, env=env)
        return r.returncode, r.stderr.strip()[-400:], time.time() - t0
    except subprocess.TimeoutExpired:
        return -1, "timeout", time.time() - t0


def load(path):
    try:
        with open(path) as fh:
            return json.load(fh)
    except (OSError, ValueError):
        return None


def one(hyperstat, outdir, models, case, variant, seed, do_diagnose=True):
    d = os.path.join(outdir, "campaigns", case, variant.label, f"s{seed}")
    model = models[(variant.arm, variant.masses)]
    write_campaign(d, case, variant, seed, model)
    write_campaign(d, case, variant, seed, model, noise_free=True)
    rec = {"case": case, "variant": variant.label, "seed": seed, "dir": os.path.relpath(d, outdir),
           "targets": variant.targets, "masses": variant.masses}
    rc, err, dt = run([hyperstat, "identify", model, os.path.join(d, "ident.nf.csv"), "--validation",
                       os.path.join(d, "val.nf.csv"), "--json", os.path.join(d, "visibility.json"), "--quiet"])
    vis = load(os.path.join(d, "visibility.json")) if rc == 0 else None
    rec["t_visibility_s"] = dt
    if vis and vis.get("noise_rms"):
        r_id = vis["identification"]["rms"] / vis["noise_rms"]
        r_val = vis["validation"]["rms"] / vis["noise_rms"]
        rec["visibility"] = max(r_id, r_val)
        rec["visibility_id_val"] = [r_id, r_val]
    else:
        rec["visibility"] = None
        rec["visibility_error"] = err
    rc, err, dt = run([hyperstat, "identify", model, os.path.join(d, "ident.csv"), "--validation",
                       os.path.join(d, "val.csv"), "--json", os.path.join(d, "identify.json"), "--quiet"])
    idj = load(os.path.join(d, "identify.json")) if rc == 0 else None
    rec["t_identify_s"] = dt
    rec["identify_exit"] = rc
    if idj:
        rec["identify"] = {"sigma": idj.get("sigma"), "fit_quality": idj.get("fit_quality"),
                           "val_rms_mm": idj.get("validation", {}).get("rms"), "noise_rms_mm": idj.get("noise_rms")}
    if not do_diagnose:
        return rec
    rc, err, dt = run([hyperstat, "diagnose", model, os.path.join(d, "ident.csv"), "--validation",
                       os.path.join(d, "val.csv"), "--json", os.path.join(d, "diagnose.json"), "--quiet"])
    rec["t_diagnose_s"] = dt
    rec["diagnose_exit"] = rc
    dj = load(os.path.join(d, "diagnose.json")) if rc == 0 else None
    if rc != 0:
        rec["diagnose_stderr"] = err
    if dj is not None:
        rec["answer"] = {k: dj.get(k) for k in ("outcome", "named_effects", "equivalence_sets", "ambiguous",
                                                 "cannot_size", "noise_factor", "targets_agree")}
        rec["answer"]["per_target"] = [{k: e.get(k) for k in ("target", "outcome", "named_effects")}
                                       for e in (dj.get("per_target") or [])]
    rec.update(judge(case, variant, dj, rec["visibility"]))
    truth = load(os.path.join(d, "truth.json")) or {}
    if case == "understated" and dj is not None:
        tf = truth.get("params", {}).get("noise_factor")
        nf = dj.get("noise_factor")
        rec["true_noise_factor"] = tf
        rec["noise_factor_within_25pct"] = bool(nf and tf and abs(nf / tf - 1) <= 0.25)
    if variant.targets > 1:
        rec["multi_target_consistent"] = multi_target_consistent(dj)
        rec["targets_agree"] = dj.get("targets_agree") if dj else None
    return rec


def rate(recs, good, pred=lambda r: True):
    sel = [r for r in recs if pred(r)]
    k = sum(1 for r in sel if r.get("judgement") in good)
    return k, len(sel)


def fmt(k, n):
    return f"{100 * k / n:.0f} % ({k}/{n})" if n else "- (0)"


def write_rates(outdir, recs, args, wall):
    vis = lambda r: r.get("visible") is not False          # noqa: E731  (None for none/understated)
    lines = ["# blind2: rates of `hyperstat diagnose` on this generator's campaigns", "",
             f"- code SHA-256 of tests/solver/diagnosis/blind2/*.py: `{code_hash()}`",
             f"- git HEAD: `{git_head()}`",
             f"- command: `python -m tests.solver.diagnosis.blind2.score --hyperstat {args.hyperstat} --out {args.out} "
             f"--seeds {args.seeds} --jobs {args.jobs}" + (f" --cases {args.cases}" if args.cases else "")
             + (f" --limit {args.limit}" if args.limit else "") + "`",
             f"- campaigns: {len(recs)}; wall clock {wall:.0f} s; load average at the end {os.getloadavg()[0]:.1f}",
             f"- visibility threshold: noise-free rigid-fit RMS >= {VISIBLE} x stated noise RMS (else counted apart)",
             "", "Units: mm, rad.", "", "| rate | value |", "|---|---|"]
    cat = lambda c: (lambda r: r["category"] == c and vis(r))  # noqa: E731
    rows = [
        ("in-library: truth named (alone or in an equivalence set), visible", rate(recs, {"named"}, cat("in"))),
        ("in-library, model without masses, gravity effect: 'cannot size' honest", rate(recs, {"cannot size (honest)"}, cat("in-nomass-gravity"))),
        ("out-of-library: honest, visible", rate(recs, {"honest"}, lambda r: r["category"] in ("out", "out-nomass-gravity") and vis(r))),
        ("out-of-library: confident wrong, visible", rate(recs, {"confident wrong"}, lambda r: r["category"] in ("out", "out-nomass-gravity") and vis(r))),
        ("out-of-library: missed (no significant gap), visible", rate(recs, {"missed"}, lambda r: r["category"] in ("out", "out-nomass-gravity") and vis(r))),
        ("out-of-library, model without masses (gravity effects): honest", rate(recs, {"honest"}, cat("out-nomass-gravity"))),
        ("understated noise flagged", rate(recs, {"flagged"}, cat("understated"))),
        ("no effect: false alarms (an effect named)", rate(recs, {"false alarm"}, cat("none"))),
        ("no effect: answered 'no significant gap'", rate(recs, {"clean"}, cat("none"))),
        ("errors (diagnose exit code != 0 or no JSON)", rate(recs, {"error"})),
    ]
    for name, (k, n) in rows:
        lines.append(f"| {name} | {fmt(k, n)} |")
    nm = [r for r in recs if not r["masses"] and "sized_without_masses" in r]
    lines.append(f"| models without masses: a gravity effect named anyway (sized without masses) | {fmt(sum(r['sized_without_masses'] for r in nm), len(nm))} |")
    lines.append(f"| models without masses: cannot_size lists a gravity effect | {fmt(sum(r['cannot_size_gravity'] for r in nm), len(nm))} |")
    mt = [r for r in recs if r["targets"] > 1 and r.get("multi_target_consistent") is not None]
    lines.append(f"| 3-reflector campaigns: per-reflector answers consistent with the whole (rule M) | {fmt(sum(bool(r['multi_target_consistent']) for r in mt), len(mt))} |")
    lines.append(f"| 3-reflector campaigns: diagnose's own targets_agree true | {fmt(sum(r.get('targets_agree') is True for r in mt), len(mt))} |")
    us = [r for r in recs if r["case"] == "understated" and "noise_factor_within_25pct" in r]
    lines.append(f"| understated noise: noise_factor within 25 % of the truth | {fmt(sum(r['noise_factor_within_25pct'] for r in us), len(us))} |")
    below = [r for r in recs if r.get("visible") is False]
    lines.append(f"| below the visibility threshold (counted apart) | {len(below)} |")
    lines += ["", "## Per case", "", "| case | category | campaigns | judgements |", "|---|---|---|---|"]
    for case in CASES:
        rs = [r for r in recs if r["case"] == case]
        if not rs:
            continue
        js = {}
        for r in rs:
            key = r.get("judgement") + (" (below floor)" if r.get("visible") is False else "")
            js[key] = js.get(key, 0) + 1
        lines.append(f"| {case} | {CASES[case][0]} | {len(rs)} | " + ", ".join(f"{k} {v}" for k, v in sorted(js.items())) + " |")
    lines += ["", "## Every campaign", "",
              "| case | variant | seed | visibility | outcome | named (equivalence sets) | cannot_size | per target | judgement |",
              "|---|---|---|---|---|---|---|---|---|"]
    for r in recs:
        a = r.get("answer") or {}
        sets = "; ".join(f"{'/'.join(s.get('members', []))}" for s in (a.get("equivalence_sets") or []) if isinstance(s, dict))
        named = ",".join(a.get("named_effects") or []) + (f" ({sets})" if sets else "")
        cs = ",".join(c.get("effect", "?") for c in (a.get("cannot_size") or []) if isinstance(c, dict))
        pt = ";".join(f"{e.get('outcome')}:{','.join(e.get('named_effects') or [])}" for e in (a.get("per_target") or []))
        v = r.get("visibility")
        lines.append(f"| {r['case']} | {r['variant']} | {r['seed']} | {'-' if v is None else f'{v:.2f}'} | "
                     f"{a.get('outcome', 'ERROR')} | {named} | {cs} | {pt} | {r.get('judgement')}"
                     + (" (below floor)" if r.get("visible") is False else "") + " |")
    tmp = os.path.join(outdir, "rates.md.tmp")
    with open(tmp, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    os.replace(tmp, os.path.join(outdir, "rates.md"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hyperstat", default=".venv/bin/hyperstat")
    ap.add_argument("--out", required=True)
    ap.add_argument("--seeds", type=int, default=DEFAULT_SEEDS)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all)")
    ap.add_argument("--limit", type=int, default=0, help="run only the first N campaigns of the list")
    args = ap.parse_args(argv)
    cases = [c for c in args.cases.split(",") if c] or None
    for c in cases or []:
        if c not in CASES:
            ap.error(f"unknown case {c!r}; known: {', '.join(CASES)}")
    hyperstat = os.path.abspath(args.hyperstat)
    os.makedirs(args.out, exist_ok=True)
    t0 = time.time()
    models = import_models(hyperstat, args.out)
    todo = campaign_list(args.seeds, cases)
    if args.limit:
        todo = todo[: args.limit]
    recs = [None] * len(todo)
    with cf.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futs = {pool.submit(one, hyperstat, args.out, models, c, v, s): i for i, (c, v, s) in enumerate(todo)}
        for n, f in enumerate(cf.as_completed(futs)):
            i = futs[f]
            recs[i] = f.result()
            print(f"[{n + 1}/{len(todo)}] {recs[i]['case']} {recs[i]['variant']} s{recs[i]['seed']}: "
                  f"{(recs[i].get('answer') or {}).get('outcome', 'ERROR')} -> {recs[i].get('judgement')}", file=sys.stderr)
    wall = time.time() - t0
    with open(os.path.join(args.out, "campaigns.json.tmp"), "w") as fh:
        json.dump({"code_sha256": code_hash(), "git_head": git_head(), "campaigns": recs}, fh, indent=1, default=str)
    os.replace(os.path.join(args.out, "campaigns.json.tmp"), os.path.join(args.out, "campaigns.json"))
    write_rates(args.out, recs, args, wall)
    print(f"wrote {args.out}/rates.md and campaigns.json ({len(recs)} campaigns, {wall:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
