"""Scorer of the seventh blind generator: runs ``hyperstat diagnose`` on every case, judges it.

    python -m tests.solver.diagnosis.blind5.score --hyperstat PATH --out DIR --seeds 0 --jobs 2

PATH is the ``hyperstat`` executable (e.g. ``/work/main/.venv/bin/hyperstat``) or a checkout
holding ``.venv/bin/hyperstat``.  Writes ``DIR/rates.md`` (the judging rules are RULES.md's),
``DIR/results.json`` and, per campaign, ``DIR/<seed>/<case>/{data,val}.csv, truth.json,
diagnose.json, diagnose.log``.  Units: mm, rad; times in s of wall clock.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import hashlib
import json
import os
import subprocess
import time
from pathlib import Path

from .cases import CASES, PARALLEL
from .generate import MODELS, FAMILIES, write_campaign

HERE = Path(__file__).resolve().parent
VISIBILITY_LINE = 0.6
TIMEOUT_S = 1200
EXPLAINING = ("explained", "partly explained")


def sources_sha256():
    """SHA-256 over the directory's *.py files (sorted by name; name, NUL, bytes, NUL each)."""
    h = hashlib.sha256()
    for p in sorted(HERE.glob("*.py")):
        h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()


def _hyperstat(path):
    p = Path(os.path.abspath(path))
    if p.is_dir():
        exe = p / ".venv" / "bin" / "hyperstat"
        repo = p
    else:
        exe = p
        repo = p.parent
    try:
        commit = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"], capture_output=True, text=True,
                                check=True).stdout.strip()
    except (subprocess.CalledProcessError, FileNotFoundError):
        commit = "unknown"
    try:
        version = subprocess.run([str(exe), "--version"], capture_output=True, text=True).stdout.strip()
    except OSError:
        version = "unknown"
    return str(exe), commit, version


def norm_name(n):
    """Library names compared as written; an angle-harmonic order compared as a number."""
    n = str(n)
    if n.startswith("angle-harmonic-"):
        try:
            return "angle-harmonic-%g" % float(n[len("angle-harmonic-"):])
        except ValueError:
            return n
    return n


def judge(truth, res):
    """The verdict of one campaign under RULES.md.  res: diagnose's JSON or {"outcome": "FAILED ..."}."""
    kind = truth["kind"]
    outcome = res.get("outcome", "FAILED")
    failed = outcome.startswith("FAILED") or outcome.startswith("TIMEOUT")
    named = [norm_name(n) for n in res.get("named_effects", []) or []]
    sets = res.get("equivalence_sets", []) or []
    members = set(named)
    for s in sets:
        members.update(norm_name(m) for m in s.get("members", []))
    conf = res.get("confidence", "")
    below = kind in ("in", "out") and truth["visibility"] < VISIBILITY_LINE
    v = {"failed": failed, "below": below, "named": False, "outright": False, "wrong": False, "honest": False,
         "false_alarm": False, "flagged": False, "right_joint": "-"}
    if kind == "in":
        t = norm_name(truth["truth"])
        if outcome in EXPLAINING and t in members:
            v["named"] = True
            if named == [t] and not any(len(s.get("members", [])) > 1 for s in sets):
                v["outright"] = True
        if outcome in EXPLAINING and conf == "high" and t not in members:
            v["wrong"] = True
        if truth.get("joints"):
            ej = res.get("effect_joints", {}) or {}
            got = None
            for k, js in ej.items():
                if norm_name(k) == t:
                    got = {str(j) for j in js}
            if got is not None:
                want = set(truth["joints"])
                v["right_joint"] = "yes" if got == want else ("part" if got & want else "no")
            elif v["named"]:
                v["right_joint"] = "none given"
        v["verdict"] = ("FAILED" if failed else "outright" if v["outright"] else "named" if v["named"]
                        else "confidently wrong" if v["wrong"] else "missed")
    elif kind == "out":
        v["honest"] = (outcome in ("unexplained", "partly explained")) or (outcome == "explained" and conf == "low")
        v["wrong"] = outcome == "explained" and conf == "high"
        v["verdict"] = ("FAILED" if failed else "honest" if v["honest"] else "confidently wrong" if v["wrong"]
                        else "not honest")
    elif kind == "none":
        v["false_alarm"] = outcome != "no significant gap"
        v["verdict"] = "false alarm" if v["false_alarm"] else "right"
    elif kind == "under":
        v["flagged"] = outcome == "understated noise"
        v["verdict"] = "flagged" if v["flagged"] else "not flagged"
    v["outcome"], v["named_effects"], v["confidence"] = outcome, named, conf
    v["sets"] = ["|".join(s.get("members", [])) for s in sets]
    return v


