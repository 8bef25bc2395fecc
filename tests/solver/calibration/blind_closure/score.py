"""Scorer of the blind closure calibration set (see RULES.md).  Units: mm, rad.

    python -m tests.solver.calibration.blind_closure.score [--hyperstat PATH] [--out DIR]
           [--jobs N] [--only NAME ...]

Generates the campaigns (generate.py), runs `hyperstat identify` and `hyperstat
export-controller` (again with --force when refused) and `hyperstat check-controller` on every
file written, reads every controller file with OUR OWN reading of the documented format
(kin.py: docs/controller-format.md "Reference model", docs/model-format.md), predicts the
validation poses from the file alone on the branch of the home, compares with the noise-free
truth and judges with the thresholds of RULES.md.  Writes DIR/rates.md and DIR/results.json.
Does NOT import hyperstat.
"""
import argparse
import concurrent.futures as cf
import glob
import hashlib
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np

from . import generate as G
from . import kin

HERE = os.path.dirname(os.path.abspath(__file__))
TIMEOUT = 600

# thresholds (RULES.md)
CW_NOISE = 3.0        # confident wrong: E > 3 x stated 3-D noise RMS ...
CW_RECORD = 2.0       # ... and E > 2 x the file's recorded held-out RMS
ACCURATE = 1.5        # a refused file would have been accurate: E <= 1.5 x the used 3-D noise RMS
OPTIMISTIC = 1.5      # held-out statistic optimistic: file's residual RMS on the held-out data > 1.5 x reported
READER_TOL = 1e-6     # our reading of the file must reproduce its test vectors to 1e-6 mm
ASSEMBLE_TOL = 1e-6   # the file's geometry assembles: closure residual < 1e-6 (mm, L-scaled rotation)
BRANCH_RAD = 0.1      # passive joints farther than this from the truth: another branch


def py_sha256():
    lines = []
    for p in sorted(glob.glob(os.path.join(HERE, "*.py"))):
        with open(p, "rb") as f:
            lines.append("%s %s" % (os.path.basename(p), hashlib.sha256(f.read()).hexdigest()))
    return hashlib.sha256(("\n".join(lines) + "\n").encode()).hexdigest(), lines


def run(cmd, env, log):
    t0 = time.time()
    try:
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=TIMEOUT)
        rc, out, err = p.returncode, p.stdout, p.stderr
    except subprocess.TimeoutExpired as e:
        rc, out, err = "timeout", (e.stdout or b"").decode() if isinstance(e.stdout, bytes) else (e.stdout or ""), \
            (e.stderr or b"").decode() if isinstance(e.stderr, bytes) else (e.stderr or "")
    dt = time.time() - t0
    with open(log, "w") as f:
        f.write("$ %s\n# rc=%s  %.1f s\n--- stdout\n%s\n--- stderr\n%s\n" % (" ".join(cmd), rc, dt, out, err))
    return rc, out, err, dt


def load_json(p):
    try:
        with open(p) as f:
            return json.load(f)
    except Exception:
        return None


def header_prior(csv):
    tr = tg = None
    with open(csv) as f:
        for line in f:
            if not line.startswith("#"):
                break
            if line.startswith("# tracker:"):
                tr = [float(v) for v in line.split(":", 1)[1].split()]
            if line.startswith("# target:"):
                tg = [float(v) for v in line.split(":", 1)[1].split()]
    return tr, tg


def _tracker_vals(entries):
    vals = {}
    for e in entries or []:
        if str(e.get("kind", "")).lower() != "tracker":
            continue
        nm = str(e.get("name", "")).lower()
        m = re.search(r"(r[xyz]|[xyz])$", nm)
        if m and e.get("estimate") is not None:
            vals[m.group(1)] = float(e["estimate"])
    return vals


def tracker_from_file(doc, prior, id_params):
    """(origin, rotvec, components not in the file, components from the header prior).
    The file lists the identified tracker components; the others (held at their value, seen only
    in combination) are taken from identify's JSON `parameters` of the same inputs, else the
    data file's header prior."""
    vals = _tracker_vals(doc.get("identified"))
    idv = _tracker_vals(id_params)
    keys = ["x", "y", "z", "rx", "ry", "rz"]
    missing = [k for k in keys if k not in vals]
    from_prior = [k for k in missing if k not in idv]
    v = [vals.get(k, idv.get(k, prior[i])) for i, k in enumerate(keys)]
    return np.array(v[:3]), np.array(v[3:]), missing, from_prior, bool(vals)


