"""Score hyperstat's diagnosis on the blind generator's campaigns (rules: RULES.md beside this file).

    python -m tests.solver.diagnosis.blind.score --hyperstat PATH/TO/hyperstat --out DIR \\
        [--seeds 3] [--cases a,b] [--arms ind6,cobot6] [--jobs 2] [--workdir DIR] [--limit N]

From the repository root.  Per campaign: generate (our generator, a temporary directory
unless ``--workdir``), ``hyperstat import-robot`` of the arm's URDF (once per URDF),
``hyperstat identify`` (the rigid calibration: validation RMS before, for the noise-floor
rule), ``hyperstat diagnose --json`` (the answer scored), each as a subprocess.  Writes
``DIR/rates.md`` and ``DIR/rates.json``.  Nothing here imports hyperstat.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import hashlib
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from typing import Dict, List, Optional, Tuple

import numpy as np

from .cases import CASE_BY_NAME, GRAVITY, GRAVITY_SIZED, Case, campaigns
from .generator import build, noise_rms, write

HERE = os.path.dirname(os.path.abspath(__file__))
FLOOR = 1.15          # validation RMS before / noise RMS below this: counted apart
K_TOL = 0.3           # a harmonic order named within this of the truth is the truth
OUTCOMES = ("no significant gap", "explained", "partly explained", "unexplained", "understated noise",
            "over-fitting", "inputs wrong")


# --------------------------------------------------------------------------- running

def run(cmd: List[str], log_prefix: str, timeout: float = 900.0) -> Tuple[int, float, float, str]:
    """Run ``cmd`` with stdout/stderr to files; returns (rc, wall s, CPU s of the child, stderr tail)."""
    out, err = log_prefix + ".out", log_prefix + ".err"
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    t0 = time.time()
    with open(out, "w") as fo, open(err, "w") as fe:
        p = subprocess.Popen(cmd, stdout=fo, stderr=fe, env=env)
        deadline = t0 + timeout
        rc, ru = None, None
        while True:
            pid, status, ru = os.wait4(p.pid, os.WNOHANG)
            if pid == p.pid:
                rc = os.waitstatus_to_exitcode(status)
                p.returncode = rc
                break
            if time.time() > deadline:
                p.kill()
                pid, status, ru = os.wait4(p.pid, 0)
                rc = -9
                p.returncode = rc
                break
            time.sleep(0.02)
    wall = time.time() - t0
    cpu = (ru.ru_utime + ru.ru_stime) if ru is not None else float("nan")
    with open(err) as f:
        tail = f.read()[-1500:]
    return rc, wall, cpu, tail


def read_json(path: str) -> Optional[dict]:
    try:
        with open(path) as f:
            return json.load(f)
    except Exception:
        return None


# --------------------------------------------------------------------------- the answer, normalised

def answer_of(d: Optional[dict]) -> dict:
    """The contract's keys (CONTRACT-diagnose.md), with safe defaults when a key is missing."""
    d = d or {}
    sets = []
    for s in d.get("equivalence_sets") or []:
        if isinstance(s, dict):
            sets.append({"members": [str(m) for m in (s.get("members") or [])],
                         "separating_measurement": str(s.get("separating_measurement") or "")})
    cs = []
    for c in d.get("cannot_size") or []:
        if isinstance(c, dict):
            cs.append({"effect": str(c.get("effect", "")), "field": str(c.get("field", "")), "reason": str(c.get("reason", ""))})
    return {
        "outcome": str(d.get("outcome", "")).strip().lower(),
        "named": [str(x) for x in (d.get("named_effects") or [])],
        "sets": sets,
        "ambiguous": bool(d.get("ambiguous", False)),
        "cannot_size": cs,
        "noise_factor": d.get("noise_factor"),
        "validation_factor": d.get("validation_factor"),
        "identification_factor": d.get("identification_factor"),
        "targets_agree": d.get("targets_agree"),
        "per_target": [{"target": p.get("target"), "outcome": p.get("outcome")} for p in (d.get("per_target") or [])
                       if isinstance(p, dict)],
    }


def harmonic_order(name: str) -> Optional[float]:
    m = re.fullmatch(r"angle-harmonic-([0-9]+(?:\.[0-9]+)?)", name.strip())
    return float(m.group(1)) if m else None