def run_one(exe, case, cdir):
    model = MODELS / FAMILIES[case["family"]]["model"]
    cmd = ["nice", "-n", "5", exe, "diagnose", str(model), str(cdir / "data.csv"), "--validation",
           str(cdir / "val.csv"), "--json", str(cdir / "diagnose.json"), "--quiet"]
    t0 = time.time()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S)
        secs = time.time() - t0
        (cdir / "diagnose.log").write_text("$ %s\nexit %d\n%s\n%s" % (" ".join(cmd), p.returncode, p.stdout,
                                                                          p.stderr))
        if p.returncode != 0 or not (cdir / "diagnose.json").exists():
            last = (p.stderr.strip().splitlines() or ["?"])[-1][:200]
            return {"outcome": "FAILED (exit %d: %s)" % (p.returncode, last)}, secs
        return json.loads((cdir / "diagnose.json").read_text()), secs
    except subprocess.TimeoutExpired:
        return {"outcome": "TIMEOUT (> %d s)" % TIMEOUT_S}, time.time() - t0


def _rate(k, n):
    return "%d/%d (%s)" % (k, n, ("%.0f %%" % (100.0 * k / n)) if n else "-")


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--hyperstat", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", default=None, help="comma-separated case ids (the smoke run)")
    a = ap.parse_args(argv)
    exe, commit, version = _hyperstat(a.hyperstat)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    seeds = [int(s) for s in a.seeds.split(",")]
    only = set(a.only.split(",")) if a.only else None
    cases = [c for c in CASES if only is None or c["id"] in only]
    t_start = time.time()
    # the longest first (the hexapod, then the Tripteor), so that two jobs end together
    first = {"hexapod": 0, "tripteor_x7": 1}
    jobs = sorted(((seed, case, out / str(seed) / case["id"]) for seed in seeds for case in cases),
                  key=lambda j: first.get(j[1]["family"], 2))
    t_gen = [0.0]

    def job(seed, case, cdir):
        # each worker writes its campaign, then diagnoses it (generation overlaps the other job's diagnose)
        t0 = time.time()
        _, truth = write_campaign(case, cdir, seed)
        t_gen[0] += time.time() - t0
        res, secs = run_one(exe, case, cdir)
        return truth, res, secs

    results = []
    with cf.ThreadPoolExecutor(max_workers=a.jobs) as pool:
        futs = {pool.submit(job, seed, case, cdir): (seed, case) for seed, case, cdir in jobs}
        for f in cf.as_completed(futs):
            seed, case = futs[f]
            truth, res, secs = f.result()
            v = judge(truth, res)
            results.append({"seed": seed, "case": case["id"], "family": case["family"], "kind": case["kind"],
                            "truth": truth, "secs": secs, "judge": v})
            print("%-22s %-6s %-20s vis %5.2f  %-18s %-30s %s  %.0f s" % (
                case["id"], case["kind"], case.get("truth") or "-", truth["visibility"], v["outcome"][:18],
                ",".join(v["named_effects"])[:30], v["verdict"], secs), flush=True)
    order = {c["id"]: i for i, c in enumerate(CASES)}
    results.sort(key=lambda r: (r["seed"], order[r["case"]]))
    wall = time.time() - t_start
    (out / "results.json").write_text(json.dumps(results, indent=1, default=float))
    write_rates(out / "rates.md", results, exe, commit, version, seeds, a.jobs, wall, t_gen[0])
    print("wrote", out / "rates.md")