def vec_joints(mech, j):
    if isinstance(j, dict):
        return np.array([float(j[n[0]]) for n in mech.joints])
    return np.array([float(x) for x in j])


def predict(mech, target, X):
    """Follow the file's geometry from its home through X; None where it does not assemble."""
    q, nr, ok = mech.solve(mech.home.copy())
    out, qs = [], []
    if not ok:
        return [None] * len(X), [None] * len(X), nr
    worst = nr
    for x in X:
        q2, wr, wj, ok = mech.continue_to(q, x)
        if not ok:
            out.append(None)
            qs.append(None)
            continue
        q = q2
        worst = max(worst, wr)
        out.append(mech.tool(q, target)[0])
        qs.append(q.copy())
    return out, qs, worst


def rms(E):
    E = np.asarray(E, float)
    return float(np.sqrt((E ** 2).sum(-1).mean())) if len(E) else float("nan")


def evaluate_file(path, truth, data_csv, hs, env, outdir, tag, id_params):
    """Our reading of one controller file, its predictions and errors."""
    res = {"file": os.path.basename(path)}
    rc, out, err, _ = run([hs, "check-controller", path], env, os.path.join(outdir, "check_%s.log" % tag))
    res["check_controller_rc"] = rc
    doc = load_json(path)
    if doc is None:
        res["error"] = "unreadable JSON"
        return res
    try:
        model, defects = doc["model"], doc["defects"]
        target = doc.get("target", [0, 0, 0])
        if doc.get("targets"):
            target = list(doc["targets"].values())[0]
        mech = kin.Mechanism(model, defects)
        mech.accept = ASSEMBLE_TOL
    except Exception as e:  # our reader cannot build it
        res["error"] = "reader: %r" % (e,)
        return res
    # reader self-check on the file's own test vectors (forward with every joint given)
    dev = 0.0
    nvec = 0
    for v in (doc.get("test_vectors", {}) or {}).get("vectors", []):
        try:
            q = vec_joints(mech, v["joints"])
            p = mech.tool(q, target)[0]
            dev = max(dev, float(np.linalg.norm(p - np.asarray(v["tool_point"], float))))
            nvec += 1
        except Exception as e:
            res["reader_vector_error"] = repr(e)
            dev = float("inf")
    res["reader_vectors"] = nvec
    res["reader_max_dev_mm"] = dev
    res["reader_ok"] = bool(nvec > 0 and dev < READER_TOL)
    # predictions on the branch of the home
    Xv = truth["validation"]["actuated"]
    Xi = truth["identification"]["actuated"]
    pv, qv, worst_v = predict(mech, target, Xv)
    pi_, _, _ = predict(mech, target, Xi)
    res["not_assembled_val"] = sum(p is None for p in pv)
    res["not_assembled_id"] = sum(p is None for p in pi_)
    res["max_closure_residual"] = float(worst_v)
    ok_v = [k for k, p in enumerate(pv) if p is not None]
    ok_i = [k for k, p in enumerate(pi_) if p is not None]
    tr_prior, _ = header_prior(data_csv)
    o, rv, missing, from_prior, has = tracker_from_file(doc, tr_prior, id_params)
    res["tracker_in_file"] = has
    res["tracker_not_in_file"] = missing
    res["tracker_from_header_prior"] = from_prior
    Tv = np.asarray(truth["validation"]["tracker_mm"])
    Bv = np.asarray(truth["validation"]["base_mm"])
    Mv = np.asarray(truth["validation"]["measured_mm"])
    Mi = np.asarray(truth["identification"]["measured_mm"])
    if not ok_v:
        res["E_judge"] = float("inf")
        return res
    Pv = np.array([pv[k] for k in ok_v])
    # convention of the tracker pose: the one that fits the identification data the file saw
    R = kin.rotvec(rv)
    convs = {"base_from_tracker": lambda P: (P - o) @ R, "tracker_from_base": lambda P: P @ R.T + o}
    best = None
    if ok_i:
        Pi = np.array([pi_[k] for k in ok_i])
        for nm, f in convs.items():
            e = rms(f(Pi) - Mi[ok_i])
            if best is None or e < best[1]:
                best = (nm, e)
        res["tracker_convention"] = best[0]
        res["id_rms_ours"] = best[1]
    conv = convs[best[0] if best else "base_from_tracker"]
    res["E_trk"] = rms(conv(Pv) - Tv[ok_v])
    res["V_ours"] = rms(conv(Pv) - Mv[ok_v])
    res["E_reg"] = kin.kabsch(Pv, Bv[ok_v])[2]
    res["E_base"] = rms(Pv - Bv[ok_v])
    # branch: passive joints against the truth
    qt = truth["validation"]["joints"]
    dq = 0.0
    for k in ok_v:
        a = np.asarray(qv[k])[mech.pas]
        b = np.asarray(qt[k])[mech.pas]
        d = np.abs(np.angle(np.exp(1j * (a - b))))
        dq = max(dq, float(d.max()) if len(d) else 0.0)
    res["max_passive_vs_truth_rad"] = dq
    res["other_branch"] = dq > BRANCH_RAD
    judged_by = "tracker frame of the file" if (has and res["reader_ok"]) else "rigid registration"
    res["judged_by"] = judged_by
    res["E_judge"] = res["E_trk"] if judged_by.startswith("tracker") else res["E_reg"]
    if res["not_assembled_val"]:
        res["E_judge"] = float("inf")
    st = doc.get("statistics", {}) or {}
    res["V_file"] = (st.get("validation") or {}).get("rms")
    res["I_file"] = (st.get("identification") or {}).get("rms")
    cal = doc.get("calibration", {}) or {}
    res["fit_quality"] = cal.get("fit_quality")
    res["forced"] = cal.get("forced")
    return res


