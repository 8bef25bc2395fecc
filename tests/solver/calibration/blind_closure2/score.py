"""Scorer of blind closure set 2 (mm, rad).  Imports no hyperstat code: it runs the CLI.

    /work/main/.venv/bin/python -m tests.solver.calibration.blind_closure2.score \
        [--hyperstat PATH] [--out DIR] [--jobs N] [--only NAME[,NAME]] [--data DIR]

Per campaign: `identify` (with --validation, --json), `export-controller` (with --validation);
a refused export again with --force; `check-controller` on every written file; every written or
forced file read with our own reading of the documented controller format (kin.py) and its
reflector positions at the validation poses compared with the generator's noise-free truth.
Judging rules and thresholds: RULES.md.  Writes DIR/rates.md and DIR/results.json.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import glob
import hashlib
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from .kin import Mechanism, kabsch
from . import generate as gen

HERE = os.path.dirname(os.path.abspath(__file__))
TIMEOUT = 600

# judging thresholds (RULES.md)
WRONG_NOISE = 3.0          # prediction error RMS > 3 x the 3-D noise RMS (true noise) ...
WRONG_RECORDED = 2.0       # ... and > 2 x the file's recorded held-out RMS
ACCURATE_NOISE = 1.5       # a refused file is "accurate" when its error RMS <= 1.5 x the 3-D noise RMS
OPTIMISTIC = 0.8           # recorded held-out RMS < 0.8 x sqrt(E^2 + 3 sigma^2): optimistic
CLOSE_TOL = 1e-3           # mm (rotation x length scale): a file geometry that leaves more does not close
READER_TOL = 1e-6          # mm: our reading must reproduce the file's test vectors to this
ALARM_CODES = {"inputs-wrong", "effect-missing"}
EXPLAINING_NOTES = {"closing-geometry-moved", "held-out-above-noise", "no-gain-over-nominal"}


def sha_py():
    lines = []
    for p in sorted(glob.glob(os.path.join(HERE, "*.py"))):
        h = hashlib.sha256(open(p, "rb").read()).hexdigest()
        lines.append("%s  %s" % (h, os.path.basename(p)))
    combined = hashlib.sha256(("\n".join(lines) + "\n").encode()).hexdigest()
    return combined, lines


def git_head(hyperstat):
    d = os.path.dirname(os.path.realpath(hyperstat))
    for _ in range(4):
        if os.path.isdir(os.path.join(d, ".git")) or os.path.isfile(os.path.join(d, ".git")):
            break
        d = os.path.dirname(d)
    try:
        head = subprocess.run(["git", "-C", d, "rev-parse", "HEAD"], capture_output=True, text=True, timeout=30).stdout.strip()
        dirty = subprocess.run(["git", "-C", d, "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True, timeout=60).stdout.strip()
        return d, head, bool(dirty)
    except Exception as e:  # noqa: BLE001
        return d, "unknown (%s)" % e, None


def run(cmd, env):
    t = time.time()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=TIMEOUT)
        return {"cmd": cmd, "rc": p.returncode, "stdout": p.stdout[-4000:], "stderr": p.stderr[-4000:], "seconds": time.time() - t}
    except subprocess.TimeoutExpired:
        return {"cmd": cmd, "rc": "timeout", "stdout": "", "stderr": "timeout after %d s" % TIMEOUT, "seconds": time.time() - t}


def last_sentence(text):
    lines = [l.strip() for l in (text or "").splitlines() if l.strip()]
    err = [l for l in lines if "not written" in l or "error" in l.lower()]
    return (err[-1] if err else (lines[-1] if lines else ""))[:600]


# ------------------------------------------------------------------ our reading of a controller file
def evaluate_file(path, truth, meas_val):
    doc = json.load(open(path))
    ev = {"file": os.path.basename(path)}
    mdl = doc["model"]
    defects = doc["defects"]
    target = doc.get("target", [0.0, 0.0, 0.0])
    if doc.get("targets"):
        ev["note"] = "file has several targets; ours has one"
    mech = Mechanism(mdl, defects)
    q0, res0 = mech.newton(mech.home.copy())[:2]
    ev["home_closure"] = res0
    # reader self-check: the file's test vectors
    dev = 0.0
    nvec = 0
    for v in (doc.get("test_vectors") or {}).get("vectors", [])[:24]:
        q, info = mech.follow(q0, np.array(v["actuated"], float), accept=CLOSE_TOL)
        if not info["ok"]:
            continue
        T = mech.output_pose(q)
        dev = max(dev, float(np.linalg.norm(T[:3, 3] - np.array(v["position"]))))
        nvec += 1
    ev["reader_vectors"] = nvec
    ev["reader_max_dev_mm"] = dev
    # predictions at the validation poses
    pred, true, meas = [], [], []
    unassembled = []
    for k, rec in enumerate(truth["validation"]):
        q, info = mech.follow(q0, np.array(rec["actuated"], float), accept=CLOSE_TOL)
        if not info["ok"] or res0 > CLOSE_TOL:
            unassembled.append(rec["pose"])
            continue
        pred.append(mech.tool_point(q, target))
        true.append(rec["position_base_mm"])
        meas.append(meas_val[rec["pose"]])
    ev["unassembled"] = unassembled
    if len(pred) >= 3:
        P, Q, M = np.array(pred), np.array(true), np.array(meas)
        ev["err_controller_frame_rms"] = float(np.sqrt(np.mean(np.sum((P - Q) ** 2, 1))))
        R, t = kabsch(P, Q)
        E = P @ R.T + t - Q
        ev["err_registered_rms"] = float(np.sqrt(np.mean(np.sum(E ** 2, 1))))
        ev["err_registered_max"] = float(np.max(np.linalg.norm(E, axis=1)))
        R2, t2 = kabsch(P, M)
        E2 = P @ R2.T + t2 - M
        ev["heldout_vs_measured_registered_rms"] = float(np.sqrt(np.mean(np.sum(E2 ** 2, 1))))
    stats = doc.get("statistics", {})
    ev["recorded_validation_rms"] = (stats.get("validation") or {}).get("rms")
    ev["recorded_identification_rms"] = (stats.get("identification") or {}).get("rms")
    cal = doc.get("calibration", {})
    ev["fit_quality"] = cal.get("fit_quality")
    ev["forced"] = cal.get("forced")
    ev["reasons"] = cal.get("reasons")
    ev["findings"] = [{"code": f.get("code"), "refuses": f.get("refuses"), "message": (f.get("message") or "")[:400]}
                      for f in cal.get("findings", [])]
    return ev


def read_val(path):
    out = {}
    with open(path) as fh:
        rows = [l.strip() for l in fh if l.strip() and not l.startswith("#")]
    cols = rows[0].split(",")
    ix = [cols.index("x[mm]"), cols.index("y[mm]"), cols.index("z[mm]")]
    for r in rows[1:]:
        v = r.split(",")
        out[v[0]] = [float(v[i]) for i in ix]
    return out


# ------------------------------------------------------------------ one campaign
def score_campaign(camp, a):
    name, key = camp[0], camp[1]
    data = os.path.join(a.data, name + ".csv")
    val = os.path.join(a.data, name + ".validation.csv")
    truth = json.load(open(os.path.join(a.data, name + ".truth.json")))
    model = gen.model_path(key)
    out = os.path.join(a.out, name)
    os.makedirs(out, exist_ok=True)
    r = {"campaign": name, "mechanism": key, "over_constrained": truth["over_constrained"],
         "sigma": truth["noise_sigma_per_axis_mm"], "stated": truth["noise_stated_mm"],
         "understatement": truth["understatement"], "sound": truth["sound"],
         "poses": len(truth["identification"]), "validation_poses": len(truth["validation"]),
         "defect_scale_mm": truth["defect_scale_mm"]}
    noise3 = math.sqrt(3.0) * r["sigma"]
    r["noise3_rms"] = noise3
    with tempfile.TemporaryDirectory(prefix="bc2cache_") as cache:
        env = dict(os.environ, HYPERSTAT_CACHE=cache, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
        idj = os.path.join(out, "identify.json")
        ri = run([a.hyperstat, "identify", model, data, "--validation", val, "--json", idj], env)
        r["identify"] = {"rc": ri["rc"], "seconds": ri["seconds"], "stderr_tail": ri["stderr"][-1500:]}
        if os.path.exists(idj) and ri["rc"] == 0:
            j = json.load(open(idj))
            r["identify"].update({
                "fit_quality": j.get("fit_quality"), "sigma": j.get("sigma"), "rank": j.get("rank"),
                "unknowns": j.get("unknowns"), "condition_number": j.get("condition_number"),
                "identification_rms": (j.get("identification") or {}).get("rms"),
                "validation_rms": (j.get("validation") or {}).get("rms"),
                "nominal_validation_rms": ((j.get("nominal") or {}).get("validation") or {}).get("rms"),
                "noise_rms": j.get("noise_rms"),
                "findings": [{"code": f.get("code"), "refuses": f.get("refuses"),
                              "message": (f.get("message") or f.get("reason") or "")[:400]} for f in j.get("findings", [])],
            })
        mf = os.path.join(out, "machine.json")
        re_ = run([a.hyperstat, "export-controller", model, data, "--validation", val, "--out", mf], env)
        r["export"] = {"rc": re_["rc"], "seconds": re_["seconds"], "stderr_tail": re_["stderr"][-1500:],
                       "sentence": last_sentence(re_["stderr"]) if re_["rc"] != 0 else ""}
        files = []
        if re_["rc"] == 0 and os.path.exists(mf):
            files.append(("written", mf))
        else:
            ff = os.path.join(out, "machine.forced.json")
            rf = run([a.hyperstat, "export-controller", model, data, "--validation", val, "--out", ff, "--force"], env)
            r["forced_export"] = {"rc": rf["rc"], "seconds": rf["seconds"], "stderr_tail": rf["stderr"][-1500:]}
            if rf["rc"] == 0 and os.path.exists(ff):
                files.append(("forced", ff))
        meas_val = read_val(val)
        for kind, path in files:
            cj = os.path.join(out, os.path.basename(path).replace(".json", ".check.json"))
            rc = run([a.hyperstat, "check-controller", path, "--json", cj], env)
            try:
                ev = evaluate_file(path, truth, meas_val)
            except Exception as e:  # noqa: BLE001 - our own reader failing is reported, not hidden
                ev = {"file": os.path.basename(path), "reader_error": "%s: %s" % (type(e).__name__, e)}
            ev["check_rc"] = rc["rc"]
            ev["check_sentence"] = last_sentence(rc["stderr"]) if rc["rc"] != 0 else ""
            r[kind] = ev
    judge(r)
    return r


# ------------------------------------------------------------------ judging (RULES.md)
def is_wrong(ev, noise3):
    if "reader_error" in ev:
        return None
    if ev.get("unassembled") or ev.get("check_rc") != 0:
        return True
    e = ev.get("err_registered_rms")
    rec = ev.get("recorded_validation_rms")
    if e is None:
        return True
    return bool(e > WRONG_NOISE * noise3 and (rec is None or e > WRONG_RECORDED * rec))


def judge(r):
    noise3 = r["noise3_rms"]
    idf = r["identify"]
    codes = {f["code"] for f in idf.get("findings", [])}
    j = {}
    alarm = bool(codes & ALARM_CODES) or idf.get("fit_quality") in ("inputs wrong", "model misses an effect")
    j["identify_alarm"] = alarm
    j["identify_failed"] = idf["rc"] != 0
    refused = r["export"]["rc"] != 0
    j["refused"] = refused
    if r["sound"]:
        j["false_alarm"] = alarm
    else:
        flagged = alarm or refused or (idf.get("fit_quality") not in (None, "ok"))
        if "written" in r:
            flagged = flagged or (r["written"].get("fit_quality") not in (None, "ok"))
        j["understated_flagged"] = flagged
    if "written" in r:
        ev = r["written"]
        w = is_wrong(ev, noise3)
        notes = {f["code"] for f in ev.get("findings", []) if not f.get("refuses")}
        j["wrong"] = w
        j["confident_wrong"] = bool(w) and not (notes & EXPLAINING_NOTES)
        j["wrong_with_note"] = bool(w) and bool(notes & EXPLAINING_NOTES)
    if "forced" in r:
        ev = r["forced"]
        w = is_wrong(ev, noise3)
        e = ev.get("err_registered_rms")
        accurate = (w is False) and e is not None and e <= ACCURATE_NOISE * noise3 and ev.get("check_rc") == 0
        j["forced_wrong"] = w
        j["forced_accurate"] = accurate
        if r["sound"] and refused:
            j["needless_refusal"] = accurate
            j["refusal_reason"] = r["export"]["sentence"]
    for kind in ("written", "forced"):
        ev = r.get(kind)
        if ev and ev.get("err_registered_rms") is not None and ev.get("recorded_validation_rms") is not None:
            expect = math.sqrt(ev["err_registered_rms"] ** 2 + 3.0 * r["sigma"] ** 2)
            j["heldout_optimistic"] = bool(ev["recorded_validation_rms"] < OPTIMISTIC * expect)
            j["heldout_expected"] = expect
            if idf.get("validation_rms") is not None:
                j["identify_heldout_optimistic"] = bool(idf["validation_rms"] < OPTIMISTIC * expect)
        if ev and ev.get("reader_max_dev_mm", 0.0) > READER_TOL:
            j["reader_mismatch"] = True
    r["judged"] = j


# ------------------------------------------------------------------ report
def f3(v, fmt="%.4f"):
    if v is None:
        return "-"
    if isinstance(v, bool) or isinstance(v, int) or not isinstance(v, float):
        return str(v)
    return fmt % v


def write_rates(results, a, t0):
    combined, lines = sha_py()
    repo, head, dirty = git_head(a.hyperstat)
    L = ["# Blind closure set 2: rates", "",
         "Units: lengths in mm, angles in rad.  Errors are RMS of 3-D norms over the 30 validation poses.", "",
         "* hyperstat: `%s` (checkout `%s`, git HEAD `%s`%s)" % (a.hyperstat, repo, head, ", working tree modified" if dirty else ""),
         "* SHA-256 of this directory's *.py files (combined over the lines below): `%s`" % combined]
    L += ["  * `%s`" % l for l in lines]
    L += ["* wall time %.0f s, jobs %d" % (time.time() - t0, a.jobs), ""]
    L += ["## Per campaign", "",
          "| campaign | mechanism | OC | sigma (mm) | stated (mm) | poses | identify fit / sigma / codes | export | file err reg. (mm) | err ctrl frame (mm) | recorded val RMS (mm) | 3-D noise (mm) | check | verdict |",
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    counts = {"sound": 0, "understated": 0, "written": 0, "confident_wrong": 0, "wrong_with_note": 0, "false_alarm": 0,
              "needless_refusal": 0, "mediocre_refusal": 0, "justified_refusal": 0, "understated_flagged": 0,
              "heldout_optimistic": 0, "files": 0, "check_fail": 0, "reader_mismatch": 0, "identify_failed": 0,
              "id_optimistic": 0}
    reasons = []
    for r in results:
        j = r.get("judged", {})
        idf = r["identify"]
        ev = r.get("written") or r.get("forced") or {}
        verdict = []
        if r["sound"]:
            counts["sound"] += 1
            if j.get("false_alarm"):
                counts["false_alarm"] += 1
                verdict.append("FALSE ALARM")
        else:
            counts["understated"] += 1
            if j.get("understated_flagged"):
                counts["understated_flagged"] += 1
                verdict.append("understated flagged")
            else:
                verdict.append("UNDERSTATED NOT FLAGGED")
        if j.get("identify_failed"):
            counts["identify_failed"] += 1
            verdict.append("identify rc %s" % idf["rc"])
        if "written" in r:
            counts["written"] += 1
            if j.get("confident_wrong"):
                counts["confident_wrong"] += 1
                verdict.append("CONFIDENT WRONG")
            elif j.get("wrong_with_note"):
                counts["wrong_with_note"] += 1
                verdict.append("wrong with a note")
        if j.get("refused"):
            if "forced" not in r:
                verdict.append("refused; forced export failed")
            elif j.get("forced_wrong"):
                counts["justified_refusal"] += r["sound"]
                verdict.append("refused (forced file wrong)")
            elif j.get("forced_accurate"):
                if r["sound"]:
                    counts["needless_refusal"] += 1
                    verdict.append("NEEDLESS REFUSAL")
                    reasons.append((r["campaign"], j.get("refusal_reason", "")))
                else:
                    verdict.append("refused (forced file accurate)")
            else:
                counts["mediocre_refusal"] += r["sound"]
                verdict.append("refused (forced file between 1.5x and the wrong line)")
        for kind in ("written", "forced"):
            if kind in r:
                counts["files"] += 1
                if r[kind].get("check_rc") != 0:
                    counts["check_fail"] += 1
        if j.get("heldout_optimistic"):
            counts["heldout_optimistic"] += 1
            verdict.append("held-out optimistic")
        if j.get("identify_heldout_optimistic"):
            counts["id_optimistic"] += 1
        if j.get("reader_mismatch"):
            counts["reader_mismatch"] += 1
            verdict.append("OUR READER DISAGREES WITH THE FILE'S VECTORS")
        codes = ",".join(sorted({f["code"] for f in idf.get("findings", [])})) or "-"
        L.append("| %s | %s | %s | %.3f | %.4g | %d+%d | %s / %s / %s | %s | %s | %s | %s | %.4f | %s | %s |" % (
            r["campaign"], r["mechanism"], "yes" if r["over_constrained"] else "no", r["sigma"], r["stated"],
            r["poses"], r["validation_poses"], idf.get("fit_quality", "rc %s" % idf["rc"]), f3(idf.get("sigma"), "%.3g"), codes,
            "written" if "written" in r else ("refused, forced" if "forced" in r else "refused, no file"),
            f3(ev.get("err_registered_rms")), f3(ev.get("err_controller_frame_rms")), f3(ev.get("recorded_validation_rms")),
            r["noise3_rms"], f3(ev.get("check_rc")), "; ".join(verdict) or "ok"))

    def rate(n, d):
        return "%d / %d" % (n, d) + ("" if d == 0 else " (%.0f %%)" % (100.0 * n / d))
    L += ["", "## Rates", "",
          "* confident wrong (written without --force, no explaining note, error > %g x 3-D noise and > %g x recorded held-out RMS, or unassembled, or check-controller refuses): **%s** of written files" % (WRONG_NOISE, WRONG_RECORDED, rate(counts["confident_wrong"], counts["written"])),
          "* wrong with an explaining note: %s of written files" % rate(counts["wrong_with_note"], counts["written"]),
          "* false alarm (sound campaign called inputs-wrong / effect-missing by identify): **%s** of sound campaigns" % rate(counts["false_alarm"], counts["sound"]),
          "* needless refusal (sound campaign refused, forced file error <= %g x 3-D noise, assembled, checked): **%s** of sound campaigns" % (ACCURATE_NOISE, rate(counts["needless_refusal"], counts["sound"])),
          "* refusal of a sound campaign whose forced file is between %g x noise and the wrong line: %s" % (ACCURATE_NOISE, rate(counts["mediocre_refusal"], counts["sound"])),
          "* refusal of a sound campaign whose forced file is wrong (justified): %s" % rate(counts["justified_refusal"], counts["sound"]),
          "* understated noise flagged: **%s** of understated campaigns" % rate(counts["understated_flagged"], counts["understated"]),
          "* held-out optimistic (the file's recorded held-out RMS < %g x sqrt(E^2 + 3 sigma^2)): **%s** of evaluated files (identify's own held-out RMS: %s)" % (OPTIMISTIC, rate(counts["heldout_optimistic"], len(results)), rate(counts["id_optimistic"], len(results))),
          "* check-controller refusals: %s of files (written and forced)" % rate(counts["check_fail"], counts["files"]),
          "* our reader disagreeing with a file's test vectors (> %g mm): %d" % (READER_TOL, counts["reader_mismatch"]),
          "* identify failing (non-zero exit): %d" % counts["identify_failed"], ""]
    if reasons:
        L += ["## Needless refusals, with the stated reason", ""]
        L += ["* %s: %s" % (c, s) for c, s in reasons]
        L.append("")
    L += ["## Findings per campaign (identify)", ""]
    for r in results:
        fs = r["identify"].get("findings", [])
        L.append("* %s: %s" % (r["campaign"], "; ".join("%s%s: %s" % (f["code"], " (refuses)" if f.get("refuses") else "", f["message"][:200]) for f in fs) or "none"))
    L.append("")
    L += ["## Refusal sentences", ""]
    for r in results:
        if r["export"]["rc"] != 0:
            L.append("* %s (exit %s): %s" % (r["campaign"], r["export"]["rc"], r["export"]["sentence"]))
    with open(os.path.join(a.out, "rates.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")
    with open(os.path.join(a.out, "results.json"), "w") as fh:
        json.dump({"sha256_py": combined, "hyperstat": a.hyperstat, "git_head": head, "results": results, "counts": counts}, fh, indent=1, default=str)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--hyperstat", default="/work/main/.venv/bin/hyperstat")
    ap.add_argument("--out", default="blind_closure2_out")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--only", default=None, help="campaign name(s), comma-separated")
    ap.add_argument("--data", default=os.path.join(HERE, "campaigns"), help="campaign files (written by generate.py when missing)")
    a = ap.parse_args(argv)
    a.out = os.path.abspath(a.out)
    a.data = os.path.abspath(a.data)
    a.hyperstat = os.path.abspath(a.hyperstat) if os.sep in a.hyperstat else a.hyperstat
    os.makedirs(a.out, exist_ok=True)
    only = set(a.only.split(",")) if a.only else None
    camps = [c for c in gen.CAMPAIGNS if not only or c[0] in only]
    gen.write_models()
    for c in camps:
        if not os.path.exists(os.path.join(a.data, c[0] + ".truth.json")):
            gen.generate(c, a.data)
    t0 = time.time()
    results = []
    with cf.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
        futs = {ex.submit(score_campaign, c, a): c for c in camps}
        for f in cf.as_completed(futs):
            c = futs[f]
            try:
                r = f.result()
            except Exception as e:  # noqa: BLE001
                r = {"campaign": c[0], "mechanism": c[1], "over_constrained": gen.OVER_CONSTRAINED[c[1]], "sigma": c[2],
                     "stated": c[2] / c[5], "understatement": c[5], "sound": c[5] == 1, "poses": c[3], "validation_poses": gen.N_VALIDATION,
                     "noise3_rms": math.sqrt(3) * c[2], "identify": {"rc": "scorer error: %s: %s" % (type(e).__name__, e)},
                     "export": {"rc": "scorer error", "sentence": ""}, "judged": {}}
            results.append(r)
            print("%-5s identify rc %s, export rc %s, %s" % (c[0], r["identify"]["rc"], r["export"]["rc"], r.get("judged")), flush=True)
    order = {c[0]: i for i, c in enumerate(gen.CAMPAIGNS)}
    results.sort(key=lambda r: order[r["campaign"]])
    write_rates(results, a, t0)
    print("wrote %s" % os.path.join(a.out, "rates.md"))


if __name__ == "__main__":
    main()
