"""Step 1 of the diagnosis: is there a gap, and is it one a missing effect can explain?

Units: lengths in mm; noise factors are dimensionless (``sqrt(chi2 / dof)``).

* The gap test (:func:`gap_test`): the weighted residuals of a fit (position rows, and
  orientation rows for 6-D data: :mod:`.observations`) follow a chi-square law with
  ``3 rows - rank`` degrees of freedom when the file's noise model is right and
  nothing is missing; the validation points give a second, independent test, against the
  exact covariance of a held-out prediction error, ``I + J_v (J^T J)^+ J_v^T`` in weighted
  units (:func:`prediction_covariance`): the fitted model's own uncertainty at each held-out
  pose, larger where the poses extrapolate (the workspace's edge) than its average
  ``rank / 3K`` over the identification poses.
* Inputs wrong (:func:`inputs_wrong`): sigma in the hundreds, or residuals of a
  fraction of a link, come from the joint map, the units or the targets, not from a
  missing effect (:func:`~hyperstat.solver.calibration.identify.fit_quality`).
* Over-fitting (:func:`overfitting`): the rigid fit predicts held-out poses far worse
  than the poses it was fitted to (an F-test of the two noise factors), or worse than
  the nominal model: too many parameters for the poses, not a missing effect and not
  noise.
"""

from __future__ import annotations

import numpy as np
from scipy.special import chdtrc, fdtrc

from hyperstat.solver.calibration.identify import IdentificationResult, _weights
from hyperstat.solver.calibration.measurements import MeasurementSet
from hyperstat.solver.diagnosis.observations import oriented, residual_rows
from hyperstat.solver.diagnosis.where import P_THRESHOLD

__all__ = ["gap_test", "prediction_covariance", "noise_statement", "overfitting", "inputs_wrong", "weighted_validation", "OVERFIT_RATIO"]

OVERFIT_RATIO = 1.3  #: validation noise factor this many times the identification's (and significant): over-fitting
FEW_EQUATIONS = 2.0  #: fewer equations per identified parameter than this: over-fitting whatever the factors
NOMINAL_MARGIN = 1.1  #: the calibrated model predicts held-out poses this much worse than the nominal one: over-fitting


def gap_test(result: IdentificationResult, data: MeasurementSet, validation: MeasurementSet | None) -> dict:
    """The chi-square gap test on a fit's identification residuals and, if given, its validation residuals.

    Returns ``identification`` and ``validation`` (chi2, dof, p_value, noise_factor),
    ``threshold`` (1e-3 over the number of tests) and ``significant``.
    """
    resid, w = _rows(result, data, result.residuals)
    chi_id = float(np.sum((resid * w[:, None]) ** 2))
    dof = max(3 * len(w) - result.rank, 1)
    test = {"identification": {"chi2": chi_id, "dof": dof, "p_value": float(chdtrc(dof, chi_id)),
                               "noise_factor": float(np.sqrt(chi_id / dof))}}
    held = None
    if validation is not None and len(validation) and result.validation_residuals is not None:
        rv, wv = _rows(result, validation, result.validation_residuals)
        held = prediction_covariance(result, data, validation)
        if held["residuals"].shape != rv.shape or not np.allclose(held["residuals"], rv, rtol=0.0,
                                                                  atol=1e-3 / max(float(wv.max()), 1e-300)):
            # the Jacobian was taken at other closures than the fit's held-out predictions (another assembly mode):
            # the average inflation of the identification poses instead
            k = len(wv)
            held = {"covariance": np.eye(3 * k) * (1.0 + result.rank / (3.0 * len(w))), "max_pose_inflation": None}
        z = (rv * wv[:, None]).reshape(-1)
        chi_raw = float(z @ z)
        chi_v = float(z @ _solve_spd(held["covariance"], z))  # whitened by the exact prediction covariance
        dof_v = 3 * len(wv)
        scale = chi_raw / max(chi_v, 1e-300)  # the inflation these residuals met (reported; the test is chi_v)
        test["validation"] = {"chi2": chi_raw, "chi2_whitened": chi_v, "dof": dof_v,
                              "p_value": float(chdtrc(dof_v, chi_v)),
                              "variance_inflation": float(np.trace(held["covariance"]) / dof_v),
                              "variance_inflation_met": float(scale),
                              "variance_inflation_max_pose": held["max_pose_inflation"],
                              "noise_factor": float(np.sqrt(chi_v / dof_v))}
    test["threshold"] = P_THRESHOLD / (len(test))
    test["significant"] = bool(min(v["p_value"] for k, v in test.items() if isinstance(v, dict)) < test["threshold"])
    kinds = row_type_tests(result, data, validation, held)
    if kinds is not None:  # 6-D: positions and orientations also tested apart (an effect may sit in one kind only)
        test["row_types"] = kinds
        if not test["significant"] and kinds["significant"]:
            test["significant"] = True
            test["significant_by"] = "row types"
    return test


