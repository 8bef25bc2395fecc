"""Scorer of the sixth blind generator: generate, run `hyperstat diagnose` on every campaign, judge by
RULES.md, write rates.md (with the SHA-256 of this directory's *.py files).  Units: mm, rad.
The visibility of each effect is the generator's own (a linearised rigid fit, RULES.md).

    .venv/bin/python -m tests.solver.diagnosis.blind4.score --hyperstat .venv/bin/hyperstat --out out/blind4 --seeds 0 --jobs 2

Runs hyperstat only as a command (import-robot and build for the model files, diagnose on the noisy
files); imports nothing from it.
"""
from __future__ import annotations

import argparse
import glob
import hashlib
import json
import os
import subprocess
import time
from concurrent.futures import ThreadPoolExecutor

from . import generator

VISIBLE = 0.6  # noise-free rigid fit's held-out RMS / the stated noise RMS
HONEST_OUT = ("unexplained", "partly explained")


def code_sha256():
    here = os.path.dirname(os.path.abspath(__file__))
    h = hashlib.sha256()
    for p in sorted(glob.glob(os.path.join(here, "*.py"))):
        h.update(os.path.basename(p).encode())
        with open(p, "rb") as f:
            h.update(f.read())
    return h.hexdigest()


def run_one(hyperstat, d, timeout):
    res = {"dir": d}
    model = json.load(open(os.path.join(d, "truth.json")))["model"]
    t1 = time.time()
    try:
        dg = subprocess.run([hyperstat, "diagnose", model,
                             os.path.join(d, "data.csv"), "--validation", os.path.join(d, "val.csv"),
                             "--json", os.path.join(d, "diagnose.json"), "--quiet"],
                            capture_output=True, text=True, timeout=timeout)
        res["rc"] = dg.returncode
        res["stderr"] = dg.stderr.strip()[-500:]
    except subprocess.TimeoutExpired:
        res["rc"] = "timeout"
        res["stderr"] = f"diagnose took more than {timeout} s"
    res["diagnose_s"] = time.time() - t1
    return res


def _k(name):
    try:
        return float(name.rsplit("-", 1)[1])
    except (IndexError, ValueError):
        return None


def same_effect(a, b):
    if a == b:
        return True
    if a.startswith("angle-harmonic-") and b.startswith("angle-harmonic-"):
        ka, kb = _k(a), _k(b)
        return ka is not None and kb is not None and abs(ka - kb) < 0.01
    return False


def judge(info, diag, vis):
    kind = info["kind"]
    out = {"outcome": None, "named": [], "verdict": "error", "visible": vis is None or vis >= VISIBLE}
    if diag is None:
        out["verdict"] = "no answer (diagnose failed)"
        out["ok"] = False
        return out
    oc = diag.get("outcome")
    named = diag.get("named_effects") or []
    sets = [s.get("members", []) for s in diag.get("equivalence_sets") or []]
    conf = diag.get("confidence")
    out.update(outcome=oc, named=named, sets=sets, confidence=conf, ambiguous=diag.get("ambiguous"),
               effect_joints=diag.get("effect_joints") or {}, targets_agree=diag.get("targets_agree"),
               cannot_size=[c.get("effect") for c in diag.get("cannot_size") or []],
               noise_factor=diag.get("noise_factor"))
    if kind == "none":
        out["ok"] = oc == "no significant gap"
        out["verdict"] = "no false alarm" if out["ok"] else "FALSE ALARM"
    elif kind == "noise":
        out["ok"] = oc == "understated noise"
        nfac = diag.get("noise_factor")
        out["factor_ok"] = bool(nfac) and abs(nfac / info["noise_factor"] - 1) <= 0.25
        out["verdict"] = "flagged" if out["ok"] else "NOT FLAGGED"
    elif kind == "in":
        truth = info["effect"]
        in_named = any(same_effect(truth, n) for n in named)
        in_set = any(same_effect(truth, m) for s in sets for m in s)
        out["ok"] = oc in ("explained", "partly explained") and (in_named or in_set)
        out["outright"] = out["ok"] and oc == "explained" and in_named and not diag.get("ambiguous") and conf == "high"
        tj = info["parameters"].get("joint")
        if tj is None:
            for key in ("beta", "s", "amp", "bow", "kappa", "c"):
                v = info["parameters"].get(key)
                if isinstance(v, dict):
                    tj = sorted(v)
                    break
        joints = None
        for n, js in (diag.get("effect_joints") or {}).items():
            if same_effect(truth, n):
                joints = js
        out["right_joint"] = None if joints is None or tj is None else \
            (set([tj] if isinstance(tj, str) else tj) <= set(map(str, joints)))
        if out["ok"]:
            out["verdict"] = "named" if in_named else "in the answer's set"
        else:
            wrong_conf = oc == "explained" and conf == "high"
            out["verdict"] = "CONFIDENTLY WRONG" if wrong_conf else "missed"
    elif kind == "out":
        out["ok"] = oc in HONEST_OUT or (oc == "explained" and conf == "low")
        if out["ok"]:
            out["verdict"] = "honest"
        elif oc == "explained" or oc == "understated noise":
            out["verdict"] = "CONFIDENTLY WRONG"
        else:
            out["verdict"] = f"not honest ({oc})"
    return out


def pct(a, b):
    return f"{100.0 * a / b:.0f} % ({a}/{b})" if b else "- (0)"