def matches(name: str, pattern: str, order: Optional[float] = None) -> bool:
    """``pattern`` a library name, ``angle-harmonic-*`` (any order), or ``angle-harmonic``
    with ``order`` (the order within K_TOL)."""
    if pattern == "angle-harmonic-*":
        return harmonic_order(name) is not None
    if pattern == "angle-harmonic":
        k = harmonic_order(name)
        return k is not None and (order is None or abs(k - order) <= K_TOL)
    return name.strip() == pattern


def any_match(names, patterns, order=None) -> bool:
    return any(matches(n, p, order) for n in names for p in patterns)


def members(ans: dict) -> List[str]:
    return [m for s in ans["sets"] for m in s["members"]]


def real_ambiguity(ans: dict) -> bool:
    return ans["ambiguous"] and any(len(s["members"]) > 1 for s in ans["sets"])


# --------------------------------------------------------------------------- the rules (RULES.md)

def judge(case: Case, ans: dict, crashed: bool, visible: bool) -> Tuple[str, bool]:
    """(verdict, right) of one campaign, by RULES.md."""
    if crashed:
        return "crash", False
    o = ans["outcome"]
    named = ans["named"]
    if not case.masses and any_match(named, GRAVITY_SIZED):
        return "invented mass", False
    if case.rule == "none":
        return ("right", True) if o == "no significant gap" else ("false alarm", False)
    if case.rule == "noise":
        return ("right", True) if o == "understated noise" else ("wrong", False)
    if case.rule == "in-library":
        if o in ("explained", "partly explained"):
            if any_match(named, [case.truth], case.truth_order):
                return ("named" if o == "explained" else "named (partly)"), True
            if real_ambiguity(ans) and any_match(members(ans), [case.truth], case.truth_order):
                return "named in set", True
            return "wrong effect", False
        if o == "no significant gap":
            return "missed", False
        return "wrong", False
    if case.rule == "out-of-library":
        if o in ("unexplained", "partly explained"):
            return "honest", True
        if o == "explained":
            if case.accept and any_match(named, case.accept, case.accept_order):
                return "honest (the physics named)", True
            if real_ambiguity(ans) and (any_match(members(ans), case.family) or
                                        (case.accept and any_match(members(ans), case.accept, case.accept_order))):
                return "honest (ambiguous set)", True
            return "confidently wrong", False
        if o == "understated noise":
            return "confidently wrong", False
        if o == "no significant gap":
            return "missed", False
        return "wrong", False
    if case.rule == "no-mass":
        if not any(matches(c["effect"], p) for c in ans["cannot_size"] for p in GRAVITY):
            return "no cannot_size", False
        if o in ("unexplained", "partly explained"):
            return "honest", True
        if o == "explained":
            if real_ambiguity(ans) and any_match(members(ans), GRAVITY):
                return "honest (ambiguous set)", True
            return "confidently wrong", False
        if o == "no significant gap":
            return "missed", False
        return "wrong", False
    raise ValueError(case.rule)


# --------------------------------------------------------------------------- one campaign

def one(case: Case, arm: str, seed: int, work: str, hyperstat: str, skel: str) -> dict:
    d = os.path.join(work, f"{case.name}__{arm}__s{seed}")
    t0 = time.time()
    c = build(case.name, arm, seed)
    files = write(c, d)
    gen_s = time.time() - t0
    truth = read_json(os.path.join(d, "truth.json")) or {}
    row = {"case": case.name, "arm": arm, "seed": seed, "category": case.category, "rule": case.rule,
           "size": c.size, "targets": len(c.targets), "masses": case.masses, "design": case.design,
           "noise_val_um": noise_rms(c.sigma_header, np.flatnonzero(c.is_val)) * 1e6,
           "expected_ratio": truth.get("expected_val_ratio"), "fits_within_noise": truth.get("fits_within_noise", []),
           "best_alias": (truth.get("aliases") or [{}])[0].get("candidate"), "generate_s": gen_s}
    # rigid calibration: the validation RMS before
    idj = os.path.join(d, "identify.json")
    rc, wall, cpu, tail = run([hyperstat, "identify", skel, files["data"], "--validation", files["validation"],
                               "--json", idj, "--quiet"], os.path.join(d, "identify"))
    idd = read_json(idj) if rc == 0 else None
    if idd and idd.get("validation"):
        row["val_before_um"] = idd["validation"]["rms"] * 1e3
        row["ratio"] = row["val_before_um"] / row["noise_val_um"]
    else:
        row["val_before_um"] = None
        row["ratio"] = None
        row["identify_error"] = f"rc {rc}: {tail.strip()[-300:]}"
    row["identify_wall_s"], row["identify_cpu_s"] = wall, cpu
    # the diagnosis
    dj = os.path.join(d, "diagnose.json")
    rc, wall, cpu, tail = run([hyperstat, "diagnose", skel, files["data"], "--validation", files["validation"],
                               "--json", dj, "--quiet"], os.path.join(d, "diagnose"))
    raw = read_json(dj) if rc == 0 else None
    crashed = rc != 0 or raw is None or "Traceback" in tail
    ans = answer_of(raw)
    if not crashed and ans["outcome"] not in OUTCOMES:
        crashed = True
        tail = f"outcome {ans['outcome']!r} is not one of the contract's outcomes. " + tail
    row.update({"diagnose_rc": rc, "diagnose_wall_s": wall, "diagnose_cpu_s": cpu,
                "stderr": tail.strip()[-600:] if crashed else "", "answer": ans})
    applies_floor = case.category in ("in-library", "out-of-library")
    row["visible"] = (not applies_floor) or row["ratio"] is None or row["ratio"] >= FLOOR
    row["verdict"], row["right"] = judge(case, ans, crashed, row["visible"])
    row["crashed"] = crashed
    return row


