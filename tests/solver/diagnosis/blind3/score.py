"""Scorer of the fifth blind generator: generate the campaigns, run ``hyperstat diagnose`` on each
as a black box, judge each answer by RULES.md, write ``rates.md``.

    python -m tests.solver.diagnosis.blind3.score --hyperstat .venv/bin/hyperstat --out out/blind3 --jobs 2

Options: ``--seeds 0,1`` (the run of record: the default), ``--only PATTERN`` (campaigns whose
``family/case`` contains PATTERN, comma-separated; for smoke runs), ``--no-diagnose`` (generate
and run the visibility check only: a self-check of the generator that never calls diagnose).

Per campaign the scorer runs two commands: ``hyperstat identify`` on the noise-free copy of the
campaign (the visibility check: how much of the effect a rigid calibration cannot absorb, RULES.md)
and ``hyperstat diagnose`` on the noisy files (the answer judged).  Nothing is imported from
hyperstat.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import multiprocessing as mp
import os
import resource
import subprocess
import sys
import time

from . import generator

HERE = os.path.dirname(os.path.abspath(__file__))
VISIBLE = 0.6            # noise-free rigid residual / stated noise (RMS, 3-D) at or above: visible
DEFAULT_SEEDS = (0, 1)
TARGETS = {"in_serial": 0.95, "in_parallel": 0.95, "out_honest": 0.95}

_FAMILIES = {}
_CFG = {}


def code_hash():
    """SHA-256 over the directory's *.py files (sorted by name; name, NUL, bytes, NUL each)."""
    h = hashlib.sha256()
    per = {}
    for name in sorted(f for f in os.listdir(HERE) if f.endswith(".py")):
        with open(os.path.join(HERE, name), "rb") as fh:
            data = fh.read()
        per[name] = hashlib.sha256(data).hexdigest()
        h.update(name.encode() + b"\0" + data + b"\0")
    return h.hexdigest(), per


def _env():
    env = dict(os.environ)
    for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[k] = "1"
    return env


def _run(cmd, timeout):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.time()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=_env())
        rc, err = p.returncode, p.stderr[-2000:]
    except subprocess.TimeoutExpired:
        rc, err = "timeout", ""
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return rc, err, time.time() - t0, cpu


def _family(name):
    if name not in _FAMILIES:
        _FAMILIES[name] = generator.load_family(name, _CFG["models"], _CFG["hyperstat"], _CFG["repo"])
    return _FAMILIES[name]


def _init(cfg):
    _CFG.update(cfg)


def run_task(task):
    family, case_name, seed = task
    case = {c.name: c for c in generator.all_cases() if c.family == family}[case_name]
    fam = _family(family)
    outdir = os.path.join(_CFG["out"], "campaigns", family, case_name, f"s{seed}")
    t0, c0 = time.time(), time.process_time()
    try:
        camp = generator.generate(fam, case, seed, outdir)
    except Exception as exc:          # a generator failure is the generator's, never hyperstat's
        return {"family": family, "case": case_name, "seed": seed, "category": case.category,
                "kind": fam.kind, "truth": [], "cover": [], "effects": [], "dir": outdir,
                "generator_error": f"{type(exc).__name__}: {exc}"}
    gen_s, gen_cpu = time.time() - t0, time.process_time() - c0
    hs = _CFG["hyperstat"]
    res = {"family": family, "case": case_name, "seed": seed, "category": case.category,
           "kind": camp.truth["kind"], "truth": camp.truth["truth"], "cover": camp.truth["cover"],
           "effects": camp.truth["effects"], "generate_s": round(gen_s, 2), "generate_cpu_s": round(gen_cpu, 2),
           "dir": outdir}
    # visibility (effect campaigns): the rigid calibration of the noise-free copy
    if case.category in ("in", "out"):
        id_json = os.path.join(outdir, "identify_noise_free.json")
        rc, err, wall, cpu = _run([hs, "identify", fam.model_path, camp.files["nf"], "--validation",
                                   camp.files["nf.validation"], "--json", id_json, "--quiet"], 900)
        res["identify_cpu_s"] = round(cpu, 1)
        res["visibility"] = visibility(id_json) if rc == 0 else None
        res["identify_error"] = None if rc == 0 else f"{rc}: {err.strip()[-300:]}"
    if _CFG["diagnose"]:
        d_json = os.path.join(outdir, "diagnose.json")
        rc, err, wall, cpu = _run([hs, "diagnose", fam.model_path, camp.files["data"], "--validation",
                                   camp.files["data.validation"], "--json", d_json, "--quiet"], 1500)
        res["diagnose_wall_s"] = round(wall, 1)
        res["diagnose_cpu_s"] = round(cpu, 1)
        if rc == 0 and os.path.exists(d_json):
            with open(d_json) as fh:
                res["answer"] = summarize(json.load(fh))
        else:
            res["answer"] = {"outcome": f"error ({rc})", "error": err.strip()[-500:]}
    return res


