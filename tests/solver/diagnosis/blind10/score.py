"""The run of record of the twelfth blind set (directory ``blind10``): generation, ``hyperstat diagnose``
per campaign, judging, ``rates.md`` and ``verdicts.json``.  Units: visibility dimensionless, times s.

    .venv/bin/python -m tests.solver.diagnosis.blind10.score --hyperstat .venv/bin/hyperstat \
        --out out/blind10 --seed 0 --jobs 2

Judging rules: ``RULES.md`` (adopted from ``blind9/RULES.md``).  Runs diagnose as a command; nothing
here imports hyperstat.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

HERE = os.path.dirname(os.path.abspath(__file__))
TIMEOUT = 1200.0  # s per campaign, counted as a failure
LINE = 0.6  # visibility line fixed in advance
PARALLEL = {"tx7", "hexa"}


def sources_sha256():
    """SHA-256 of this directory's sources (*.py, magnitudes.json, robots/*, models/*.json, sorted by
    relative name) then the imported ../blind7/kin.py and ../blind8/machine.py: each relative name
    and its bytes.  RULES.md excluded."""
    names = []
    for root, _, files in os.walk(HERE):
        if "__pycache__" in root:
            continue
        for f in files:
            rel = os.path.relpath(os.path.join(root, f), HERE)
            top = rel.split(os.sep)[0]
            if (f.endswith(".py") and os.sep not in rel) or rel == "magnitudes.json" or top == "robots" \
                    or (top == "models" and f.endswith(".json")):
                names.append(rel)
    names.sort()
    names += [os.path.join("..", "blind7", "kin.py"), os.path.join("..", "blind8", "machine.py")]
    h = hashlib.sha256()
    for rel in names:
        h.update(rel.replace(os.sep, "/").encode())
        with open(os.path.join(HERE, rel), "rb") as f:
            h.update(f.read())
    return h.hexdigest()


def _k(name):
    return float(name.split("angle-harmonic-")[1])


def same_effect(a, b):
    if a.startswith("angle-harmonic-") and b.startswith("angle-harmonic-"):
        try:
            return abs(_k(a) - _k(b)) <= 0.01
        except ValueError:
            return False
    return a == b


def judge(truth, ans):
    """Verdict of one campaign: truth (truth.json) and the diagnose JSON (None: a failure)."""
    kind = truth["kind"]
    v = {"name": truth["name"], "kind": kind, "family": truth["family"], "model": truth["model"],
         "visibility": truth.get("visibility"), "truth": truth.get("effect"),
         "counted": kind in ("none", "under") or (truth.get("visibility") or 0.0) >= LINE}
    if ans is None:
        v.update(outcome="failure", success=False, confidently_wrong=False)
        return v
    out = ans.get("outcome")
    named = list(ans.get("named_effects") or [])
    members = list(named)
    for s in ans.get("equivalence_sets") or []:
        members += list(s.get("members") or [])
    conf = ans.get("confidence")
    v.update(outcome=out, named=named, confidence=conf, ambiguous=ans.get("ambiguous"))
    if kind == "in":
        t = truth["effect"]
        ok = out in ("explained", "partly explained") and any(same_effect(t, m) for m in members)
        v["success"] = ok
        v["named_outright"] = bool(out == "explained" and any(same_effect(t, m) for m in named)
                                   and not ans.get("ambiguous") and conf == "high")
        v["confidently_wrong"] = bool(out == "explained" and conf == "high" and not ok)
        tj = truth.get("joints")
        if not tj:
            v["right_joint"] = "n/a"
        elif not ok:
            v["right_joint"] = "-"
        else:
            ej = None
            for k, js in (ans.get("effect_joints") or {}).items():
                if same_effect(t, k):
                    ej = [str(x) for x in js]
            if ej is None:
                v["right_joint"] = "none given"
            elif set(ej) == set(tj):
                v["right_joint"] = "yes"
            elif set(ej) & set(tj):
                v["right_joint"] = "part"
            else:
                v["right_joint"] = "no"
    elif kind == "out":
        honest = out in ("unexplained", "partly explained") or (out == "explained" and conf == "low")
        v["success"] = honest
        v["confidently_wrong"] = bool((out == "explained" and conf == "high") or out == "understated noise")
    elif kind == "none":
        v["success"] = out == "no significant gap"
        v["confidently_wrong"] = bool(out == "explained" and conf == "high")
    else:
        v["success"] = out == "understated noise"
        v["confidently_wrong"] = bool(out == "explained" and conf == "high")
    return v


def run_one(hs, camp, model, nice=True):
    js = os.path.join(camp, "diagnosis.json")
    if os.path.exists(js):
        os.remove(js)
    cmd = ([] if not nice else ["nice", "-n", "5"]) + [
        hs, "diagnose", model, os.path.join(camp, "data.csv"), "--validation", os.path.join(camp, "val.csv"),
        "--json", js, "--quiet"]
    t0 = time.time()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
        rc, err = p.returncode, p.stderr[-2000:]
    except subprocess.TimeoutExpired:
        rc, err = "timeout", ""
    dt = time.time() - t0
    ans = None
    if rc == 0 and os.path.exists(js):
        with open(js) as f:
            ans = json.load(f)
    return ans, dt, rc, err


def rates(verdicts):
    def rate(sel):
        c = [v for v in verdicts if sel(v) and v["counted"]]
        s = sum(1 for v in c if v["success"])
        return s, len(c)

    r = {
        "in-library named, serial": rate(lambda v: v["kind"] == "in" and v["family"] not in PARALLEL),
        "in-library named, parallel": rate(lambda v: v["kind"] == "in" and v["family"] in PARALLEL),
        "out-of-library honest": rate(lambda v: v["kind"] == "out"),
        "no effect: no false alarm": rate(lambda v: v["kind"] == "none"),
        "understated noise flagged": rate(lambda v: v["kind"] == "under"),
    }
    cw = sum(1 for v in verdicts if v.get("confidently_wrong") and v["counted"])
    fails = sum(1 for v in verdicts if v["outcome"] == "failure")
    return r, cw, fails


def write_report(out, verdicts, sha, head, wall):
    r, cw, fails = rates(verdicts)
    lines = ["# Twelfth blind set (blind10): rates of the run", "",
             f"sources_sha256 `{sha}`, git HEAD `{head}`, wall {wall:.0f} s; visibility line {LINE}", "",
             "| rate | count | % |", "|---|---|---|"]
    for k, (s, n) in r.items():
        lines.append(f"| {k} | {s}/{n} | {100.0 * s / n if n else float('nan'):.0f} |")
    lines += [f"| confidently wrong (counted campaigns) | {cw} | |", f"| diagnose failures | {fails} | |", "",
              "| case | family | model | kind | truth | visibility | counted | outcome | named | confidence |"
              " success | outright | right joint | confidently wrong | time s |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for v in verdicts:
        vis = "-" if v["visibility"] is None else f"{v['visibility']:.2f}"
        lines.append(f"| {v['name']} | {v['family']} | {v['model']} | {v['kind']} | {v['truth'] or '-'} | {vis} | "
                     f"{v['counted']} | {v['outcome']} | {', '.join(v.get('named') or []) or '-'} | "
                     f"{v.get('confidence')} | {v['success']} | {v.get('named_outright', '-')} | "
                     f"{v.get('right_joint', '-')} | {v.get('confidently_wrong')} | {v.get('time', 0):.1f} |")
    with open(os.path.join(out, "rates.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(out, "verdicts.json"), "w") as f:
        json.dump({"sources_sha256": sha, "git_head": head, "rates": {k: list(x) for k, x in r.items()},
                   "confidently_wrong": cw, "failures": fails, "verdicts": verdicts}, f, indent=1)
    return r, cw, fails


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--hyperstat", default=".venv/bin/hyperstat")
    ap.add_argument("--out", default="out/blind10")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cases")
    a = ap.parse_args(argv)
    from tests.solver.diagnosis.blind10.generate import generate

    t0 = time.time()
    sha = sources_sha256()
    head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    names = a.cases.split(",") if a.cases else None
    truths = generate(a.out, a.seed, names)
    print(f"generated {len(truths)} campaigns in {time.time() - t0:.0f} s", flush=True)
    order = sorted(truths, key=lambda n: (truths[n]["family"] != "hexa", n))  # hexapod first
    hs = os.path.abspath(a.hyperstat)

    def work(n):
        t = truths[n]
        camp = os.path.join(a.out, "campaigns", n)
        ans, dt, rc, err = run_one(hs, camp, os.path.join(a.out, "models", t["model"] + ".skel.json"))
        v = judge(t, ans)
        v["time"] = dt
        v["exit"] = rc
        if ans is None:
            v["stderr"] = err
        print(f"{n:20s} {v['outcome']:20s} success {v['success']}  {dt:6.1f} s", flush=True)
        return v

    with ThreadPoolExecutor(max_workers=a.jobs) as ex:
        verdicts = list(ex.map(work, order))
    r, cw, fails = write_report(a.out, verdicts, sha, head, time.time() - t0)
    for k, (s, n) in r.items():
        print(f"{k}: {s}/{n}")
    print(f"confidently wrong: {cw}; failures: {fails}")
    print(f"sources_sha256 {sha}")
    print(f"git rev-parse HEAD {head}")
    print(f"wall {time.time() - t0:.0f} s")


if __name__ == "__main__":
    sys.exit(main())