# --------------------------------------------------------------------------- rates

def rate(rows):
    n = len(rows)
    k = sum(1 for r in rows if r["right"])
    return {"right": k, "counted": n, "rate": (k / n) if n else None}


def pct(r):
    return "-" if r["rate"] is None else f"{100 * r['rate']:.0f} % ({r['right']}/{r['counted']})"


def summarise(rows: List[dict]) -> dict:
    counted = [r for r in rows if r["visible"]]
    apart = [r for r in rows if not r["visible"]]
    by_cat = {}
    for cat in ("in-library", "out-of-library", "understated-noise", "none"):
        rs = [r for r in counted if r["category"] == cat]
        by_cat[cat] = rate(rs)
        by_cat[cat]["verdicts"] = _count(r["verdict"] for r in rs)
    oo = [r for r in counted if r["category"] == "out-of-library"]
    extra = {
        "in-library named and 'explained' without ambiguity": rate([dict(r, right=r["verdict"] == "named" and not r["answer"]["ambiguous"])
                                                                     for r in counted if r["category"] == "in-library"]),
        "out-of-library confidently wrong": rate([dict(r, right=r["verdict"] in ("confidently wrong", "invented mass"))
                                                  for r in oo]),
        "out-of-library missed (no significant gap)": rate([dict(r, right=r["verdict"] == "missed") for r in oo]),
        "out-of-library, no-mass campaigns: honest": rate([r for r in oo if r["rule"] == "no-mass"]),
        "out-of-library, masses declared: honest": rate([r for r in oo if r["rule"] != "no-mass"]),
        "no-mass campaigns (all categories): cannot_size names a gravity effect": rate(
            [dict(r, right=any(matches(c["effect"], p) for c in r["answer"]["cannot_size"] for p in GRAVITY))
             for r in rows if not r["masses"] and not r["crashed"]]),
        "understated noise: noise factor within 20 % of the truth": rate(
            [dict(r, right=r["answer"]["noise_factor"] is not None and
                  abs(float(r["answer"]["noise_factor"]) / CASE_BY_NAME[r["case"]].noise_factor - 1) <= 0.2)
             for r in counted if r["category"] == "understated-noise" and r["verdict"] == "right"]),
        "multi-reflector campaigns: targets_agree true": rate(
            [dict(r, right=r["answer"]["targets_agree"] is True) for r in rows if r["targets"] > 1 and not r["crashed"]]),
        "false alarms (none campaigns not answered 'no significant gap')": {
            "right": sum(1 for r in rows if r["category"] == "none" and not r["right"]),
            "counted": sum(1 for r in rows if r["category"] == "none"), "rate": None},
    }
    per_case = {}
    for r in rows:
        key = f"{r['case']} / {r['arm']}"
        e = per_case.setdefault(key, {"case": r["case"], "arm": r["arm"], "category": r["category"], "rows": []})
        e["rows"].append(r)
    pc = {}
    for key, e in per_case.items():
        vis = [r for r in e["rows"] if r["visible"]]
        pc[key] = {"case": e["case"], "arm": e["arm"], "category": e["category"], **rate(vis),
                   "below_floor": len(e["rows"]) - len(vis), "verdicts": _count(r["verdict"] for r in vis),
                   "outcomes": _count(_short(r) for r in vis)}
    per_arm = {}
    for arm in sorted({r["arm"] for r in rows}):
        per_arm[arm] = {cat: rate([r for r in counted if r["arm"] == arm and r["category"] == cat])
                        for cat in ("in-library", "out-of-library", "understated-noise", "none")}
    return {"by_category": by_cat, "extra": extra, "per_case": pc, "per_arm": per_arm,
            "below_floor": {"campaigns": len(apart), "verdicts": _count(r["verdict"] for r in apart),
                            "acceptable": sum(1 for r in apart if r["right"] or r["answer"]["outcome"] == "no significant gap")},
            "crashes": [{"case": r["case"], "arm": r["arm"], "seed": r["seed"], "rc": r["diagnose_rc"], "stderr": r["stderr"]}
                        for r in rows if r["crashed"]]}