def visibility(path):
    with open(path) as fh:
        j = json.load(fh)
    out = {"position": None, "orientation": None}
    if j.get("noise_rms"):
        out["position"] = j["identification"]["rms"] / j["noise_rms"]
    ori = j.get("orientation")
    if ori and ori.get("noise_rms"):
        out["orientation"] = ori["identification"]["rms"] / ori["noise_rms"]
    vals = [v for v in out.values() if v is not None]
    out["ratio"] = max(vals) if vals else None
    return out


def summarize(d):
    keys = ("outcome", "named_effects", "equivalence_sets", "ambiguous", "effect_joints", "confidence",
            "targets_agree", "noise_factor", "validation_factor", "identification_factor", "cannot_size")
    s = {k: d.get(k) for k in keys}
    s["per_target"] = [{"target": t.get("target"), "outcome": t.get("outcome"), "named_effects": t.get("named_effects")}
                       for t in (d.get("per_target") or [])]
    s["rejected"] = [{"effect": r.get("effect"), "stage": r.get("stage")} for r in (d.get("rejected") or [])][:12]
    return s


# ---------------------------------------------------------------------- judging (RULES.md)
def _matches(name, t):
    eff = t["effect"]
    if eff.startswith("angle-harmonic-"):
        if not isinstance(name, str) or not name.startswith("angle-harmonic-"):
            return False
        try:
            k = float(name[len("angle-harmonic-"):])
        except ValueError:
            return False
        return abs(k - float(t["order"])) <= 0.1 + 1e-9
    return name == eff


def judge_truth(ans, t):
    """'named' (a named effect, on a true joint when the answer gives joints), 'in set' (a member of
    a named effect's equivalence set that states its separating measurement), 'wrong joint', None."""
    named = ans.get("named_effects") or []
    joints = ans.get("effect_joints") or {}
    wrong_joint = False
    for x in named:
        if _matches(x, t):
            ej = joints.get(x)
            if ej is None or not t["joints"] or {str(j) for j in ej} & {str(j) for j in t["joints"]}:
                return "named"
            wrong_joint = True
    for eq in ans.get("equivalence_sets") or []:
        members = eq.get("members") or []
        if any(_matches(m, t) for m in members[1:]) and (eq.get("separating_measurement") or "").strip():
            return "in set"
    return "wrong joint" if wrong_joint else None