def prediction_covariance(result: IdentificationResult, data: MeasurementSet,
                          validation: MeasurementSet) -> dict:
    """The covariance of a fit's weighted prediction errors at held-out poses, in units of the stated noise.

    A least-squares fit on the identification rows (weighted Jacobian ``J`` of the identified
    base parameters, :func:`~hyperstat.solver.calibration.identify.identify`) errs by
    ``-(J^T J)^+ J^T e``; a held-out row ``v`` (weighted Jacobian ``J_v``) then has the
    prediction error ``e_v + J_v (J^T J)^+ J^T e``, of covariance ``I + J_v (J^T J)^+ J_v^T``
    when the noise model is right and nothing is missing (linearised at the fit). Its
    diagonal blocks are ``1 + h_v`` per pose, ``h_v`` the pose's prediction leverage: its
    average over the identification poses is ``rank / 3K``, but held-out poses at the
    workspace's edge extrapolate and have more, and the off-diagonal blocks correlate the
    held-out poses through the shared parameter error.

    Returns
    -------
    dict
        ``covariance`` (3 Kv, 3 Kv), the rows of :func:`_rows` flattened (position rows, then
        orientation rows for 6-D data), ``max_pose_inflation`` (the largest ``1 + h_v``, the
        trace of a pose's block over 3) and ``residuals`` (the held-out residual rows where the
        Jacobian was taken: the caller checks they are the fit's own).

    Examples
    --------
    A straight line fitted to 4 points with unit noise: the prediction variance at ``x`` is
    ``1 + 1/4 + (x - mean)^2 / sum((x_i - mean)^2)`` (per component), larger outside the points:

    >>> import numpy as np
    >>> x = np.array([0.0, 1.0, 2.0, 3.0]); xv = np.array([1.5, 6.0])
    >>> J = np.column_stack([np.ones(4), x]); Jv = np.column_stack([np.ones(2), xv])
    >>> c = _covariance_from(J, Jv)
    >>> np.allclose(np.diag(c), 1 + 1 / 4 + (xv - 1.5) ** 2 / 5)
    True
    """
    _, w, jac, _ = residual_rows(result.model, result.theta, data, jacobian=True, q_start=result.configurations)
    resid_v, wv, jac_v, _ = residual_rows(result.model, result.theta, validation, jacobian=True)
    base = [result.model.names.index(b) for b in result.base]
    x = (jac[:, :, base] * w[:, None, None]).reshape(3 * len(w), -1)
    xv = (jac_v[:, :, base] * wv[:, None, None]).reshape(3 * len(wv), -1)
    cov = _covariance_from(x, xv, max(result.rank, 1))
    per_row = np.diag(cov).reshape(len(wv), 3).mean(axis=1)
    return {"covariance": cov, "max_pose_inflation": float(per_row.max()) if len(per_row) else 1.0,
            "residuals": resid_v}