def _read_err(log):
    try:
        with open(log) as f:
            txt = f.read()
    except OSError:
        return []
    err = txt.split("--- stderr", 1)[-1]
    return [ln for ln in err.strip().splitlines() if ln.strip()]


def codes_of(idj):
    out = []
    for f in (idj or {}).get("findings", []) or []:
        if isinstance(f, dict):
            out.append((f.get("code"), bool(f.get("refuses"))))
    return out


def score_campaign(name, gendir, hs, outroot, cache):
    truth = load_json(os.path.join(gendir, name, "truth.json"))
    d = os.path.join(outroot, "runs", name)
    os.makedirs(d, exist_ok=True)
    env = dict(os.environ, HYPERSTAT_CACHE=cache, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    model = os.path.join(HERE, truth["model_file"])
    data = os.path.join(gendir, name, "data.csv")
    val = os.path.join(gendir, name, "val.csv")
    r = {"campaign": name, "mechanism": truth["mechanism"], "overconstrained": truth["overconstrained"],
         "sound": truth["sound"], "noise_used_mm": truth["noise_used_mm"],
         "noise_stated_mm": truth["noise_stated_mm"], "n_id": truth["n_id"], "n_val": truth["n_val"],
         "defect_size": truth["defect_size"], "region": truth["region"]}
    idj = os.path.join(d, "identify.json")
    rc, out, err, dt = run([hs, "identify", model, data, "--validation", val, "--json", idj], env,
                           os.path.join(d, "identify.log"))
    r["identify_rc"], r["identify_s"] = rc, round(dt, 1)
    j = load_json(idj) if rc != "timeout" else None
    r["identify_answered"] = j is not None
    id_params = (j or {}).get("parameters") or []
    text = (out + "\n" + err).lower()
    if j is not None:
        r["codes"] = codes_of(j)
        r["sigma"] = j.get("sigma")
        r["V_identify"] = (j.get("validation") or {}).get("rms")
        r["I_identify"] = (j.get("identification") or {}).get("rms")
        r["noise_rms_identify"] = j.get("noise_rms")
        r["rank"], r["unknowns"] = j.get("rank"), j.get("unknowns")
    else:
        r["codes"] = []
    codes = [c for c, _ in r["codes"]]
    r["inputs_wrong"] = ("inputs-wrong" in codes) or ("absurd" in text and "inputs" in text and j is None)
    r["effect_missing"] = "effect-missing" in codes
    # export
    mf = os.path.join(d, "machine.json")
    rc, out, err, dt = run([hs, "export-controller", model, data, "--validation", val, "--out", mf,
                            "--json", os.path.join(d, "export.json")], env, os.path.join(d, "export.log"))
    r["export_rc"], r["export_s"] = rc, round(dt, 1)
    r["export_message"] = [ln for ln in err.strip().splitlines() if ln.strip()][-1:] if rc not in (0, "timeout") else []
    r["written"] = rc == 0 and os.path.exists(mf)
    if r["written"]:
        r["file"] = evaluate_file(mf, truth, data, hs, env, d, "written", id_params)
    elif rc != "timeout":
        ff = os.path.join(d, "machine_forced.json")
        rc2, _, _, dt2 = run([hs, "export-controller", model, data, "--validation", val, "--out", ff,
                              "--force", "--json", os.path.join(d, "export_forced.json")], env,
                             os.path.join(d, "export_forced.log"))
        r["forced_rc"], r["forced_s"] = rc2, round(dt2, 1)
        if rc2 == 0 and os.path.exists(ff):
            r["forced_file"] = evaluate_file(ff, truth, data, hs, env, d, "forced", id_params)
        else:
            r["forced_message"] = [ln for ln in _read_err(os.path.join(d, "export_forced.log"))][-1:]
    judge(r)
    with open(os.path.join(d, "result.json"), "w") as f:
        json.dump(r, f, indent=1, default=str)
    return r


def judge(r):
    n3s = math.sqrt(3) * r["noise_stated_mm"]
    n3u = math.sqrt(3) * r["noise_used_mm"]
    r["N3_stated"], r["N3_used"] = n3s, n3u
    v = {}
    v["no_answer"] = (not r["identify_answered"]) or r["export_rc"] == "timeout" or \
        r["export_rc"] not in (0, 1, 2)
    if r["sound"]:
        v["false_alarm"] = bool(r["inputs_wrong"])
        v["spurious_effect_missing"] = bool(r["effect_missing"])
    else:
        v["understated_flagged"] = bool(r["inputs_wrong"] or r["effect_missing"])
    f = r.get("file")
    if r["written"] and f is not None:
        E = f.get("E_judge", float("inf"))
        Vf = f.get("V_file")
        unjudged = (not f.get("reader_ok")) and f.get("check_controller_rc") == 0 and \
            not f.get("not_assembled_val")
        v["unjudged_reader"] = bool(unjudged)
        wrong = (E > CW_NOISE * n3s and (Vf is None or E > CW_RECORD * Vf)) or \
            bool(f.get("not_assembled_val")) or f.get("check_controller_rc") not in (0,)
        v["confident_wrong"] = bool(wrong and not unjudged)
        Vi = r.get("V_identify")
        if Vi and f.get("V_ours") is not None and not unjudged:
            v["heldout_optimistic"] = bool(f["V_ours"] > OPTIMISTIC * Vi)
    ff = r.get("forced_file")
    if not r["written"] and ff is not None:
        E = ff.get("E_judge", float("inf"))
        accurate = E <= ACCURATE * n3u and not ff.get("not_assembled_val")
        if r["sound"]:
            v["needless_refusal"] = bool(accurate)
        v["refusal_of_inaccurate"] = not accurate
        Vi = r.get("V_identify")
        if Vi and ff.get("V_ours") is not None and ff.get("reader_ok"):
            v["heldout_optimistic"] = bool(ff["V_ours"] > OPTIMISTIC * Vi)
    if not r["written"] and ff is None and r["export_rc"] not in ("timeout",):
        v["forced_also_refused"] = True
    r["verdicts"] = v


def fmt(x, k=4):
    if x is None:
        return "-"
    if isinstance(x, float):
        if math.isinf(x):
            return "inf"
        return "%.*g" % (k, x)
    return str(x)


def write_rates(results, outdir, hs, head, shas, wall):
    lines = ["# Blind closure calibration set: rates", "",
             "Units: lengths mm, angles rad.  E = the file's prediction error RMS at the validation poses "
             "against the noise-free truth (judging frame: RULES.md); N3 = 3-D noise RMS = sqrt(3) sigma.", "",
             "* hyperstat: `%s`, checkout git HEAD `%s`" % (hs, head),
             "* SHA-256 of the directory's *.py files: `%s`" % shas[0]]
    lines += ["  * `%s`" % s for s in shas[1]]
    lines += ["* wall time: %.0f s" % wall, ""]

    def rate(key, pool):
        pool = [r for r in pool if key in r["verdicts"]]
        k = sum(bool(r["verdicts"][key]) for r in pool)
        return "%d / %d" % (k, len(pool)), [r["campaign"] for r in pool if r["verdicts"][key]]

    sound = [r for r in results if r["sound"]]
    uns = [r for r in results if not r["sound"]]
    lines += ["## Rates", "", "| rate | count | campaigns |", "|---|---|---|"]
    for key, pool, label in [
        ("confident_wrong", results, "confident wrong (written file, judged wrong)"),
        ("false_alarm", sound, "false alarm (sound campaign called inputs-wrong)"),
        ("spurious_effect_missing", sound, "spurious effect-missing on a sound campaign"),
        ("needless_refusal", sound, "needless refusal (sound, refused, forced file accurate)"),
        ("refusal_of_inaccurate", results, "refusal of an inaccurate file (forced file not accurate)"),
        ("forced_also_refused", results, "refused, and --force wrote no file either (not judged)"),
        ("understated_flagged", uns, "understated noise flagged"),
        ("heldout_optimistic", results, "held-out statistic optimistic"),
        ("unjudged_reader", results, "unjudged: our reader disagrees with a file check-controller accepts"),
        ("no_answer", results, "no answer (timeout / crash)"),
    ]:
        c, names = rate(key, pool)
        lines.append("| %s | %s | %s |" % (label, c, ", ".join(names)))
    lines += ["", "## Per campaign", "",
              "| campaign | mech | OC | sound | noise used/stated (mm) | poses | identify rc | findings | "
              "sigma | V identify (mm) | export rc | file | E judge (mm) | E/N3 used | E reg (mm) | "
              "E base (mm) | V file (mm) | V ours (mm) | branch dq (rad) | reader | check rc | verdicts |",
              "|" + "---|" * 22]
    for r in results:
        f = r.get("file") or r.get("forced_file") or {}
        which = "written" if r.get("file") else ("forced" if r.get("forced_file") else "none")
        E = f.get("E_judge")
        codes = ",".join(sorted({c for c, _ in r.get("codes", []) if c}))
        verd = ",".join(k for k, x in r["verdicts"].items() if x)
        lines.append("| %s | %s | %s | %s | %s/%s | %d+%d | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            r["campaign"], r["mechanism"], "y" if r["overconstrained"] else "n", "y" if r["sound"] else "n",
            r["noise_used_mm"], r["noise_stated_mm"], r["n_id"], r["n_val"], r["identify_rc"], codes or "-",
            fmt(r.get("sigma")), fmt(r.get("V_identify")), r["export_rc"], which, fmt(E),
            fmt(E / r["N3_used"]) if isinstance(E, float) else "-", fmt(f.get("E_reg")), fmt(f.get("E_base")),
            fmt(f.get("V_file")), fmt(f.get("V_ours")), fmt(f.get("max_passive_vs_truth_rad")),
            ("ok" if f.get("reader_ok") else "MISMATCH %s" % fmt(f.get("reader_max_dev_mm"))) if f else "-",
            f.get("check_controller_rc", "-"), verd or "-"))
    lines += ["", "Refusal messages (last stderr line of a refused export):", ""]
    for r in results:
        if r.get("export_message"):
            lines.append("* %s: %s" % (r["campaign"], r["export_message"][0][:400]))
        if r.get("forced_message"):
            lines.append("* %s (--force): %s" % (r["campaign"], r["forced_message"][0][:400]))
    with open(os.path.join(outdir, "rates.md"), "w") as f:
        f.write("\n".join(lines) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description="score the blind closure calibration set")
    ap.add_argument("--hyperstat", default="/work/main/.venv/bin/hyperstat")
    ap.add_argument("--out", default="out/blind_closure")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--only", nargs="*")
    a = ap.parse_args(argv)
    t0 = time.time()
    hs = os.path.abspath(a.hyperstat)
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    checkout = os.path.dirname(os.path.dirname(os.path.dirname(hs)))
    try:
        head = subprocess.run(["git", "-C", checkout, "rev-parse", "HEAD"], capture_output=True,
                              text=True).stdout.strip() or "unknown"
    except Exception:
        head = "unknown"
    gendir = os.path.join(out, "campaigns")
    G.main(["--out", gendir] + (["--only"] + a.only if a.only else []))
    names = [c[0] for c in G.CAMPAIGNS if not a.only or c[0] in a.only]
    cache = tempfile.mkdtemp(prefix="hyperstat_cache_")
    results = []
    with cf.ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
        futs = {ex.submit(score_campaign, n, gendir, hs, out, cache): n for n in names}
        for fu in cf.as_completed(futs):
            r = fu.result()
            results.append(r)
            print("%-15s identify rc %s export rc %s %s" % (r["campaign"], r["identify_rc"], r["export_rc"],
                                                             {k: x for k, x in r["verdicts"].items() if x}))
            sys.stdout.flush()
    order = {n: i for i, n in enumerate(names)}
    results.sort(key=lambda r: order[r["campaign"]])
    with open(os.path.join(out, "results.json"), "w") as f:
        json.dump(results, f, indent=1, default=str)
    write_rates(results, out, hs, head, py_sha256(), time.time() - t0)
    print("wrote", os.path.join(out, "rates.md"))


if __name__ == "__main__":
    main()