def judge(res):
    if res.get("generator_error"):
        res["visible"] = None
        res["verdict"] = "GENERATOR ERROR (not counted)"
        return res
    ans = res.get("answer") or {}
    cat = res["category"]
    out = ans.get("outcome")
    vis = (res.get("visibility") or {}).get("ratio")
    res["visible"] = None if cat in ("none", "understated") else (vis is not None and vis >= VISIBLE)
    if cat == "none":
        res["verdict"] = "ok" if out == "no significant gap" else "FALSE ALARM"
        res["effect_claimed"] = bool(ans.get("named_effects")) or out in ("explained", "partly explained")
    elif cat == "understated":
        res["verdict"] = "flagged" if out == "understated noise" else "NOT FLAGGED"
    elif cat == "in":
        per = [judge_truth(ans, t) for t in res["truth"]]
        res["per_truth"] = per
        ok = all(p in ("named", "in set") for p in per)
        res["verdict"] = "named" if ok else "MISSED"
    else:
        cover = set(res["cover"])
        named = ans.get("named_effects") or []
        members = set(named)
        for eq in ans.get("equivalence_sets") or []:
            members |= set(eq.get("members") or [])
        if out in ("unexplained", "partly explained"):
            res["verdict"] = "honest"
        elif out == "explained" and members & cover:
            res["verdict"] = "honest (covered)"
        elif out == "explained" and ans.get("confidence") == "low":
            res["verdict"] = "honest (low confidence)"
        elif out == "explained":
            res["verdict"] = "CONFIDENTLY WRONG"
        else:
            res["verdict"] = f"NOT HONEST ({out})"
    return res


def rates(results):
    def frac(items, pred):
        n = len(items)
        k = sum(1 for r in items if pred(r))
        return k, n

    r = {}
    r["generator_errors"] = frac([x for x in results if x.get("generator_error")], lambda x: True)
    results = [x for x in results if not x.get("generator_error")]
    ins = [x for x in results if x["category"] == "in" and x["visible"]]
    r["in_serial"] = frac([x for x in ins if x["kind"] == "serial"], lambda x: x["verdict"] == "named")
    r["in_parallel"] = frac([x for x in ins if x["kind"] == "parallel"], lambda x: x["verdict"] == "named")
    outs = [x for x in results if x["category"] == "out" and x["visible"]]
    r["out_honest"] = frac(outs, lambda x: x["verdict"].startswith("honest"))
    r["out_honest_strict"] = frac(outs, lambda x: x["verdict"] in ("honest", "honest (covered)"))
    nones = [x for x in results if x["category"] == "none"]
    r["false_alarms"] = frac(nones, lambda x: x["verdict"] != "ok")
    r["effect_claimed_on_none"] = frac(nones, lambda x: x.get("effect_claimed"))
    und = [x for x in results if x["category"] == "understated"]
    r["understated_flagged"] = frac(und, lambda x: x["verdict"] == "flagged")
    r["in_below_visibility"] = frac([x for x in results if x["category"] == "in" and not x["visible"]], lambda x: True)
    r["out_below_visibility"] = frac([x for x in results if x["category"] == "out" and not x["visible"]], lambda x: True)
    r["in_named_all_incl_invisible"] = frac([x for x in results if x["category"] == "in"], lambda x: x["verdict"] == "named")
    return r


def _pct(k, n):
    return f"{100.0 * k / n:.0f} % ({k}/{n})" if n else "- (0/0)"


