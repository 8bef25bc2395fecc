"""The run of record of the tenth blind generator (``blind8``): generate the 72 campaigns, run
``hyperstat diagnose`` on each as a user does (a command, never an import), judge by ``RULES.md``,
write ``rates.md`` and ``verdicts.json``, print the rates, the sources' SHA-256 and ``git rev-parse HEAD``.

    .venv/bin/python -m tests.solver.diagnosis.blind8.score --hyperstat .venv/bin/hyperstat \
        --out out/blind8 --seed 0 --jobs 2

Units: times in s, rates in % of the counted campaigns (counts beside them), visibility a ratio.
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

from .machine import HERE

TIMEOUT = 1200.0  # s per campaign; beyond it the campaign counts as a failure
VIS_LINE = 0.6
PARALLEL = {"tx7", "hexa"}
MASSED = {"tx7_m", "hexa_m", "gantry_m", "desk_m"}


def sources_sha256(root=HERE):
    """SHA-256 over (relative name, bytes) of this directory's ``*.py``, ``robots/*``, ``models/*.json``
    and the imported ``../blind7/kin.py``, sorted by name; ``RULES.md`` excluded."""
    files = glob.glob(os.path.join(root, "*.py")) + glob.glob(os.path.join(root, "robots", "*")) + \
        glob.glob(os.path.join(root, "models", "*.json"))
    files = sorted(os.path.relpath(f, root) for f in files)
    files.append(os.path.join("..", "blind7", "kin.py"))
    h = hashlib.sha256()
    for rel in files:
        h.update(rel.encode())
        h.update(b"\0")
        with open(os.path.join(root, rel), "rb") as f:
            h.update(f.read())
        h.update(b"\0")
    return h.hexdigest()


def truth_name(case):
    e = case["effect"]
    if e == "angle-harmonic":
        return f"angle-harmonic-{case['params']['k']:g}"
    return e


def truth_joints(case):
    per = case.get("params", {}).get("per")
    return sorted(per) if per else None


def _same(a, b):
    if a == b:
        return True
    pre = "angle-harmonic-"
    if a.startswith(pre) and b.startswith(pre):
        try:
            return abs(float(a[len(pre):]) - float(b[len(pre):])) < 0.01
        except ValueError:
            return False
    return False


def _in(name, names):
    return any(_same(name, n) for n in names)


def judge(case, d):
    """Verdict of one campaign (``d`` the diagnose JSON, or None on a failure)."""
    kind = case["kind"]
    v = dict(name=case["name"], family=case["family"], model=case["model"], kind=kind,
             truth=truth_name(case) if kind in ("in", "out") else "-",
             visibility=case.get("visibility"), counted=True)
    if kind in ("in", "out") and (case.get("visibility") is None or case["visibility"] < VIS_LINE):
        v["counted"] = False
    if d is None:
        v.update(outcome="failure", ok=False, confidently_wrong=False)
        return v
    outcome = d.get("outcome")
    named = list(d.get("named_effects") or [])
    members = list(named)
    for s in d.get("equivalence_sets") or []:
        members += list(s.get("members") or [])
    conf = d.get("confidence")
    v.update(outcome=outcome, named=named, members=sorted(set(members)), confidence=conf,
             ambiguous=d.get("ambiguous"))
    if kind == "in":
        t = v["truth"]
        v["ok"] = outcome in ("explained", "partly explained") and _in(t, members)
        v["outright"] = (outcome == "explained" and _in(t, named) and not d.get("ambiguous")
                         and conf == "high")
        v["confidently_wrong"] = outcome == "explained" and conf == "high" and not _in(t, members)
        tj = truth_joints(case)
        ej = d.get("effect_joints") or {}
        got = None
        for k, js in ej.items():
            if _same(k, t):
                got = sorted(str(x) for x in js)
        if not v["ok"] or tj is None:
            v["right_joint"] = "-"
        elif got is None:
            v["right_joint"] = "none given"
        else:
            v["right_joint"] = "yes" if got == tj else ("part" if set(got) & set(tj) else "no")
    elif kind == "out":
        v["ok"] = outcome in ("unexplained", "partly explained") or (outcome == "explained" and conf == "low")
        v["confidently_wrong"] = (outcome == "explained" and conf == "high") or outcome == "understated noise"
    elif kind == "none":
        v["ok"] = outcome == "no significant gap"  # ok = no false alarm
        v["confidently_wrong"] = outcome == "explained" and conf == "high"
    else:
        v["ok"] = outcome == "understated noise"
        v["confidently_wrong"] = outcome == "explained" and conf == "high"
    return v


def run_one(hyperstat, cdir, model):
    out = os.path.join(cdir, "diagnosis.json")
    if os.path.exists(out):
        os.remove(out)
    cmd = ["nice", "-n", "5", hyperstat, "diagnose", model, os.path.join(cdir, "data.csv"),
           "--validation", os.path.join(cdir, "val.csv"), "--json", out, "--quiet"]
    t0 = time.time()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
        rc, err = p.returncode, p.stderr[-2000:]
    except subprocess.TimeoutExpired:
        rc, err = "timeout", f"more than {TIMEOUT:.0f} s"
    wall = time.time() - t0
    d = None
    if rc == 0 and os.path.exists(out):
        with open(out) as f:
            d = json.load(f)
    return d, rc, err, wall


def rates(verdicts):
    def rate(sel):
        n = len(sel)
        k = sum(1 for v in sel if v["ok"])
        return k, n
    inn = [v for v in verdicts if v["kind"] == "in" and v["counted"]]
    r = {
        "in-library named, serial (%)": rate([v for v in inn if v["family"] not in PARALLEL]),
        "in-library named, parallel (%)": rate([v for v in inn if v["family"] in PARALLEL]),
        "out-of-library honest (%)": rate([v for v in verdicts if v["kind"] == "out" and v["counted"]]),
        "no effect: no false alarm (%)": rate([v for v in verdicts if v["kind"] == "none"]),
        "understated noise flagged (%)": rate([v for v in verdicts if v["kind"] == "under"]),
    }
    extra = {
        "in-library named outright": sum(1 for v in inn if v.get("outright")),
        "in-library counted": len(inn),
        "confidently wrong (all kinds)": sum(1 for v in verdicts if v.get("confidently_wrong")),
        "false alarms": sum(1 for v in verdicts if v["kind"] == "none" and not v["ok"]),
        "failures (no answer, timeout)": sum(1 for v in verdicts if v["outcome"] == "failure"),
        "below the visibility line (not counted)": sum(1 for v in verdicts if not v["counted"]),
    }
    return r, extra


def write_report(outdir, verdicts, sha, head, wall_total):
    r, extra = rates(verdicts)
    L = ["# blind8 (tenth blind generator): rates of the run", "",
         f"Sources SHA-256: `{sha}`; `git rev-parse HEAD`: `{head}`; total wall {wall_total:.0f} s.",
         "Units: rates in % (count / counted campaigns), visibility a ratio (held-out residual of the "
         "own rigid fit / stated noise), times in s.", "",
         "| rate | value | must show |", "|---|---|---|"]
    must = {"in-library named, serial (%)": ">= 95 %", "in-library named, parallel (%)": ">= 95 %",
            "out-of-library honest (%)": ">= 95 %", "no effect: no false alarm (%)": "100 % (0 false alarms)",
            "understated noise flagged (%)": "100 %"}
    for k, (a, n) in r.items():
        L.append(f"| {k} | {100.0 * a / n if n else float('nan'):.0f} % ({a}/{n}) | {must[k]} |")
    L += ["", "| count | value |", "|---|---|"] + [f"| {k} | {v} |" for k, v in extra.items()]
    L += ["", "| case | family | model (masses) | kind | truth | vis | outcome | named (set members) | "
          "confidence | ok | outright | right joint | confidently wrong | wall (s) |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for v in verdicts:
        vis = "-" if v.get("visibility") is None else f"{v['visibility']:.3f}"
        mem = ", ".join(v.get("members", []))
        L.append(f"| {v['name']} | {v['family']} | {v['model']} ({'yes' if v['model'] in MASSED else 'no'}) | "
                 f"{v['kind']} | {v['truth']} | {vis}{'' if v['counted'] else ' (not counted)'} | "
                 f"{v['outcome']} | {', '.join(v.get('named', []))} ({mem}) | {v.get('confidence', '-')} | "
                 f"{'yes' if v['ok'] else 'no'} | {v.get('outright', '-')} | {v.get('right_joint', '-')} | "
                 f"{'yes' if v.get('confidently_wrong') else 'no'} | {v.get('wall', 0):.0f} |")
    with open(os.path.join(outdir, "rates.md"), "w") as f:
        f.write("\n".join(L) + "\n")
    with open(os.path.join(outdir, "verdicts.json"), "w") as f:
        json.dump(dict(sha256=sha, head=head, rates={k: list(x) for k, x in r.items()}, counts=extra,
                       verdicts=verdicts), f, indent=1)
    return r, extra


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hyperstat", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cases", default=None, help="comma-separated subset (smoke runs)")
    a = ap.parse_args(argv)
    from .generate import generate
    t0 = time.time()
    hyperstat = os.path.abspath(a.hyperstat) if os.path.exists(a.hyperstat) else a.hyperstat
    sha = sources_sha256()
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=HERE).stdout.strip()
    except OSError:
        head = "?"
    os.makedirs(a.out, exist_ok=True)
    truths = generate(a.out, a.seed, a.cases.split(",") if a.cases else None)
    order = sorted(truths, key=lambda c: (c["family"] != "hexa",))  # hexapod campaigns first
    results = {}
    with cf.ThreadPoolExecutor(max_workers=a.jobs) as ex:
        futs = {ex.submit(run_one, hyperstat, os.path.join(a.out, "campaigns", c["name"]),
                          os.path.abspath(c["model"])): c for c in order}
        for fu in cf.as_completed(futs):
            c = futs[fu]
            d, rc, err, wall = fu.result()
            results[c["name"]] = (d, rc, err, wall)
            print(f"{c['name']:24s} rc={rc} {wall:6.1f} s  {d.get('outcome') if d else err[-200:]!s}", flush=True)
    verdicts = []
    for c in truths:
        d, rc, err, wall = results[c["name"]]
        v = judge(c, d)
        v["wall"] = wall
        v["returncode"] = rc
        if d is None:
            v["stderr"] = err
        verdicts.append(v)
    r, extra = write_report(a.out, verdicts, sha, head, time.time() - t0)
    for k, (x, n) in r.items():
        print(f"{k}: {100.0 * x / n if n else float('nan'):.0f} % ({x}/{n})")
    for k, x in extra.items():
        print(f"{k}: {x}")
    print(f"sources SHA-256: {sha}")
    print(f"git rev-parse HEAD: {head}")


if __name__ == "__main__":
    sys.exit(main())