def _covariance_from(x: np.ndarray, xv: np.ndarray, rank: int | None = None) -> np.ndarray:
    """``I + xv (x^T x)^+ xv^T`` with the columns scaled to unit norm and the pseudo-inverse cut at ``rank``."""
    norm = np.linalg.norm(x, axis=0).clip(min=1e-300)
    _, s, vt = np.linalg.svd(x / norm, full_matrices=False)
    keep = s > 1e-9 * max(float(s[0]), 1e-300) if len(s) else s > 0
    if rank is not None:
        keep[rank:] = False
    b = (xv / norm) @ (vt[keep].T / s[keep])
    return np.eye(len(xv)) + b @ b.T


def _solve_spd(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a^-1 b`` for a symmetric positive definite ``a`` (Cholesky)."""
    from scipy.linalg import cho_factor, cho_solve
    return cho_solve(cho_factor(a), b)


def row_type_tests(result: IdentificationResult, data: MeasurementSet,
                   validation: MeasurementSet | None, held: dict | None = None) -> dict | None:
    """For 6-D data, the gap test on the position rows and on the orientation rows apart (None otherwise).

    The pooled test of :func:`gap_test` adds the chi-squares of both kinds of rows: an effect that moves the
    measured point but not the measured orientation (a probe's stylus bending, a tool growing) shows in the
    position rows only, and the orientation rows, consistent with their noise, dilute it (a position factor of
    1.35 pooled with an orientation factor of 1.0 gives 1.19).  Each kind is tested against its own chi-square:
    on the identification rows with ``3 K - h`` degrees of freedom, ``h`` the sum of the kind's leverages (the
    diagonal of the hat matrix of the weighted base columns, which sums to the rank over both kinds); on the
    validation rows against the fitted model's own uncertainty at rows of
    that kind (the rows of that kind of :func:`prediction_covariance`, given as ``held``, else ``1 + h / 3K``).
    The four tests are judged at ``1e-3 / 4`` (Bonferroni), a family beside the pooled one.

    Returns
    -------
    dict or None
        ``positions`` and ``orientations``, each with ``identification`` and ``validation`` (chi2, dof, p_value,
        noise_factor, leverage), ``threshold`` and ``significant``.
    """
    if not oriented(result.model, data):
        return None
    resid, w, jac, _ = residual_rows(result.model, result.theta, data, jacobian=True, q_start=result.configurations)
    base = [result.model.names.index(b) for b in result.base]
    x = (jac[:, :, base] * w[:, None, None]).reshape(3 * len(w), -1)
    x = x / np.linalg.norm(x, axis=0).clip(min=1e-300)
    u, s, _ = np.linalg.svd(x, full_matrices=False)
    u = u[:, s > 1e-9 * max(float(s[0]), 1e-300)][:, : max(result.rank, 1)]
    lev = np.sum(u**2, axis=1).reshape(len(w), 3).sum(axis=1)
    k = len(data)
    z = np.sum((resid * w[:, None]) ** 2, axis=1)
    out = {}
    held_out = validation is not None and len(validation) > 0 and oriented(result.model, validation)
    if held_out:
        rv, wv, _, _ = residual_rows(result.model, result.theta, validation)
        zv = np.sum((rv * wv[:, None]) ** 2, axis=1)
    for kind, rows in (("positions", slice(0, k)), ("orientations", slice(k, 2 * k))):
        h = float(np.sum(lev[rows]))
        dof = max(3.0 * k - h, 1.0)
        chi = float(np.sum(z[rows]))
        entry = {"identification": {"chi2": chi, "dof": dof, "p_value": float(chdtrc(dof, chi)),
                                    "noise_factor": float(np.sqrt(chi / dof)), "leverage": h}}
        if held_out:
            kv = len(validation)
            part = slice(0, kv) if kind == "positions" else slice(kv, 2 * kv)
            chi_v = float(np.sum(zv[part]))
            if held is not None:  # the exact covariance of this kind's rows (a marginal of the whole)
                flat = slice(3 * part.start, 3 * part.stop)
                zk = (rv[part] * wv[part, None]).reshape(-1)
                cov = held["covariance"][flat, flat]
                chi_w = float(zk @ _solve_spd(cov, zk))
                scale = float(np.trace(cov) / (3 * kv))
            else:
                scale = 1.0 + h / (3.0 * k)
                chi_w = chi_v / scale
            entry["validation"] = {"chi2": chi_v, "dof": 3 * kv, "p_value": float(chdtrc(3 * kv, chi_w)),
                                   "variance_inflation": scale,
                                   "noise_factor": float(np.sqrt(chi_w / (3 * kv)))}
        out[kind] = entry
    ps = [t["p_value"] for kind in out.values() for t in kind.values()]
    out["threshold"] = P_THRESHOLD / len(ps)
    out["significant"] = bool(min(ps) < out["threshold"])
    return out


def _rows(result: IdentificationResult, data: MeasurementSet, positions: np.ndarray) -> tuple:
    """Residual rows and weights of a fit on ``data``: its position residuals, and orientation rows for 6-D data."""
    if oriented(result.model, data):
        resid, w, _, _ = residual_rows(result.model, result.theta, data)
        return resid, w
    return positions, _weights(data)


def weighted_validation(result: IdentificationResult, validation: MeasurementSet) -> np.ndarray:
    """A fit's validation residual rows (positions, and orientations for 6-D data) times their weights: noise of
    unit variance per row when the file's noise model is right and nothing is missing."""
    resid, w = _rows(result, validation, result.validation_residuals)
    return resid * w[:, None]


def noise_statement(data: MeasurementSet, factor: float) -> dict:
    """The noise model that would make the residuals consistent: the header's times ``factor``."""
    a, b = data.noise.a, data.noise.b
    return {"factor": factor, "a_mm": factor * a, "b_mm_per_m": factor * b,
            "text": f"{factor * a:.3g} mm + {factor * b:.3g} mm/m ({factor:.2f}x the header's {data.noise.text()})"}


def overfitting(test: dict, rigid: IdentificationResult, n_rows: int, structured: bool = False) -> dict | None:
    """Evidence of over-fitting of the rigid fit, or None.

    Over-fitting when

    * the fit has fewer than 2 equations per parameter (:data:`FEW_EQUATIONS`): no test can
      then tell a missing effect from the fit's own noise, unless the poses fitted already show
      the excess (their chi-square significant, and the held-out factor within
      :data:`OVERFIT_RATIO` of theirs: an understated noise shows on both);
    * the validation noise factor is at least :data:`OVERFIT_RATIO` times the
      identification's, and either the F-test of the two variances is below 1e-3 or the fit
      spends more than a quarter of its equations on parameters (where the linearised
      prediction covariance of the gap test may underrate what extrapolating costs), and
      the identification residual has no structure (``structured`` false: a structured
      residual is a missing effect seen in sample, whose extrapolation also degrades the
      held-out poses);
    * or the calibrated model predicts the held-out poses :data:`NOMINAL_MARGIN` times worse
      than the nominal one (only the tracker frame and targets fitted) beyond what estimating
      ``rank`` parameters adds by itself, and the residual has no structure. The estimate's
      error inflates the held-out poses' squared error by the average of the exact prediction
      covariance's diagonal (``variance_inflation`` of the gap test, :func:`prediction_covariance`;
      without it, ``f^2 rank / n_rows`` added to the squared factor, ``f^2 = f_id^2 / (1 - rank /
      n_rows)``); so a nominal model that is already right (a simulation without defects)
      predicts better than any calibration by that much, which is no over-fitting. A structured
      residual is a missing effect: the calibration absorbs part of it in sample and
      extrapolates it badly, so the held-out loss is that effect's, not the parameters'.

    Examples
    --------
    A fit that predicts held-out poses exactly as least squares expects (true noise factor 2,
    a quarter of the equations spent on parameters, the nominal model right) is no over-fitting,
    although the nominal model predicts 1.12 x better:

    >>> from types import SimpleNamespace
    >>> load, f = 0.25, 2.0
    >>> fi, fv = f * (1 - load) ** 0.5, (f**2 * (1 + load)) ** 0.5
    >>> test = {"identification": {"noise_factor": fi, "dof": 75}, "validation": {"noise_factor": fv, "dof": 60}}
    >>> rigid = SimpleNamespace(rank=25, nominal={"validation": {"rms": 0.02}},
    ...                         validation={"rms": 0.02 * fv / f})
    >>> overfitting(test, rigid, 100) is None
    True
    """
    if "validation" not in test:
        return None
    fi, fv = test["identification"]["noise_factor"], test["validation"]["noise_factor"]
    f = (fv / max(fi, 1e-300)) ** 2
    p = float(fdtrc(test["validation"]["dof"], test["identification"]["dof"], f))
    nominal = (rigid.nominal or {}).get("validation")
    load = rigid.rank / max(n_rows, 1)
    worse = False
    inflation = test["validation"].get("variance_inflation")
    if nominal is not None and rigid.validation is not None and not structured and "chi2_whitened" in test["validation"]:
        # the exact prediction covariance (:func:`prediction_covariance`): the calibrated model's squared held-out
        # error is the noise's times its average inflation, the nominal model's (only the tracker frame and the
        # targets fitted) the noise's alone, when the nominal model is right
        ratio = rigid.validation["rms"] / max(nominal["rms"], 1e-300)
        worse = ratio**2 > NOMINAL_MARGIN**2 * inflation
    elif nominal is not None and rigid.validation is not None and not structured:
        f_nominal = fv * nominal["rms"] / max(rigid.validation["rms"], 1e-300)  # the nominal model's held-out factor
        estimation = fi**2 * load / max(1.0 - load, 1e-3)  # what fitting rank parameters adds to the squared factor
        worse = fv**2 > NOMINAL_MARGIN**2 * (f_nominal**2 + estimation)
    # fewer than FEW_EQUATIONS per parameter: over-fitting, unless the poses fitted already show the excess the held-out
    # ones do (the in-sample chi-square significant and the held-out factor within OVERFIT_RATIO of it): a noise
    # understated by 2 x shows on both, and is no over-fitting (the later steps tell noise from a structured gap)
    seen_in_sample = test["identification"].get("p_value", 1.0) < test.get("threshold", P_THRESHOLD) \
        and fv < OVERFIT_RATIO * fi
    few = load > 1.0 / FEW_EQUATIONS and not seen_in_sample
    ratio = fv >= OVERFIT_RATIO * fi and (p < P_THRESHOLD or load > 0.25) and not structured
    if not (few or ratio or worse):
        return None
    words = (f"the rigid fit predicts held-out poses at {fv:.2f}x the stated noise against {fi:.2f}x on the poses it "
             f"was fitted to (F-test of the two p = {p:.2g}) with {rigid.rank} parameters for {n_rows} equations")
    if few:
        words += f" (fewer than {FEW_EQUATIONS:g} equations per parameter)"
    if worse:
        words += (f"; the nominal model predicted the held-out poses better ({nominal['rms']:.4g} mm against "
                  f"{rigid.validation['rms']:.4g} mm calibrated)")
    return {"identification_factor": fi, "validation_factor": fv, "p_value": p, "nominal_better": bool(worse),
            "parameters_per_equation": load,
            "evidence": words + ": too many parameters for these poses; identify fewer (identify --select-size cv) "
                                "or add poses spread over the workspace, then diagnose again"}


def inputs_wrong(rigid: IdentificationResult, length_scale: float) -> dict | None:
    """Evidence that the inputs, not a missing effect, make the gap (``fit_quality`` "inputs wrong"), or None."""
    if getattr(rigid, "fit_quality", "ok") != "inputs wrong":
        return None
    rms = rigid.identification["rms"]
    return {"sigma": rigid.sigma, "rms_mm": rms, "share_of_size": rms / length_scale,
            "evidence": (f"sigma = {rigid.sigma:.3g} and an identification RMS of {rms:.4g} mm "
                         f"({100 * rms / length_scale:.2g} % of the machine's size): no missing effect moves the point "
                         f"that much; check the joint map (signs, offsets, couplings such as q3 = J3 + J2), the units "
                         f"of the joint and position columns, the target columns (one group x_<target> per reflector) "
                         f"and that the tracker did not move")}
