"""The run of record of the eleventh blind generator (directory ``blind9``): generation, one
``hyperstat diagnose`` per campaign (as a command, as a user runs it), judging, ``rates.md`` and
``verdicts.json``.  Units: times s, visibilities (ratio), rates in %.

    python -m tests.solver.diagnosis.blind9.score --hyperstat .venv/bin/hyperstat --out out/blind9 --seed 0 --jobs 2
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

HERE = os.path.dirname(os.path.abspath(__file__))
VIS_LINE = 0.6
TIMEOUT = 1200.0
IMPORTED = ["../blind7/kin.py", "../blind8/machine.py"]


def sources_sha256():
    """SHA-256 over this directory's ``*.py``, ``robots/*``, ``models/*.json`` (relative name and bytes,
    sorted by name; RULES.md excluded) and then the imported ``../blind7/kin.py`` and
    ``../blind8/machine.py``."""
    names = sorted(
        [os.path.relpath(p, HERE) for p in glob.glob(os.path.join(HERE, "*.py"))]
        + [os.path.relpath(p, HERE) for p in glob.glob(os.path.join(HERE, "robots", "*"))]
        + [os.path.relpath(p, HERE) for p in glob.glob(os.path.join(HERE, "models", "*.json"))])
    h = hashlib.sha256()
    for n in names + IMPORTED:
        h.update(n.encode() + b"\0")
        with open(os.path.join(HERE, n), "rb") as f:
            h.update(f.read())
        h.update(b"\0")
    return h.hexdigest()


# ---- judging (adopted from blind8/RULES.md) -------------------------------------------------------
def _same(name, truth):
    if truth.startswith("angle-harmonic-") and name.startswith("angle-harmonic-"):
        try:
            return abs(float(name.rsplit("-", 1)[1]) - float(truth.rsplit("-", 1)[1])) <= 0.01
        except ValueError:
            return False
    return name == truth


def judge(case, truth, ans):
    """The verdict of one campaign (dict); ``ans`` None for a failure."""
    from tests.solver.diagnosis.blind9.effects import effect_joints, library_name
    kind = case["kind"]
    vis = truth.get("visibility")
    v = dict(name=case["name"], family=case["family"], model=case["model"], kind=kind,
             truth=library_name(case["effect"]) if case.get("effect") else "-",
             visibility=vis, counted=(kind in ("none", "under") or (vis is not None and vis >= VIS_LINE)))
    if ans is None:
        v.update(outcome="FAILURE", confidence="-", named=[], ok=False, confidently_wrong=False)
        return v
    out = ans.get("outcome")
    conf = ans.get("confidence")
    named = list(ans.get("named_effects") or [])
    members = list(named)
    for s in ans.get("equivalence_sets") or []:
        members += list(s.get("members") or [])
    v.update(outcome=out, confidence=conf, named=named, members=sorted(set(members)),
             ambiguous=ans.get("ambiguous"), effect_joints=ans.get("effect_joints"))
    high_explained = out == "explained" and conf == "high"
    if kind == "in":
        t = v["truth"]
        inm = any(_same(m, t) for m in members)
        v["ok"] = out in ("explained", "partly explained") and inm
        v["named_outright"] = (out == "explained" and any(_same(m, t) for m in named)
                               and not ans.get("ambiguous") and conf == "high")
        v["confidently_wrong"] = high_explained and not inm
        tj = set(effect_joints(case["effect"]))
        ej = ans.get("effect_joints") or {}
        got = None
        for k, js in ej.items():
            if _same(k, t):
                got = set(str(j) for j in js)
        if not v["ok"]:
            v["right_joint"] = "-"
        elif not tj:
            v["right_joint"] = "n/a"
        elif got is None:
            v["right_joint"] = "none given"
        else:
            v["right_joint"] = "yes" if got == tj else ("part" if got & tj else "no")
    elif kind == "out":
        v["ok"] = out in ("unexplained", "partly explained") or (out == "explained" and conf == "low")
        v["confidently_wrong"] = high_explained or out == "understated noise"
    elif kind == "none":
        v["ok"] = out == "no significant gap"  # ok = no false alarm
        v["confidently_wrong"] = high_explained
    else:
        v["ok"] = out == "understated noise"
        v["confidently_wrong"] = high_explained
    return v


# ---- running --------------------------------------------------------------------------------------
def run_one(hyperstat, model, cdir, timeout):
    cmd = ["nice", "-n", "5", hyperstat, "diagnose", model, os.path.join(cdir, "data.csv"),
           "--validation", os.path.join(cdir, "val.csv"), "--json", os.path.join(cdir, "diagnosis.json"),
           "--quiet"]
    t0 = time.time()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        rc, err = p.returncode, p.stderr[-2000:]
    except subprocess.TimeoutExpired:
        rc, err = "timeout", f"more than {timeout:.0f} s"
    dt = time.time() - t0
    ans = None
    jp = os.path.join(cdir, "diagnosis.json")
    if rc == 0 and os.path.exists(jp):
        with open(jp) as f:
            ans = json.load(f)
    return ans, rc, err, dt


def _rate(vs):
    n = len(vs)
    k = sum(1 for v in vs if v["ok"])
    return f"{k}/{n} ({100.0 * k / n:.0f} %)" if n else "0/0"


def rates(verdicts):
    c = [v for v in verdicts if v["counted"]]
    par = ("tx7", "hexa")
    r = {
        "in-library named, serial": _rate([v for v in c if v["kind"] == "in" and v["family"] not in par]),
        "in-library named, parallel": _rate([v for v in c if v["kind"] == "in" and v["family"] in par]),
        "out-of-library honest": _rate([v for v in c if v["kind"] == "out"]),
        "false alarms": f"{sum(1 for v in c if v['kind'] == 'none' and not v['ok'])}/"
                        f"{sum(1 for v in c if v['kind'] == 'none')}",
        "understated noise flagged": _rate([v for v in c if v["kind"] == "under"]),
        "confidently wrong": str(sum(1 for v in c if v["confidently_wrong"])),
        "failures (incl. timeouts)": str(sum(1 for v in verdicts if v["outcome"] == "FAILURE")),
        "invisible (not counted)": str(sum(1 for v in verdicts if not v["counted"])),
    }
    return r


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hyperstat", default=".venv/bin/hyperstat")
    ap.add_argument("--out", default="out/blind9")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=TIMEOUT)
    ap.add_argument("--cases", default="", help="comma-separated subset (not the run of record)")
    a = ap.parse_args(argv)
    from tests.solver.diagnosis.blind9 import generate as gen
    from tests.solver.diagnosis.blind9.cases import CASES
    sha = sources_sha256()
    head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=HERE).stdout.strip()
    names = set(a.cases.split(",")) if a.cases else None
    cases = [c for c in CASES if not names or c["name"] in names]
    t0 = time.time()
    paths, truths = gen.generate(a.out, a.seed, {c["name"] for c in cases}, True, log=lambda s: None)
    t_gen = time.time() - t0
    print(f"generated {len(cases)} campaigns in {t_gen:.0f} s", flush=True)
    order = sorted(cases, key=lambda c: (c["family"] != "hexa", CASES.index(c)))
    hyper = os.path.abspath(a.hyperstat) if os.path.exists(a.hyperstat) else a.hyperstat
    results = {}
    with cf.ThreadPoolExecutor(a.jobs) as ex:
        futs = {ex.submit(run_one, hyper, paths[c["model"]], os.path.join(a.out, "campaigns", c["name"]),
                          a.timeout): c for c in order}
        for f in cf.as_completed(futs):
            c = futs[f]
            results[c["name"]] = f.result()
            ans, rc, err, dt = results[c["name"]]
            print(f"{c['name']}: {ans.get('outcome') if ans else 'FAILURE (' + str(rc) + ')'} ({dt:.0f} s)", flush=True)
    verdicts = []
    for c in cases:
        ans, rc, err, dt = results[c["name"]]
        v = judge(c, truths[c["name"]], ans)
        v["wall_s"] = round(dt, 1)
        if ans is None:
            v["error"] = f"exit {rc}: {err}"
        verdicts.append(v)
    r = rates(verdicts)
    t_all = time.time() - t0
    lines = ["# Eleventh blind generator (blind9): rates of the run", "",
             f"sources_sha256 `{sha}`, git HEAD `{head}`, seed {a.seed}, jobs {a.jobs}, "
             f"generation {t_gen:.0f} s, total {t_all:.0f} s of wall clock", "",
             "| rate | value |", "|---|---|"] + [f"| {k} | {v} |" for k, v in r.items()] + [
             "", "| case | family | model | kind | truth | visibility | counted | outcome | confidence | named | ok | "
             "right joint | confidently wrong | wall s |", "|" + "---|" * 14]
    for v in verdicts:
        vis = f"{v['visibility']:.3f}" if v.get("visibility") is not None else "-"
        lines.append(f"| {v['name']} | {v['family']} | {v['model']} | {v['kind']} | {v['truth']} | {vis} | "
                     f"{'yes' if v['counted'] else 'no'} | {v['outcome']} | {v['confidence']} | "
                     f"{', '.join(v['named']) or '-'} | {'yes' if v['ok'] else 'no'} | {v.get('right_joint', '-')} | "
                     f"{'YES' if v['confidently_wrong'] else 'no'} | {v['wall_s']} |")
    os.makedirs(a.out, exist_ok=True)
    for name, text in (("rates.md", "\n".join(lines) + "\n"),
                       ("verdicts.json", json.dumps(dict(rates=r, sources_sha256=sha, git_head=head,
                                                         verdicts=verdicts), indent=1, default=str))):
        p = os.path.join(a.out, name)
        with open(p + ".tmp", "w") as f:
            f.write(text)
        os.replace(p + ".tmp", p)
    for k, v in r.items():
        print(f"{k}: {v}")
    print(f"sources_sha256: {sha}")
    print(f"git rev-parse HEAD: {head}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
