"""A controller file consistent with itself: what ``check-controller`` verifies without ``--source``.

Units: lengths in mm, angles in rad.

A SHA-256 anyone can recompute proves nothing about the content, and a trusted model
(``--source``) is not always at hand.  What the file says must then at least agree with
itself (issue 37); :func:`check_consistency` refuses, in one sentence naming the field:

* a ``mechanism`` name other than the embedded model's (the LinuxCNC component takes its name);
* an ``identified`` estimate that differs from the value the file applies: a geometry
  parameter from its ``defects`` entry, a target offset from ``target`` / ``targets``, an effect
  parameter from ``effects`` (to 1e-12, relative); an identified name the file does not hold;
* implausible statistics: an RMS, mean or maximum below 0 or out of order (``mean <= rms <=
  max`` holds for any set of norms), a count below 1, a noise RMS that is not positive, a rank
  above the number of unknowns or below the number of identified parameters, a condition
  number that is not finite or below 1;
* a ``calibration`` record that contradicts its numbers: per-target counts that do not add up
  to the statistics', a fit quality other than the one its residual and noise RMS give
  (:func:`~hyperstat.solver.calibration.fit_checks.fit_quality`), too few equations per
  parameter, a condition number above the limit, repeated poses or any refusing finding in a
  file not marked as written with ``--force`` (with its reasons), a covered region outside the
  joint ranges or of other joints.

The test vectors' number and spread and the joint map against them are checked with the
vectors (:func:`hyperstat.solver.export.controller.check_admissible`).
"""

from __future__ import annotations

import math

import numpy as np

from hyperstat.solver.calibration.fit_checks import (MAX_CONDITION, MIN_EQUATIONS_PER_PARAMETER, POSE_EQUATIONS,
                                                     fit_quality)
from hyperstat.solver.errors import DataError

__all__ = ["check_consistency", "target_offsets_of"]

_REL = 1e-12


def _same(a: float, b: float) -> bool:
    return abs(float(a) - float(b)) <= _REL * max(1.0, abs(float(a)), abs(float(b)))


def target_offsets_of(doc: dict) -> dict:
    """The target offsets a file applies: name -> offset (mm); ``"target"`` for a single one."""
    if doc.get("targets"):
        return {k: list(v) for k, v in doc["targets"].items()}
    return {"target": list(doc["target"])}


def check_consistency(doc: dict, mechanism, length_scale: float, source: str) -> None:
    """Refuse a controller file whose fields contradict one another (see the module docstring).

    Raises
    ------
    DataError
        One sentence naming ``source`` and the field.
    """
    if doc["mechanism"] != mechanism.name:
        raise DataError(f"{source}: field 'mechanism' is {doc['mechanism']!r}, but the embedded model is "
                        f"'{mechanism.name}': a controller would load this model under another machine's name.")
    _identified(doc, source)
    _statistics(doc, source)
    _record(doc, mechanism, length_scale, source)


def _identified(doc: dict, source: str) -> None:
    offsets = target_offsets_of(doc)
    single = not doc.get("targets")
    effects = {e["effect"]: e for e in doc["effects"]}
    violated = {n for e in doc["effects"] if e["effect"] == "violated-constraint" for n in e["options"].get("only", [])}
    seen = set()
    for k, p in enumerate(doc["identified"]):
        where = f"{source}: field 'identified[{k}]' ({p['name']})"
        if p["name"] in seen:
            raise DataError(f"{where}: the parameter is listed twice.")
        seen.add(p["name"])
        if not math.isfinite(p["estimate"]) or (p["std"] is not None and not (p["std"] >= 0 and math.isfinite(p["std"]))):
            raise DataError(f"{where}: an estimate is finite and a standard deviation finite and >= 0.")
        kind, name = p["kind"], p["name"]
        if kind == "geometry":
            if name not in doc["defects"]:
                raise DataError(f"{where}: '{name}' is not a defect of the file's 'defects'.")
            if name not in violated and not _same(doc["defects"][name], p["estimate"]):
                raise DataError(f"{where}: the estimate {p['estimate']:.12g} {p['unit']} differs from "
                                f"'defects.{name}' = {doc['defects'][name]:.12g} {p['unit']}, the value the file "
                                f"applies: the file contradicts itself.")
        elif kind == "target":
            parts = name.split("_")
            label = "target" if single else "_".join(parts[1:-1])
            axis = "xyz".index(parts[-1]) if parts[-1] in ("x", "y", "z") else None
            if label not in offsets or axis is None:
                raise DataError(f"{where}: the file has no target offset of that name.")
            if not _same(offsets[label][axis], p["estimate"]):
                field = "target" if single else f"targets.{label}"
                raise DataError(f"{where}: the estimate {p['estimate']:.12g} mm differs from '{field}[{axis}]' = "
                                f"{offsets[label][axis]:.12g} mm, the offset the file applies: the file contradicts "
                                f"itself.")
        elif kind.startswith("effect:"):
            eff = effects.get(kind.split(":", 1)[1])
            if eff is None or name not in eff["parameters"]:
                raise DataError(f"{where}: the file exports no effect parameter of that name.")
            if not _same(eff["parameters"][name], p["estimate"]):
                raise DataError(f"{where}: the estimate {p['estimate']:.12g} differs from the effect's parameter "
                                f"{eff['parameters'][name]:.12g}: the file contradicts itself.")
        elif kind not in ("tracker", "target_rotation"):
            raise DataError(f"{where}: kind '{kind}' is not a kind of identified parameter (geometry, tracker, target, "
                            f"target_rotation, effect:NAME).")


