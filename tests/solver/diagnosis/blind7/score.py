"""Run of record of the ninth blind generator (directory ``blind7``): generation, one
``hyperstat diagnose`` per campaign, judging (``judge``), ``OUT/rates.md`` and ``OUT/verdicts.json``.

``python -m tests.solver.diagnosis.blind7.score --hyperstat .venv/bin/hyperstat --out out/blind7 --seed 0 --jobs 2``
Units: times s.  The rules applied here are written in RULES.md ("Judging rules").
"""
from __future__ import annotations

import argparse
import glob
import hashlib
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

from .cases import CASES
from .generate import VIS_LINE, generate

HERE = os.path.dirname(os.path.abspath(__file__))
TIMEOUT = 1200.0


def sources_sha256():
    """SHA-256 over this directory's sources: ``*.py``, ``robots/*``, ``models/*.json`` (relative
    name and bytes, sorted by name).  RULES.md is not included."""
    files = sorted(glob.glob(os.path.join(HERE, "*.py")) + glob.glob(os.path.join(HERE, "robots", "*"))
                   + glob.glob(os.path.join(HERE, "models", "*.json")))
    h = hashlib.sha256()
    for f in files:
        h.update(os.path.relpath(f, HERE).encode() + b"\0")
        with open(f, "rb") as fh:
            h.update(fh.read())
        h.update(b"\0")
    return h.hexdigest()


def _num(name):
    try:
        return float(name.rsplit("-", 1)[1])
    except (IndexError, ValueError):
        return None


def same_effect(a, b):
    if a == b:
        return True
    if a.startswith("angle-harmonic-") and b.startswith("angle-harmonic-"):
        ka, kb = _num(a), _num(b)
        return ka is not None and kb is not None and abs(ka - kb) <= 0.01
    return False


def judge(case, res):
    """Verdict of one campaign from diagnose's JSON (``res`` None: a failure)."""
    v = dict(name=case["name"], family=case["family"], kind=case["kind"], truth=case.get("truth"),
             model=case["model"], masses_declared=case["masses_declared"])
    if res is None:
        v.update(outcome="FAILURE", confidence=None, named=[], members=[], ok=False, confidently_wrong=False)
        return v
    out = res.get("outcome")
    conf = res.get("confidence")
    named = list(res.get("named_effects") or [])
    members = list(named)
    for s in res.get("equivalence_sets") or []:
        members += list(s.get("members") or [])
    v.update(outcome=out, confidence=conf, named=named, members=members,
             ambiguous=res.get("ambiguous"), effect_joints=res.get("effect_joints"),
             noise_factor=res.get("noise_factor"))
    kind = case["kind"]
    if kind == "in":
        truth = case["truth"]
        in_members = any(same_effect(m, truth) for m in members)
        v["ok"] = out in ("explained", "partly explained") and in_members
        v["named_outright"] = (out == "explained" and any(same_effect(m, truth) for m in named)
                               and not res.get("ambiguous") and conf == "high")
        v["confidently_wrong"] = out == "explained" and conf == "high" and not in_members
        ej = None
        for k, js in (res.get("effect_joints") or {}).items():
            if same_effect(k, truth):
                ej = set(map(str, js))
        tj = set(case.get("joints") or [])
        if not v["ok"] or not tj:
            v["right_joint"] = "-"
        elif ej is None:
            v["right_joint"] = "none given"
        else:
            v["right_joint"] = "yes" if ej == tj else ("part" if ej & tj else "no")
    elif kind == "out":
        v["ok"] = out in ("unexplained", "partly explained") or (out == "explained" and conf == "low")
        v["confidently_wrong"] = (out == "explained" and conf == "high") or out == "understated noise"
    elif kind == "none":
        v["ok"] = out == "no significant gap"  # ok = no false alarm
        v["confidently_wrong"] = out == "explained" and conf == "high"
    elif kind == "under":
        v["ok"] = out == "understated noise"
        v["confidently_wrong"] = out == "explained" and conf == "high"
    return v


def run_one(hyperstat, cdir, model):
    t0 = time.time()
    js = os.path.join(cdir, "diagnosis.json")
    if os.path.exists(js):
        os.remove(js)
    cmd = ["nice", "-n", "5", hyperstat, "diagnose", model, os.path.join(cdir, "data.csv"),
           "--validation", os.path.join(cdir, "val.csv"), "--json", js, "--quiet"]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
        rc, err = p.returncode, p.stderr[-2000:]
    except subprocess.TimeoutExpired:
        rc, err = "timeout", "timeout"
    dt = time.time() - t0
    res = None
    if rc == 0 and os.path.exists(js):
        try:
            with open(js) as f:
                res = json.load(f)
        except ValueError:
            res = None
    return res, dt, rc, err