def write_rates(path, results, exe, commit, version, seeds, jobs, wall, t_gen):
    def sel(pred):
        return [r for r in results if pred(r)]
    counted = sel(lambda r: r["kind"] in ("in", "out") and not r["judge"]["below"])
    ins = [r for r in counted if r["kind"] == "in"]
    ins_par = [r for r in ins if r["family"] in PARALLEL]
    ins_ser = [r for r in ins if r["family"] not in PARALLEL]
    outs = [r for r in counted if r["kind"] == "out"]
    nones = sel(lambda r: r["kind"] == "none")
    unders = sel(lambda r: r["kind"] == "under")
    below = sel(lambda r: r["judge"]["below"])
    failed = sel(lambda r: r["judge"]["failed"])
    n = lambda rs, key: sum(1 for r in rs if r["judge"][key])  # noqa: E731
    lines = [
        "# Seventh blind generator (blind5 directory): rates",
        "",
        "Units: visibility is a ratio (held-out RMS of the noise-free effect after this generator's own",
        "linearised rigid fit, over the stated noise's RMS, both 3-D); times in s of wall clock.",
        "",
        "* generator sources: SHA-256 of `tests/solver/diagnosis/blind5/*.py` = `%s`" % sources_sha256(),
        "* code under test: `%s` (%s), commit `%s`" % (exe, version, commit),
        "* seeds %s, `--jobs %d`, per-campaign timeout %d s, visibility line %.2f" % (
            ",".join(map(str, seeds)), jobs, TIMEOUT_S, VISIBILITY_LINE),
        "* wall time %.0f s (generation %.0f s of it, summed over the jobs); %d campaigns" % (wall, t_gen, len(results)),
        "",
        "## Rates (judging rules: RULES.md)",
        "",
        "| rate | value |",
        "|---|---|",
        "| in-library named, parallel (Tripteor X7, hexapod) | %s |" % _rate(n(ins_par, "named"), len(ins_par)),
        "| in-library named, serial | %s |" % _rate(n(ins_ser, "named"), len(ins_ser)),
        "| in-library named, all | %s |" % _rate(n(ins, "named"), len(ins)),
        "| in-library named outright | %s |" % _rate(n(ins, "outright"), len(ins)),
        "| in-library confidently wrong | %s |" % _rate(n(ins, "wrong"), len(ins)),
        "| out-of-library honest | %s |" % _rate(n(outs, "honest"), len(outs)),
        "| out-of-library confidently wrong | %s |" % _rate(n(outs, "wrong"), len(outs)),
        "| false alarms (no effect) | %s |" % _rate(n(nones, "false_alarm"), len(nones)),
        "| understated noise flagged | %s |" % _rate(n(unders, "flagged"), len(unders)),
        "| below the visibility line (not counted) | %d |" % len(below),
        "| diagnose failures (error or timeout, counted as misses) | %d |" % len(failed),
        "",
        "## Every campaign",
        "",
        "| seed | family | case | kind | truth | visibility | outcome | named | sets | confidence | verdict | "
        "right joint | s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        j = r["judge"]
        lines.append("| %d | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s%s | %s | %.0f |" % (
            r["seed"], r["family"], r["case"], r["kind"], r["truth"].get("truth") or
            ("x%.1f noise" % r["truth"]["understate"] if r["kind"] == "under" else "-"),
            ("%.2f" % r["truth"]["visibility"]) if r["kind"] in ("in", "out") else "-",
            j["outcome"].replace("|", "/"), ", ".join(j["named_effects"]) or "-", "; ".join(j["sets"]) or "-",
            j["confidence"] or "-", j["verdict"], " (below line)" if j["below"] else "", j["right_joint"],
            r["secs"]))
    tmp = Path(str(path) + ".tmp")
    tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, path)


if __name__ == "__main__":
    main()