def _stats(s: dict | None, field: str, source: str) -> None:
    """``mean, max, rms`` (mm) of norms are >= 0 and in order (mean <= rms <= max), ``n`` >= 1."""
    if s is None:
        return
    mean, rms, mx = s["mean"], s["rms"], s["max"]
    for key in ("mean", "rms", "max"):
        if not (math.isfinite(s[key]) and s[key] >= 0.0):
            raise DataError(f"{source}: field '{field}.{key}' is {s[key]:g} mm: a statistic of residual norms is "
                            f"finite and at least 0.")
    slack = 1e-9 * max(mx, 1e-12)
    if not (mean <= rms + slack and rms <= mx + slack):
        raise DataError(f"{source}: field '{field}' has mean {mean:g}, RMS {rms:g} and max {mx:g} mm; of any set of "
                        f"norms mean <= RMS <= max.")
    if s["n"] < 1:
        raise DataError(f"{source}: field '{field}.n' is {s['n']}: a statistic is over at least one point.")


def _statistics(doc: dict, source: str) -> None:
    st = doc["statistics"]
    _stats(st["identification"], "statistics.identification", source)
    _stats(st["validation"], "statistics.validation", source)
    if st["noise_rms"] is not None and not (math.isfinite(st["noise_rms"]) and st["noise_rms"] > 0):
        raise DataError(f"{source}: field 'statistics.noise_rms' is {st['noise_rms']:g} mm: a noise RMS is positive.")
    n_id = len(doc["identified"])
    bound = (len(doc["defects"]) + 6 + 6 * max(len(target_offsets_of(doc)), 1)
             + sum(len(e["parameters"]) for e in doc["effects"]))
    if not st["unknowns"] <= bound:
        raise DataError(f"{source}: field 'statistics.unknowns' is {st['unknowns']}, more than the {bound} the file's "
                        f"defects, tracker frame, targets and effects can hold.")
    if not n_id <= st["rank"] <= st["unknowns"]:
        raise DataError(f"{source}: field 'statistics.rank' is {st['rank']} for {st['unknowns']} unknowns and "
                        f"{n_id} identified parameters: a rank lies between the number identified and the number of "
                        f"unknowns.")
    c = st["condition_number"]
    if c is not None and not (math.isfinite(c) and c >= 1.0):
        raise DataError(f"{source}: field 'statistics.condition_number' is {c!r}: a condition number is finite and "
                        f"at least 1.")