def _count(it):
    out: Dict[str, int] = {}
    for x in it:
        out[x] = out.get(x, 0) + 1
    return dict(sorted(out.items()))


def _short(r):
    a = r["answer"]
    s = a["outcome"] or "(none)"
    if a["named"]:
        s += ": " + "+".join(a["named"])
    if real_ambiguity(a):
        s += " [set " + "|".join(",".join(x["members"]) for x in a["sets"] if len(x["members"]) > 1) + "]"
    return s


def fmt_num(x, nd=1):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{nd}f}"


def markdown(summary: dict, rows: List[dict], meta: dict) -> str:
    L = ["# Blind validation of `hyperstat diagnose` (issue 28, item 7): rates", ""]
    L.append(f"Generator: `tests/solver/diagnosis/blind/` (sha256 of its *.py files {meta['generator_sha256'][:16]}..., "
             f"git HEAD {meta['git_head']}{' + uncommitted changes' if meta['git_dirty'] else ''}); "
             f"hyperstat: `{meta['hyperstat']}` ({meta['hyperstat_version']}).")
    L.append(f"{meta['campaigns']} campaigns ({meta['seeds']} seeds), {meta['jobs']} at a time; wall {meta['wall_s']:.0f} s, "
             f"CPU of the hyperstat subprocesses {meta['child_cpu_s']:.0f} s; load average at start {meta['load_start']}, "
             f"at end {meta['load_end']}. Rules: RULES.md (judged by score.py, written before any run).")
    L.append("")
    L.append("## Goals of issue 28 on this generator")
    L.append("")
    L.append("| goal | measured | met? |")
    L.append("|---|---|---|")
    bc = summary["by_category"]
    goals = [("out-of-library honest >= 90 %", bc["out-of-library"], 0.9),
             ("in-library named >= 95 %", bc["in-library"], 0.95),
             ("understated noise flagged >= 90 %", bc["understated-noise"], 0.9)]
    for name, r, g in goals:
        met = "-" if r["rate"] is None else ("yes" if r["rate"] >= g - 1e-12 else "no")
        L.append(f"| {name} | {pct(r)} | {met} |")
    fa = summary["extra"]["false alarms (none campaigns not answered 'no significant gap')"]
    L.append(f"| false alarms 0 | {fa['right']} of {fa['counted']} | {'yes' if fa['right'] == 0 else 'no'} |")
    L.append("")
    L.append("Counted: campaigns whose validation RMS before (hyperstat identify) is at least "
             f"{FLOOR}x the header's noise RMS (in- and out-of-library; noise cases always count). "
             f"Below that floor: {summary['below_floor']['campaigns']} campaigns, counted apart "
             f"({summary['below_floor']['acceptable']} answered 'no significant gap' or right).")
    L.append("")
    L.append("## Per category")
    L.append("")
    L.append("| category | right | verdicts |")
    L.append("|---|---|---|")
    for cat, r in bc.items():
        L.append(f"| {cat} | {pct(r)} | {', '.join(f'{k} {v}' for k, v in r['verdicts'].items())} |")
    L.append("")
    L.append("| further rate | value |")
    L.append("|---|---|")
    for k, r in summary["extra"].items():
        L.append(f"| {k} | {pct(r) if r['rate'] is not None else str(r['right']) + ' of ' + str(r['counted'])} |")
    L.append("")
    L.append("## Per arm")
    L.append("")
    L.append("| arm | in-library | out-of-library | understated-noise | none |")
    L.append("|---|---|---|---|---|")
    for arm, e in summary["per_arm"].items():
        L.append(f"| {arm} | " + " | ".join(pct(e[c]) for c in ("in-library", "out-of-library", "understated-noise", "none")) + " |")
    L.append("")
    L.append("## Per case")
    L.append("")
    L.append("| case | arm | category | right (counted) | below floor | answers |")
    L.append("|---|---|---|---|---|---|")
    for key, e in summary["per_case"].items():
        L.append(f"| {e['case']} | {e['arm']} | {e['category']} | {pct(e)} | {e['below_floor']} | "
                 f"{'; '.join(f'{k} x{v}' for k, v in e['outcomes'].items())} |")
    L.append("")
    L.append("## Every campaign")
    L.append("")
    L.append("Val. before: validation RMS of the rigid calibration (hyperstat identify), um; noise: the header's noise RMS "
             "on the validation poses, um; expected: our own prediction of that ratio (rigid.py); ours within noise: "
             "library-like candidates that fit the effect within the noise by our own fit (informational).")
    L.append("")
    L.append("| case | arm | seed | category | size | outcome | named | ambiguous / sets | cannot_size | val. before (um) | noise (um) | ratio | expected | counted | verdict | ours within noise | diagnose wall / CPU (s) |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        a = r["answer"]
        sets = "; ".join(",".join(s["members"]) for s in a["sets"]) or "-"
        cs = ",".join(c["effect"] for c in a["cannot_size"]) or "-"
        fw = ",".join(r["fits_within_noise"][:3]) or "-"
        L.append(f"| {r['case']} | {r['arm']} | {r['seed']} | {r['category']} | {r['size']} | {a['outcome'] or '(none)'} | "
                 f"{'+'.join(a['named']) or '-'} | {a['ambiguous']} / {sets} | {cs} | {fmt_num(r['val_before_um'])} | "
                 f"{fmt_num(r['noise_val_um'])} | {fmt_num(r['ratio'], 2)} | {fmt_num(r['expected_ratio'], 2)} | "
                 f"{'yes' if r['visible'] else 'below floor'} | {r['verdict']} | {fw} | "
                 f"{fmt_num(r['diagnose_wall_s'])} / {fmt_num(r['diagnose_cpu_s'])} |")
    L.append("")
    if summary["crashes"]:
        L.append("## Crashes, tracebacks, non-zero exits (counted as wrong)")
        L.append("")
        for c in summary["crashes"]:
            L.append(f"* {c['case']} / {c['arm']} / seed {c['seed']}: exit {c['rc']}: `{c['stderr'][-300:]}`")
        L.append("")
    return "\n".join(L) + "\n"


# --------------------------------------------------------------------------- provenance

def generator_sha256() -> str:
    h = hashlib.sha256()
    for name in sorted(os.listdir(HERE)):
        if name.endswith(".py"):
            with open(os.path.join(HERE, name), "rb") as f:
                h.update(name.encode() + b"\0" + f.read())
    return h.hexdigest()


def git_state() -> Tuple[str, bool]:
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=HERE, capture_output=True, text=True).stdout.strip()
        dirty = bool(subprocess.run(["git", "status", "--porcelain", "."], cwd=HERE, capture_output=True, text=True).stdout.strip())
        return head or "unknown", dirty
    except Exception:
        return "unknown", True


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Score hyperstat diagnose on the blind generator (issue 28).")
    ap.add_argument("--hyperstat", required=True, help="path of the hyperstat executable")
    ap.add_argument("--out", required=True, help="directory for rates.md and rates.json")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all)")
    ap.add_argument("--arms", default="", help="comma-separated arms (default: all)")
    ap.add_argument("--jobs", type=int, default=2, help="campaigns run at once (default 2)")
    ap.add_argument("--workdir", default="", help="keep the campaign files here (default: a temporary directory)")
    ap.add_argument("--limit", type=int, default=0, help="only the first N campaigns (smoke runs)")
    a = ap.parse_args(argv)
    names = [x for x in a.cases.split(",") if x]
    unknown = [x for x in names if x not in CASE_BY_NAME]
    if unknown:
        print(f"score: unknown case(s) {unknown}; known: {', '.join(CASE_BY_NAME)}", file=sys.stderr)
        return 2
    todo = campaigns(a.seeds, names or None)
    if a.arms:
        arms = a.arms.split(",")
        todo = [t for t in todo if t[1] in arms]
    if a.limit:
        todo = todo[:a.limit]
    os.makedirs(a.out, exist_ok=True)
    hs = os.path.abspath(a.hyperstat)
    ver = subprocess.run([hs, "--version"], capture_output=True, text=True).stdout.strip()
    work = a.workdir or tempfile.mkdtemp(prefix="blind28_")
    os.makedirs(work, exist_ok=True)
    load_start = " ".join(f"{x:.2f}" for x in os.getloadavg())
    t0 = time.time()
    # one model file per URDF (arm, with or without masses)
    from .kinematics import get_arm, write_urdf
    skels = {}
    child_cpu = 0.0
    import_errors = {}
    for case, arm, seed in todo:
        key = (arm, case.masses)
        if key in skels or key in import_errors:
            continue
        md = os.path.join(work, "models")
        os.makedirs(md, exist_ok=True)
        urdf = os.path.join(md, f"{arm}{'' if case.masses else '_nomass'}.urdf")
        write_urdf(get_arm(arm), urdf, with_masses=case.masses)
        skel = urdf[:-5] + ".skel.json"
        rc, wall, cpu, tail = run([hs, "import-robot", urdf, "--out", skel, "--quiet"], urdf[:-5] + ".import")
        child_cpu += cpu
        if rc != 0:
            import_errors[key] = f"import-robot exit {rc}: {tail.strip()[-300:]}"
        else:
            skels[key] = skel
    rows: List[dict] = []

    def task(t):
        case, arm, seed = t
        key = (arm, case.masses)
        if key in import_errors:
            return {"case": case.name, "arm": arm, "seed": seed, "category": case.category, "rule": case.rule,
                    "size": "-", "targets": case.targets, "masses": case.masses, "design": case.design,
                    "noise_val_um": None, "expected_ratio": None, "fits_within_noise": [], "best_alias": None,
                    "val_before_um": None, "ratio": None, "visible": True, "diagnose_rc": None,
                    "diagnose_wall_s": None, "diagnose_cpu_s": 0.0, "identify_cpu_s": 0.0,
                    "stderr": import_errors[key], "answer": answer_of(None), "verdict": "crash", "right": False,
                    "crashed": True}
        return one(case, arm, seed, work, hs, skels[key])

    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
        futs = {ex.submit(task, t): t for t in todo}
        for i, f in enumerate(concurrent.futures.as_completed(futs)):
            case, arm, seed = futs[f]
            try:
                r = f.result()
            except Exception as e:  # a generator failure is ours: stop loudly
                raise RuntimeError(f"campaign {case.name}/{arm}/{seed} could not be generated or scored") from e
            rows.append(r)
            print(f"[{i + 1}/{len(todo)}] {case.name} {arm} s{seed} done ({time.time() - t0:.0f} s)", file=sys.stderr)
    order = {(c.name, arm, s): i for i, (c, arm, s) in enumerate(todo)}
    rows.sort(key=lambda r: order[(r["case"], r["arm"], r["seed"])])
    child_cpu += sum((r.get("identify_cpu_s") or 0.0) + (r.get("diagnose_cpu_s") or 0.0) for r in rows)
    head, dirty = git_state()
    meta = {"generator_sha256": generator_sha256(), "git_head": head, "git_dirty": dirty, "hyperstat": hs,
            "hyperstat_version": ver, "seeds": a.seeds, "campaigns": len(rows), "jobs": a.jobs,
            "wall_s": time.time() - t0, "child_cpu_s": child_cpu, "load_start": load_start,
            "load_end": " ".join(f"{x:.2f}" for x in os.getloadavg()), "floor": FLOOR, "workdir": work if a.workdir else None}
    summary = summarise(rows)
    with open(os.path.join(a.out, "rates.json.tmp"), "w") as f:
        json.dump({"meta": meta, "summary": summary, "campaigns": rows}, f, indent=1, default=str)
    os.replace(os.path.join(a.out, "rates.json.tmp"), os.path.join(a.out, "rates.json"))
    with open(os.path.join(a.out, "rates.md.tmp"), "w") as f:
        f.write(markdown(summary, rows, meta))
    os.replace(os.path.join(a.out, "rates.md.tmp"), os.path.join(a.out, "rates.md"))
    if not a.workdir:
        shutil.rmtree(work, ignore_errors=True)
    print(f"wrote {os.path.join(a.out, 'rates.md')} and rates.json ({len(rows)} campaigns, {meta['wall_s']:.0f} s)",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