def rate(vs, pred):
    sel = [v for v in vs if pred(v)]
    return sum(1 for v in sel if v["ok"]), len(sel)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--hyperstat", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cases", help="comma-separated subset (smoke runs)")
    a = ap.parse_args(argv)
    t_start = time.time()
    names = a.cases.split(",") if a.cases else None
    cases = [c for c in CASES if names is None or c["name"] in names]
    camp = os.path.join(a.out, "campaigns")
    vis = generate(camp, a.seed, a.jobs, [c["name"] for c in cases])
    t_gen = time.time() - t_start
    # hexapod campaigns first (the longest)
    cases.sort(key=lambda c: 0 if c["family"] == "hexa" else 1)
    hs = os.path.abspath(a.hyperstat)

    def job(c):
        with open(os.path.join(camp, c["name"], "truth.json")) as f:
            truth = json.load(f)
        return c, truth, run_one(hs, os.path.join(camp, c["name"]), truth["model_file"])
    verdicts = []
    with ThreadPoolExecutor(a.jobs) as ex:
        for c, truth, (res, dt, rc, err) in ex.map(job, cases):
            v = judge(c, res)
            v.update(visibility=vis.get(c["name"]), seconds=round(dt, 1), exit=rc,
                     error=None if res is not None else err)
            v["visible"] = c["kind"] in ("none", "under") or (v["visibility"] is not None and v["visibility"] >= VIS_LINE)
            verdicts.append(v)
            print(f"{c['name']:22s} {str(v['outcome']):20s} {str(v.get('confidence')):5s} ok={v['ok']} {dt:.0f}s", flush=True)
    order = {c["name"]: i for i, c in enumerate(CASES)}
    verdicts.sort(key=lambda v: order[v["name"]])
    par = ("tx7", "hexa")
    vis_ = [v for v in verdicts if v["visible"]]
    r_in_par = rate(vis_, lambda v: v["kind"] == "in" and v["family"] in par)
    r_in_ser = rate(vis_, lambda v: v["kind"] == "in" and v["family"] not in par)
    r_out = rate(vis_, lambda v: v["kind"] == "out")
    r_none = rate(verdicts, lambda v: v["kind"] == "none")
    r_under = rate(verdicts, lambda v: v["kind"] == "under")
    outright = sum(1 for v in vis_ if v["kind"] == "in" and v.get("named_outright"))
    n_in = sum(1 for v in vis_ if v["kind"] == "in")
    cw = [v["name"] for v in verdicts if v.get("confidently_wrong")]
    below = [v["name"] for v in verdicts if not v["visible"]]
    fails = [v["name"] for v in verdicts if v["outcome"] == "FAILURE"]
    sha = sources_sha256()
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=HERE).stdout.strip()
    except OSError:
        head = "unknown"
    wall = time.time() - t_start

    def pct(r):
        return f"{r[0]}/{r[1]}" + (f" ({100.0 * r[0] / r[1]:.0f} %)" if r[1] else "")
    lines = ["# blind7 (ninth blind generator): rates of record", "",
             f"sources SHA-256 (score.sources_sha256, RULES.md excluded): `{sha}`",
             f"git rev-parse HEAD: `{head}`; seed {a.seed}; jobs {a.jobs}; generation {t_gen:.0f} s, whole run {wall:.0f} s", "",
             "| rate | value |", "|---|---|",
             f"| in-library named, parallel (tx7, hexa) | {pct(r_in_par)} |",
             f"| in-library named, serial (puma, denso, scara) | {pct(r_in_ser)} |",
             f"| in-library named outright (explained, unambiguous, high) | {outright}/{n_in} |",
             f"| out-of-library honest | {pct(r_out)} |",
             f"| no effect: no false alarm | {pct(r_none)} (false alarms {r_none[1] - r_none[0]}) |",
             f"| understated noise flagged | {pct(r_under)} |",
             f"| confidently wrong | {len(cw)}: {', '.join(cw) or '-'} |",
             f"| below the visibility line {VIS_LINE} (counted in no rate) | {len(below)}: {', '.join(below) or '-'} |",
             f"| diagnose failures (exit != 0, no JSON, > {TIMEOUT:.0f} s) | {len(fails)}: {', '.join(fails) or '-'} |",
             "", "| case | family | masses | kind | truth | visibility | outcome | confidence | named | ok | right joint | s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for v in verdicts:
        vv = "-" if v["visibility"] is None else f"{v['visibility']:.2f}"
        lines.append(f"| {v['name']} | {v['family']} | {'yes' if v['masses_declared'] else 'no'} | {v['kind']} | {v['truth'] or '-'} | {vv} | "
                     f"{v['outcome']} | {v.get('confidence')} | {', '.join(v['named']) or '-'} | {v['ok']} | {v.get('right_joint', '-')} | {v['seconds']} |")
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "rates.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(a.out, "verdicts.json"), "w") as f:
        json.dump(dict(sha256=sha, head=head, seed=a.seed, wall_s=wall, verdicts=verdicts), f, indent=1, default=str)
    print("\n".join(lines[:16]))
    print("sources SHA-256:", sha)
    print("git rev-parse HEAD:", head)
    return 0


if __name__ == "__main__":
    sys.exit(main())
