"""Run of record of the blind6 set: generate, run `hyperstat diagnose` per campaign, judge, write rates.md.

`python -m tests.solver.diagnosis.blind6.score --hyperstat PATH [--out out/blind6] [--seed 0] [--jobs 2]
[--timeout 1200] [--cases a,b]`.  PATH is the `hyperstat` executable of the checkout under test, or the
checkout (holding `.venv/bin/hyperstat`).  Judging rules: RULES.md (applied by `judge`).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from .cases import C, CASES
from .generate import FAMILIES, HERE, VISIBILITY_LINE, generate

SERIAL = {"st6", "abb6", "pal4"}
PARALLEL = {"tx7", "hexa"}
NAMED_OUTCOMES = ("explained", "partly explained")


def sources_sha256():
    """SHA-256 over this directory's *.py, robots/*.yaml and models/*.json (sorted by name, name and bytes)."""
    h = hashlib.sha256()
    files = sorted(list(HERE.glob("*.py")) + list(HERE.glob("robots/*.yaml")) + list(HERE.glob("models/*.json")))
    for f in files:
        h.update(str(f.relative_to(HERE)).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def _same(a, b):
    ha, hb = re.fullmatch(r"angle-harmonic-([0-9.]+)", a or ""), re.fullmatch(r"angle-harmonic-([0-9.]+)", b or "")
    if ha and hb:
        return abs(float(ha.group(1)) - float(hb.group(1))) < 0.01
    return a == b


def judge(truth, res):
    """The verdict of one campaign by RULES.md; `res` is diagnose's JSON (None on a failure)."""
    kind = truth["kind"]
    v = dict(case=truth["case"], family=truth["family"], kind=kind, truth=truth.get("truth"),
             visibility=truth.get("visibility"), counted=True)
    if kind in ("in", "out") and truth.get("visibility") is not None and truth["visibility"] < VISIBILITY_LINE:
        v["counted"] = False
    if res is None:
        v.update(outcome="FAILURE", confidence="-", named=[], members=[], ok=False, confidently_wrong=False, joints="-")
        return v
    out, conf = res.get("outcome"), res.get("confidence")
    named = list(res.get("named_effects") or [])
    members = list(named)
    for s in res.get("equivalence_sets") or []:
        members += list(s.get("members") or [])
    v.update(outcome=out, confidence=conf, named=named, members=sorted(set(members)))
    t = truth.get("truth")
    if kind == "in":
        hit = out in NAMED_OUTCOMES and any(_same(t, m) for m in members)
        v["ok"] = hit
        v["outright"] = (out == "explained" and any(_same(t, m) for m in named) and not res.get("ambiguous")
                         and conf == "high")
        v["confidently_wrong"] = out in NAMED_OUTCOMES and conf == "high" and not hit and out == "explained"
        ej = res.get("effect_joints") or {}
        got = None
        for k_, js in ej.items():
            if _same(t, k_):
                got = set(str(j) for j in js)
        want = set(truth.get("joints") or [])
        if not hit or not want:
            v["joints"] = "-"
        elif got is None:
            v["joints"] = "none given"
        else:
            v["joints"] = "yes" if got == want else ("part" if got & want else "no")
    elif kind == "out":
        v["ok"] = out in ("unexplained", "partly explained") or (out == "explained" and conf == "low")
        v["confidently_wrong"] = (out == "explained" and conf == "high") or out == "understated noise"
        v["joints"] = "-"
    elif kind == "none":
        v["ok"] = out == "no significant gap"  # ok = no false alarm
        v["confidently_wrong"] = False
        v["joints"] = "-"
    else:
        v["ok"] = out == "understated noise"  # flagged
        v["confidently_wrong"] = False
        v["noise_factor"] = res.get("noise_factor")
        v["joints"] = "-"
    return v


def find_hyperstat(path):
    p = Path(path)
    if p.is_dir():
        p = p / ".venv" / "bin" / "hyperstat"
    if not p.exists():
        sys.exit("score: no hyperstat executable at %s" % p)
    return p.resolve()


def run_one(hs, camp, truth, timeout):
    model = HERE / "models" / FAMILIES[truth["family"]]["model"]
    out = camp / "diagnosis.json"
    if out.exists():
        out.unlink()
    cmd = ["nice", "-n", "5", str(hs), "diagnose", str(model), str(camp / "data.csv"),
           "--validation", str(camp / "val.csv"), "--json", str(out), "--quiet"]
    t0 = time.time()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        rc, err = p.returncode, p.stderr[-600:]
    except subprocess.TimeoutExpired:
        rc, err = "timeout", "more than %d s" % timeout
    dt = time.time() - t0
    res = None
    if rc == 0 and out.exists():
        try:
            res = json.loads(out.read_text())
        except ValueError:
            res = None
    (camp / "run.json").write_text(json.dumps(dict(cmd=cmd, rc=rc, seconds=round(dt, 1), stderr=err), indent=1))
    return res, rc, dt, err


def rate(vs, pred):
    sel = [v for v in vs if pred(v) and v["counted"]]
    n = sum(1 for v in sel if v["ok"])
    return n, len(sel), (100.0 * n / len(sel) if sel else float("nan"))


def write_rates(path, vs, meta):
    L = ["# blind6 (eighth blind generator): rates of the run", "",
         "Units: mm, rad, s.  Rules: `tests/solver/diagnosis/blind6/RULES.md` (fixed before any run).", ""]
    for k, val in meta.items():
        L.append("* %s: `%s`" % (k, val))
    L.append("")
    rows = [
        ("in the library, named: parallel (tx7, hexa)", lambda v: v["kind"] == "in" and v["family"] in PARALLEL, ">= 95 %"),
        ("in the library, named: serial (st6, abb6, pal4)", lambda v: v["kind"] == "in" and v["family"] in SERIAL, ">= 95 %"),
        ("out of the library, honest", lambda v: v["kind"] == "out", ">= 95 %"),
        ("no effect: no false alarm", lambda v: v["kind"] == "none", "100 % (false alarms 0)"),
        ("understated noise: flagged", lambda v: v["kind"] == "under", "flagged"),
    ]
    L += ["| rate | count | % | must-show |", "|---|---|---|---|"]
    for name, pred, goal in rows:
        n, d, pc = rate(vs, pred)
        L.append("| %s | %d / %d | %.1f | %s |" % (name, n, d, pc, goal))
    fa = sum(1 for v in vs if v["kind"] == "none" and not v["ok"])
    cw = sum(1 for v in vs if v.get("confidently_wrong") and v["counted"])
    outright = sum(1 for v in vs if v["kind"] == "in" and v.get("outright") and v["counted"])
    nin = sum(1 for v in vs if v["kind"] == "in" and v["counted"])
    fails = sum(1 for v in vs if v["outcome"] == "FAILURE")
    below = [v["case"] for v in vs if not v["counted"]]
    L += ["", "* false alarms: %d" % fa, "* confidently wrong (in: explained, high, truth in no set; out: explained high or understated noise): %d" % cw,
          "* in the library, named outright: %d / %d" % (outright, nin), "* diagnose failures (non-zero exit, no JSON, timeout): %d" % fails,
          "* below the visibility line %.1f (listed, not counted): %s" % (VISIBILITY_LINE, ", ".join(below) or "none"), ""]
    L += ["| # | case | family | kind | truth | visibility | outcome | confidence | named | set members | joints | verdict | seconds |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for i, v in enumerate(vs, 1):
        verdict = {"in": "named" if v["ok"] else "MISSED", "out": "honest" if v["ok"] else "NOT HONEST",
                   "none": "no alarm" if v["ok"] else "FALSE ALARM", "under": "flagged" if v["ok"] else "NOT FLAGGED"}[v["kind"]]
        if v.get("confidently_wrong"):
            verdict += ", confidently wrong"
        if not v["counted"]:
            verdict += " (below line)"
        if v["kind"] == "under" and v.get("noise_factor"):
            verdict += " (factor %.2f)" % v["noise_factor"]
        L.append("| %d | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            i, v["case"], v["family"], v["kind"], v["truth"] or "-", v["visibility"] if v["visibility"] is not None else "-",
            v["outcome"], v["confidence"], ", ".join(v["named"]) or "-", ", ".join(v["members"]) or "-",
            v.get("joints", "-"), verdict, v.get("seconds", "-")))
    tmp = Path(str(path) + ".tmp")
    tmp.write_text("\n".join(L) + "\n")
    os.replace(tmp, path)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m tests.solver.diagnosis.blind6.score",
                                 description="generate the blind6 campaigns, run hyperstat diagnose on each, judge, write rates.md")
    ap.add_argument("--hyperstat", required=True, help="hyperstat executable, or the checkout holding .venv/bin/hyperstat")
    ap.add_argument("--out", default="out/blind6")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=1200.0, help="per campaign, s")
    ap.add_argument("--cases", default="", help="comma-separated case names (default: all 72)")
    a = ap.parse_args(argv)
    hs = find_hyperstat(a.hyperstat)
    out = Path(a.out)
    camps = out / "campaigns"
    names = [s for s in a.cases.split(",") if s] or [c["name"] for c in C]
    for n in names:
        if n not in CASES:
            sys.exit("score: unknown case %r" % n)
    t0 = time.time()
    truths = {t["case"]: t for t in generate(camps, a.seed, names, a.jobs, True)}
    t_gen = time.time() - t0
    order = sorted(names, key=lambda n: (CASES[n]["family"] != "hexa", names.index(n)))  # longest first

    def work(n):
        return n, run_one(hs, camps / n, truths[n], a.timeout)

    results = {}
    with ThreadPoolExecutor(a.jobs) as ex:
        for n, (res, rc, dt, err) in ex.map(work, order):
            results[n] = (res, rc, dt)
            print("%-20s rc=%s %6.1f s %s" % (n, rc, dt, (res or {}).get("outcome", "FAILURE")), flush=True)
    vs = []
    for n in names:
        v = judge(truths[n], results[n][0])
        v["seconds"] = round(results[n][2], 1)
        vs.append(v)
    try:
        rev = subprocess.run(["git", "-C", str(hs.parent.parent.parent), "rev-parse", "HEAD"], capture_output=True,
                             text=True).stdout.strip() or "unknown"
    except OSError:
        rev = "unknown"
    ver = subprocess.run([str(hs), "--version"], capture_output=True, text=True).stdout.strip()
    meta = {"hyperstat": str(hs), "hyperstat --version": ver, "checkout HEAD": rev,
            "generator SHA-256 (blind6 *.py, robots, models)": sources_sha256(), "seed": a.seed, "jobs": a.jobs,
            "timeout per campaign (s)": a.timeout, "campaigns": len(names),
            "wall time: generation (s)": round(t_gen, 1), "wall time: total (s)": round(time.time() - t0, 1)}
    (out / "verdicts.json").write_text(json.dumps(dict(meta=meta, verdicts=vs), indent=1, default=str))
    write_rates(out / "rates.md", vs, meta)
    print("wrote", out / "rates.md")


if __name__ == "__main__":
    main()
