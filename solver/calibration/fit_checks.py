"""Whether a fit can be trusted: residuals against the stated noise per target, equations per parameter,
conditioning, targets that coincide, and the joint-space region the poses cover.

Units: lengths in mm, angles in rad.

These are the tests behind :func:`~hyperstat.solver.calibration.identify.identify`'s findings,
which the export gate (:mod:`hyperstat.solver.export.calibration_gate`) reads and a controller
file records:

* **noise ratio per target** (:func:`target_stats`, :func:`noise_ratios`): the RMS of a target's
  3-D residuals over the RMS of the 3-D noise its rows state (``sqrt(mean |r|^2) /
  sqrt(mean 3 sigma^2)``), on the identification poses and on the held-out ones.  A calibrated
  model that describes the machine predicts held-out poses at about ``sqrt(1 + p/m)`` times the
  noise (p parameters, m equations: 1.0-1.3 in sound campaigns); above :data:`SIGMA_WARN` the
  model is not what the data say the machine is.  Without a stated noise the reference is the
  fit's own residual scale (the identification ratios are then 1 by construction, the held-out
  ones still tell).
* **equations per parameter** (:func:`equation_count`): at least :data:`MIN_EQUATIONS_PER_PARAMETER`
  equations per identified parameter, counting each distinct pose once and, for the machine's
  parameters (everything but the target offsets), at most :data:`POSE_EQUATIONS` equations per pose
  (a pose fixes at most the output frame's six coordinates, whatever the number of targets on
  it; more targets add equations for their own offsets only).  At two equations per parameter
  the residual variance has as many degrees of freedom as there are parameters, and the
  calibrated model's own error at its poses averages ``sigma sqrt(p/m) = 0.71 sigma``; below,
  the fit's noise dominates what it claims to know (the diagnosis calls it over-fitting at the
  same count, :data:`hyperstat.solver.diagnosis.gap.FEW_EQUATIONS`).
* **conditioning**: the condition number of the identification Jacobian with columns scaled to
  unit norm (angles first times the length scale) at most :data:`MAX_CONDITION`.  Sound campaigns of
  the templates reach 1.2e1 (SCARA) to 4e4 (Tripteor X7, 107 random poses; hexapod 1.6e4-1.8e4 with
  40-107 poses); the rank cut is at 1e-8 of the largest singular value.  Above 1e6 the weakest
  identified combination is determined a million times worse than the best: its estimate follows
  the noise, and the rank decision is near its cut.
* **coinciding targets** (:func:`coinciding_targets`): two reflectors cannot share a point; offsets
  closer than three standard deviations of their difference, or than :data:`TARGET_SEPARATION_MM`,
  mean one target's columns are a copy of another's (or two were stacked).
* **region** (:func:`joint_region`): per actuated joint, the range its identification poses cover;
  a controller that moves beyond it runs an extrapolated model.

Examples
--------
>>> fit_quality(1.02, 0.03, 1500.0, True, ratios=[1.1, 6.0])
'model misses an effect'
>>> fit_quality(0.97, 0.05, 1500.0, True, ratios=[1.0, 1.1, 2400.0])
'inputs wrong'
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["SIGMA_WARN", "SIGMA_INPUTS", "SIZE_INPUTS", "FIT_QUALITY", "MIN_EQUATIONS_PER_PARAMETER",
           "POSE_EQUATIONS", "MAX_CONDITION", "TARGET_SEPARATION_MM", "fit_quality", "target_stats", "noise_ratios",
           "equation_count", "coinciding_targets", "joint_region", "target_label"]

SIGMA_WARN = 3.0  #: residuals (or held-out residuals) above this many times the noise: the model misses something
SIGMA_INPUTS = 100.0  #: sigma from which the inputs (joint map, units, targets), not the model, are at fault
SIZE_INPUTS = 0.01  #: residual RMS above this share of the machine's length scale: the inputs are at fault
FIT_QUALITY = ("ok", "model misses an effect", "inputs wrong")
MIN_EQUATIONS_PER_PARAMETER = 2.0  #: equations per identified parameter below which a fit is refused for export
POSE_EQUATIONS = 6  #: equations a pose gives at most about the machine (the output frame's six coordinates)
MAX_CONDITION = 1e6  #: condition number (unit-norm scaled columns) above which a fit is poorly conditioned
TARGET_SEPARATION_MM = 1.0  #: two targets closer than this (mm) coincide, whatever their standard deviations


def fit_quality(sigma: float, rms: float, length_scale: float, noise_stated: bool, ratios=(),
                held_out_rms: float | None = None) -> str:
    """Severity of a fit, one of :data:`FIT_QUALITY`.

    ``"inputs wrong"`` when the residual RMS (mm), on the identification or the held-out poses,
    exceeds :data:`SIZE_INPUTS` of the machine's length scale (a wrong joint sign, offset or
    coupling, a unit error, targets stacked in one column or copied move the point by a fraction of
    a link), or when sigma (stated noise) or any noise ratio of ``ratios`` (per target, on the
    identification or the held-out poses, :func:`noise_ratios`) reaches :data:`SIGMA_INPUTS`;
    ``"model misses an effect"`` when sigma (stated noise) or a ratio exceeds :data:`SIGMA_WARN`
    (compliance, gear errors, temperature, too few poses for the parameters, or noise understated:
    a few times the noise, well below a link's size); ``"ok"`` else.

    >>> fit_quality(6.6, 0.57, 1500.0, True), fit_quality(1840.0, 40.0, 1500.0, True), fit_quality(1.02, 0.03, 1500.0, True)
    ('model misses an effect', 'inputs wrong', 'ok')
    """
    worst = max((float(r) for r in ratios if r is not None and math.isfinite(r)), default=0.0)
    if any(r is not None and not math.isfinite(r) for r in ratios):
        worst = math.inf
    big = rms > SIZE_INPUTS * length_scale or (held_out_rms is not None and held_out_rms > SIZE_INPUTS * length_scale)
    if big or (noise_stated and sigma >= SIGMA_INPUTS) or worst >= SIGMA_INPUTS:
        return "inputs wrong"
    if (noise_stated and sigma > SIGMA_WARN) or worst > SIGMA_WARN:
        return "model misses an effect"
    return "ok"


def target_label(name: str) -> str:
    """A target's name in words and files: ``"target"`` for the single unnamed one."""
    return name or "target"


def target_stats(data, resid: np.ndarray, sigma_rows: np.ndarray | None) -> dict:
    """Per target: ``mean, max, rms, n`` of its 3-D residual norms and the ``noise_rms`` its rows state (mm).

    ``noise_rms`` is ``sqrt(mean 3 sigma^2)`` over the target's rows (None without a stated noise).
    """
    e = np.linalg.norm(np.atleast_2d(resid), axis=1)
    out = {}
    idx = np.asarray(data.target_index, dtype=int)
    for t, name in enumerate(data.target_names):
        rows = idx == t
        if not rows.any():
            continue
        et = e[rows]
        out[target_label(name)] = {
            "mean": float(np.mean(et)), "max": float(np.max(et)), "rms": float(np.sqrt(np.mean(et**2))),
            "n": int(rows.sum()),
            "noise_rms": None if sigma_rows is None else float(np.sqrt(np.mean(3.0 * sigma_rows[rows] ** 2)))}
    return out


def noise_ratios(stats: dict, reference: float | None = None) -> dict:
    """Per target: residual RMS over the noise RMS its rows state (or over ``reference``, mm, without one)."""
    out = {}
    for name, s in stats.items():
        ref = s.get("noise_rms") if s.get("noise_rms") is not None else reference
        out[name] = None if not ref else float(s["rms"] / ref)
    return out


def equation_count(rows_per_pose: list, kinds: list) -> dict:
    """Equations against identified parameters (:data:`MIN_EQUATIONS_PER_PARAMETER`, :data:`POSE_EQUATIONS`).

    Parameters
    ----------
    rows_per_pose : list of int
        Equation rows of each distinct pose (repeated poses counted once).
    kinds : list of str
        Kind of each identified parameter (``geometry``, ``tracker``, ``target``, ``target_rotation``,
        ``effect:NAME``).

    Returns
    -------
    dict
        ``poses, equations, machine_equations, parameters, machine_parameters, per_parameter`` (the
        smaller of the two ratios), ``enough`` (bool) and ``min_poses`` (the fewest poses like these
        that would be enough).

    >>> r = equation_count([9] * 7, ["geometry"] * 18 + ["tracker"] * 6 + ["target"] * 9)
    >>> r["equations"], r["machine_equations"], r["enough"], r["min_poses"]
    (63, 42, False, 8)
    """
    rows = [int(r) for r in rows_per_pose]
    p = len(kinds)
    p_m = sum(1 for k in kinds if k not in ("target", "target_rotation"))
    eq = int(sum(rows))
    eq_m = int(sum(min(r, POSE_EQUATIONS) for r in rows))
    ratio = min(eq / p if p else math.inf, eq_m / p_m if p_m else math.inf)
    typical = float(np.median(rows)) if rows else 3.0
    need = max(math.ceil(MIN_EQUATIONS_PER_PARAMETER * p / max(typical, 1.0)),
               math.ceil(MIN_EQUATIONS_PER_PARAMETER * p_m / max(min(typical, POSE_EQUATIONS), 1.0)))
    return {"poses": len(rows), "equations": eq, "machine_equations": eq_m, "parameters": p,
            "machine_parameters": p_m, "per_parameter": float(ratio),
            "enough": bool(ratio >= MIN_EQUATIONS_PER_PARAMETER), "min_poses": int(need)}


def coinciding_targets(offsets: dict, covariance: dict) -> list[dict]:
    """Pairs of targets whose identified offsets coincide: closer than three standard deviations of their
    difference or than :data:`TARGET_SEPARATION_MM`.

    Parameters
    ----------
    offsets : dict
        Target name -> offset in the output frame (mm).
    covariance : dict
        ``(a, b)`` -> 3 x 3 covariance block of the offsets of targets ``a`` and ``b`` (``(a, a)`` included;
        a missing block is zero).

    >>> coinciding_targets({"A": [10.0, 0, 0], "B": [10.0, 0, 0.2], "C": [-80.0, 5, 0]}, {})
    [{'targets': ['A', 'B'], 'distance_mm': 0.2, 'limit_mm': 1.0}]
    """
    names = list(offsets)
    out = []
    zero = np.zeros((3, 3))
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            d = np.asarray(offsets[a], float) - np.asarray(offsets[b], float)
            c = (covariance.get((a, a), zero) + covariance.get((b, b), zero) - covariance.get((a, b), zero)
                 - covariance.get((a, b), zero).T)
            limit = max(3.0 * math.sqrt(max(float(np.trace(c)), 0.0)), TARGET_SEPARATION_MM)
            dist = float(np.linalg.norm(d))
            if dist < limit:
                out.append({"targets": [a, b], "distance_mm": round(dist, 12), "limit_mm": limit})
    return out


def joint_region(mechanism, data) -> dict:
    """The actuated values the poses cover: per actuated joint (model order), the lowest and highest (rad / mm)."""
    q = np.asarray(data.q, dtype=float)
    joints = [mechanism.joints[i] for i in mechanism.actuated]
    return {"joints": [j.name for j in joints], "units": ["rad" if j.type == "R" else "mm" for j in joints],
            "low": [float(v) for v in q.min(axis=0)], "high": [float(v) for v in q.max(axis=0)]}