def write_rates(results, path, meta):
    rt = rates(results)
    L = ["# Fifth blind generator (blind3): rates of one run", ""]
    L += [f"* command: `{meta['command']}`", f"* code SHA-256 (*.py of tests/solver/diagnosis/blind3): `{meta['code_hash']}`"]
    for name, h in meta["per_file"].items():
        L.append(f"  * `{name}`: `{h}`")
    L += [f"* repository commit: `{meta['commit']}`; hyperstat: `{meta['version']}`",
          f"* started {meta['start']}, wall clock {meta['wall_s']:.0f} s with {meta['jobs']} jobs; "
          f"CPU of the diagnose subprocesses {meta['diag_cpu']:.0f} s, of identify (visibility) {meta['id_cpu']:.0f} s, "
          f"of the generator {meta['gen_cpu']:.0f} s; "
          f"load average at the end {meta['load']}",
          f"* campaigns: {len(results)} (seeds {meta['seeds']}); visibility line: noise-free rigid residual "
          f">= {VISIBLE} x the stated noise (RMS)", ""]
    L += ["## Rates (RULES.md)", "", "| rate | measured | must show | met? |", "|---|---|---|---|"]

    def row(label, key, target=None, zero=False):
        k, n = rt[key]
        if zero:
            met = "yes" if k == 0 else "**no**"
            tgt = "0"
        elif target is not None:
            met = "yes" if n and k / n >= target else "**no**"
            tgt = f">= {100 * target:.0f} %"
        else:
            met, tgt = "", ""
        L.append(f"| {label} | {_pct(k, n)} | {tgt} | {met} |")

    row("in-library named, serial arms (visible)", "in_serial", TARGETS["in_serial"])
    row("in-library named, parallel machines (visible)", "in_parallel", TARGETS["in_parallel"])
    row("out-of-library honest (visible)", "out_honest", TARGETS["out_honest"])
    row("false alarms (no-effect campaigns not answered 'no significant gap')", "false_alarms", zero=True)
    k, n = rt["understated_flagged"]
    L.append(f"| understated noise flagged | {_pct(k, n)} | flagged | {'yes' if n and k == n else '**no**'} |")
    row("(out-of-library honest without the low-confidence allowance)", "out_honest_strict")
    row("(no-effect campaigns with an effect claimed)", "effect_claimed_on_none")
    row("(in-library named, all campaigns, visible or not)", "in_named_all_incl_invisible")
    row("(in-library campaigns below the visibility line)", "in_below_visibility")
    row("(out-of-library campaigns below the visibility line)", "out_below_visibility")
    row("(campaigns the generator failed to make: not counted)", "generator_errors")
    L.append("")
    # per family and category
    L += ["## Per family", "", "| family | category | campaigns | visible | verdicts |", "|---|---|---|---|---|"]
    fams = sorted({x["family"] for x in results})
    for f in fams:
        for cat in ("none", "understated", "in", "out"):
            xs = [x for x in results if x["family"] == f and x["category"] == cat]
            if not xs:
                continue
            vis = sum(1 for x in xs if x["visible"] in (True, None))
            counts = {}
            for x in xs:
                counts[x["verdict"]] = counts.get(x["verdict"], 0) + 1
            L.append(f"| {f} | {cat} | {len(xs)} | {vis} | " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) + " |")
    L.append("")
    L += ["## Every campaign", "",
          "| family | case | seed | cat | visibility | outcome | named (joints) | sets | conf. | targets agree | noise factor | verdict | diag CPU s |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for x in sorted(results, key=lambda r: (r["family"], r["category"], r["case"], r["seed"])):
        a = x.get("answer") or {}
        v = (x.get("visibility") or {}).get("ratio")
        named = a.get("named_effects") or []
        ej = a.get("effect_joints") or {}
        nm = ", ".join(f"{n}" + (f" ({','.join(map(str, ej[n]))})" if n in ej else "") for n in named) or "-"
        sets = "; ".join("{" + ", ".join(e.get("members") or []) + "}" for e in (a.get("equivalence_sets") or [])
                         if len(e.get("members") or []) > 1) or "-"
        nf = a.get("noise_factor")
        vis_s = f"{v:.2f}" + ("" if x["visible"] in (True, None) else " (below)") if v is not None else "?"
        L.append(f"| {x['family']} | {x['case']} | {x['seed']} | {x['category']} | {vis_s} | {a.get('outcome')} | {nm} | "
                 f"{sets} | {a.get('confidence')} | {a.get('targets_agree')} | "
                 f"{'' if nf is None else f'{nf:.2f}'} | {x['verdict']} | {x.get('diagnose_cpu_s', '')} |")
    L.append("")
    L += ["## Truth of every campaign (the generator's effects, drawn magnitudes)", ""]
    for x in sorted(results, key=lambda r: (r["family"], r["category"], r["case"], r["seed"])):
        L.append(f"* {x['family']} / {x['case']} / s{x['seed']}: " + ("; ".join(x["effects"]) or "no effect")
                 + (f"; truth {[t['effect'] + str(t['joints']) for t in x['truth']]}" if x["truth"] else "")
                 + (f"; cover {x['cover']}" if x["cover"] else ""))
    with open(path + ".part", "w") as fh:
        fh.write("\n".join(L) + "\n")
    os.replace(path + ".part", path)
    return rt


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hyperstat", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--seeds", default=",".join(str(s) for s in DEFAULT_SEEDS))
    ap.add_argument("--only", default=None)
    ap.add_argument("--no-diagnose", action="store_true")
    ap.add_argument("--repo", default=".")
    args = ap.parse_args(argv)
    start = time.time()
    hs = os.path.abspath(args.hyperstat) if os.path.exists(args.hyperstat) else args.hyperstat
    out = os.path.abspath(args.out)
    models = os.path.join(out, "models")
    os.makedirs(models, exist_ok=True)
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    cfg = {"hyperstat": hs, "out": out, "models": models, "repo": os.path.abspath(args.repo),
           "diagnose": not args.no_diagnose}
    _init(cfg)
    for name in ("kr_like", "lbr_like", "tripteor_x7", "hexapod"):
        _family(name)                 # model files written once, before the workers start
    tasks = []
    for seed in seeds:
        for c in generator.all_cases():
            key = f"{c.family}/{c.name}"
            if args.only and not any(p in key for p in args.only.split(",")):
                continue
            tasks.append((c.family, c.name, seed))
    # the parallel machines first (longest), so that the two workers finish together
    order = {"hexapod": 0, "tripteor_x7": 1, "kr_like": 2, "lbr_like": 3}
    tasks.sort(key=lambda t: (order[t[0]], t[2]))
    results = []
    ctx = mp.get_context("fork")
    with ctx.Pool(args.jobs, initializer=_init, initargs=(cfg,)) as pool:
        for k, res in enumerate(pool.imap_unordered(run_task, tasks), start=1):
            results.append(res)
            a = res.get("answer") or {}
            v = (res.get("visibility") or {}).get("ratio")
            print(f"[{k}/{len(tasks)}] {res['family']}/{res['case']}/s{res['seed']}: visibility "
                  f"{'?' if v is None else f'{v:.2f}'}" + (f", {a.get('outcome')}" if cfg["diagnose"] else "")
                  + f" ({time.time() - start:.0f} s)", flush=True)
    for r in results:
        judge(r)
    h, per = code_hash()
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=HERE).stdout.strip()
    except OSError:
        commit = "?"
    try:
        version = subprocess.run([hs, "--version"], capture_output=True, text=True).stdout.strip()
    except OSError:
        version = "?"
    meta = {"command": " ".join([os.path.basename(sys.executable), "-m", "tests.solver.diagnosis.blind3.score"] + (argv or sys.argv[1:])),
            "code_hash": h, "per_file": per, "commit": commit, "version": version,
            "start": datetime.datetime.fromtimestamp(start).isoformat(timespec="seconds"),
            "wall_s": time.time() - start, "jobs": args.jobs, "seeds": seeds,
            "diag_cpu": sum(r.get("diagnose_cpu_s") or 0 for r in results),
            "gen_cpu": sum(r.get("generate_cpu_s") or 0 for r in results),
            "id_cpu": sum(r.get("identify_cpu_s") or 0 for r in results), "load": " ".join(f"{x:.1f}" for x in os.getloadavg())}
    with open(os.path.join(out, "results.json"), "w") as fh:
        json.dump({"meta": meta, "results": results}, fh, indent=1, default=str)
    rt = write_rates(results, os.path.join(out, "rates.md"), meta)
    print(f"wrote {os.path.join(out, 'rates.md')}")
    for k, (a, n) in rt.items():
        print(f"  {k}: {a}/{n}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