def write_rates(path, rows, seeds, wall, sha, commit, hyperstat):
    vis = [r for r in rows if r["j"]["visible"]]
    def sel(kind, serial=None, visible=True):
        return [r for r in rows if r["info"]["kind"] == kind and (serial is None or r["info"]["serial"] == serial)
                and (r["j"]["visible"] if visible else True)]
    ins, inp, outs = sel("in", True), sel("in", False), sel("out")
    nones, noises = sel("none", visible=False), sel("noise", visible=False)
    below = [r for r in rows if not r["j"]["visible"] and r["info"]["kind"] in ("in", "out")]
    ok = lambda rs: sum(1 for r in rs if r["j"].get("ok"))
    cw = lambda rs: sum(1 for r in rs if r["j"]["verdict"] == "CONFIDENTLY WRONG")
    lines = ["# Sixth blind generator (blind4): rates of record", "",
             "Units: mm, rad.  Judging rules: RULES.md of this directory (frozen before the run).", "",
             f"* code SHA-256 of `tests/solver/diagnosis/blind4/*.py`: `{sha}`",
             f"* commit of the code under test: `{commit}`",
             f"* hyperstat: `{hyperstat}`; seeds {seeds}; {len(rows)} campaigns; wall time {wall:.0f} s",
             f"* visibility line: the generator's noise-free rigid fit leaves a held-out RMS >= {VISIBLE} x the stated noise RMS", "",
             "| rate | value |", "|---|---|",
             f"| in-library named, serial arms (visible) | {pct(ok(ins), len(ins))} |",
             f"| in-library named, parallel machines (visible) | {pct(ok(inp), len(inp))} |",
             f"| in-library: named outright (explained, set of one, high confidence) | {pct(sum(1 for r in ins + inp if r['j'].get('outright')), len(ins + inp))} |",
             f"| in-library: confidently wrong (explained, high confidence, truth not in a set) | {pct(cw(ins + inp), len(ins + inp))} |",
             f"| out-of-library honest (visible) | {pct(ok(outs), len(outs))} |",
             f"| out-of-library confidently wrong | {pct(cw(outs), len(outs))} |",
             f"| false alarms on no-effect campaigns (not 'no significant gap') | {len(nones) - ok(nones)} of {len(nones)} |",
             f"| understated noise flagged | {ok(noises)} of {len(noises)} (factor within 25 %: {sum(1 for r in noises if r['j'].get('factor_ok'))}) |",
             f"| below the visibility line (not counted) | {len(below)}; of them confidently wrong: {cw(below)} |",
             f"| diagnose failures (no JSON) | {sum(1 for r in rows if r['j']['outcome'] is None)} |",
             "", "## Every campaign", "",
             "| family | case | kind | truth | visibility | outcome | named | sets | confidence | verdict | right joint | s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        i, j = r["info"], r["j"]
        v = "-" if r["vis"] is None else f"{r['vis']:.2f}"
        sets = "; ".join("{" + ", ".join(s) + "}" for s in j.get("sets", []) if len(s) > 1)
        lines.append(f"| {i['family']} | {i['case']} (s{i['seed']}) | {i['kind']} | {i['effect'] or '-'} | {v} | "
                     f"{j['outcome']} | {', '.join(j['named']) or '-'} | {sets or '-'} | {j.get('confidence')} | "
                     f"{j['verdict']}{'' if j['visible'] else ' (below line)'} | {j.get('right_joint', '')} | "
                     f"{r['res'].get('diagnose_s', 0):.0f} |")
    fails = [r for r in rows if r["j"]["outcome"] is None]
    if fails:
        lines += ["", "## Diagnose failures", ""]
        for r in fails:
            lines.append(f"* {r['info']['family']}/{r['info']['case']}: rc {r['res'].get('rc')}: {r['res'].get('stderr')}")
    with open(path + ".tmp", "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(path + ".tmp", path)
    return "\n".join(lines[:22])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--hyperstat", default=".venv/bin/hyperstat")
    ap.add_argument("--out", default="out/blind4")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--only", default=None, help="comma-separated families or family/case")
    ap.add_argument("--timeout", type=float, default=1200.0, help="seconds per diagnose")
    a = ap.parse_args(argv)
    seeds = [int(s) for s in a.seeds.split(",")]
    only = set(a.only.split(",")) if a.only else None
    hs = os.path.abspath(a.hyperstat) if os.path.exists(a.hyperstat) else a.hyperstat
    t0 = time.time()
    sha = code_sha256()
    print(f"code SHA-256 {sha}")
    done = generator.generate_all(hs, a.out, seeds, a.limit, only)
    print(f"generated {len(done)} campaigns in {time.time() - t0:.0f} s")
    with ThreadPoolExecutor(max_workers=a.jobs) as ex:
        results = list(ex.map(lambda di: run_one(hs, di[0], a.timeout), done))
    rows = []
    for (d, info), res in zip(done, results):
        vis = info.get("visibility")
        diag = None
        try:
            diag = json.load(open(os.path.join(d, "diagnose.json")))
        except Exception:
            pass
        rows.append({"info": info, "res": res, "vis": vis, "j": judge(info, diag, vis)})
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                                cwd=os.path.dirname(os.path.abspath(__file__))).stdout.strip()
    except Exception:
        commit = "unknown"
    head = write_rates(os.path.join(a.out, "rates.md"), rows, a.seeds, time.time() - t0, sha, commit, hs)
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump([{k: r[k] for k in ("res", "vis", "j")} | {"info": {kk: vv for kk, vv in r["info"].items() if kk != "geometry"}}
                   for r in rows], f, indent=1, default=str)
    print(head)
    print(f"wrote {os.path.join(a.out, 'rates.md')}")


if __name__ == "__main__":
    main()