def _record(doc: dict, mechanism, length_scale: float, source: str) -> None:
    rec = doc["calibration"]
    st = doc["statistics"]
    where = f"{source}: field 'calibration"
    labels = set(target_offsets_of(doc))
    if set(rec["targets"]) != labels:
        raise DataError(f"{where}.targets' names {sorted(rec['targets'])}, the file's targets are {sorted(labels)}.")
    stated = rec["reference"] == "stated noise"
    if stated == (rec["reference_rms"] is not None) or (not stated and not rec["reference_rms"] > 0):
        raise DataError(f"{where}.reference_rms' must be null with a stated noise and a positive RMS (mm) without one.")
    if stated != (st["noise_rms"] is not None):
        raise DataError(f"{where}.reference' is {rec['reference']!r} but 'statistics.noise_rms' is "
                        f"{st['noise_rms']!r}.")
    ratios = []
    for name, t in rec["targets"].items():
        for part in ("identification", "validation"):
            s = t[part]
            if s is None:
                if part == "identification":
                    raise DataError(f"{where}.targets.{name}.identification' is missing.")
                continue
            _stats(s, f"calibration.targets.{name}.{part}", source)
            noise = s["noise_rms"]
            if stated and not (noise is not None and math.isfinite(noise) and noise > 0):
                raise DataError(f"{where}.targets.{name}.{part}.noise_rms' must be a positive RMS (mm) with a stated "
                                f"noise.")
            if part == "validation" or stated:
                ratios.append(s["rms"] / (noise if stated else rec["reference_rms"]))
    for part in ("identification", "validation"):
        if st[part] is None:
            if any(t[part] is not None for t in rec["targets"].values()):
                raise DataError(f"{where}.targets' hold {part} statistics, 'statistics.{part}' is null.")
            continue
        total = sum(t[part]["n"] for t in rec["targets"].values() if t[part] is not None)
        if total != st[part]["n"]:
            raise DataError(f"{where}.targets' count {total} {part} points, 'statistics.{part}.n' {st[part]['n']}.")
    judged = fit_quality(rec["sigma"], st["identification"]["rms"], length_scale, stated, ratios,
                         None if st["validation"] is None else st["validation"]["rms"])
    if judged != rec["fit_quality"]:
        raise DataError(f"{where}.fit_quality' is {rec['fit_quality']!r}, but its residual and noise RMS make it "
                        f"{judged!r}.")
    eq = rec["equations"]
    n_id = len(doc["identified"])
    n_machine = sum(1 for p in doc["identified"] if p["kind"] not in ("target", "target_rotation"))
    if eq["parameters"] != n_id or eq["machine_parameters"] != n_machine:
        raise DataError(f"{where}.equations' counts {eq['parameters']} parameters ({eq['machine_parameters']} of the "
                        f"machine); the file identifies {n_id} ({n_machine}).")
    if not (1 <= eq["poses"] and eq["machine_equations"] <= min(eq["equations"], POSE_EQUATIONS * eq["poses"])):
        raise DataError(f"{where}.equations' are not counts of poses and equations ({POSE_EQUATIONS} a pose at most "
                        f"for the machine).")
    region = rec["region"]
    act = [mechanism.joints[i] for i in mechanism.actuated]
    if region["joints"] != [j.name for j in act] or region["units"] != ["rad" if j.type == "R" else "mm" for j in act]:
        raise DataError(f"{where}.region' names joints {region['joints']}, the model's actuated joints are "
                        f"{[j.name for j in act]}.")
    lo, hi = mechanism.ranges[mechanism.actuated].T
    low, high = np.asarray(region["low"], float), np.asarray(region["high"], float)
    if low.shape != lo.shape or high.shape != hi.shape or not np.all(low <= high):
        raise DataError(f"{where}.region' is not a region (one low <= high per actuated joint).")
    out = np.flatnonzero((low < lo - 1e-9) | (high > hi + 1e-9))
    if len(out):
        k = int(out[0])
        raise DataError(f"{where}.region': the poses covered [{low[k]:g}, {high[k]:g}] {region['units'][k]} of joint "
                        f"'{region['joints'][k]}', outside its range [{lo[k]:g}, {hi[k]:g}] (were the joint ranges "
                        f"changed after export?).")
    must = []
    if judged != "ok":
        must.append(f"its fit quality is {judged!r}")
    ratio = min(eq["equations"] / max(n_id, 1), eq["machine_equations"] / max(n_machine, 1) if n_machine else math.inf)
    if ratio < MIN_EQUATIONS_PER_PARAMETER:
        must.append(f"it has {ratio:.2g} equations per parameter")
    if st["condition_number"] is not None and st["condition_number"] > MAX_CONDITION:
        must.append(f"its condition number is {st['condition_number']:.3g}")
    if rec["repeated_poses"]:
        must.append("poses repeat within the noise")
    refusing = [f for f in rec["findings"] if f["refuses"]]
    if refusing:
        must.append(f"identify made {len(refusing)} finding(s) that stop an export")
    if rec["forced"] != bool(rec["reasons"]) or len(rec["reasons"]) != len(refusing):
        raise DataError(f"{where}.forced' and '.reasons' must come together, one reason per refusing finding.")
    if must and not rec["forced"]:
        raise DataError(f"{where}': {'; '.join(must)}, yet the file is not marked as written with --force: the "
                        f"export gate would have refused it.")
