"""Step 3 of the diagnosis: candidate effects, linearised at the rigid solution, scored and selected.

Units: lengths in mm, angles in rad.

Each candidate effect (:mod:`hyperstat.solver.diagnosis.effects`) is linearised at the
rigid solution (its Jacobian columns next to the base geometric ones) and scored by
blocked cross-validation: folds are workspace regions and, when recorded, payload,
session and temperature groups; the refit on each training fold is a ridge-regularised
Gauss-Newton step (prior standard deviations 0.5 mm and 1e-3 rad on the geometry, a
thousand times the realistic magnitude on the effect: practically none), so that
extrapolating weakly identifiable geometric directions into an unseen region does not
dominate the score.  BIC (known noise variance: ``chi2 + k ln n``) is reported beside.
An effect whose columns the geometry spans is reported as absorbed and never selected.
Each candidate is fitted within its physical domain (bounded least squares,
``scipy.optimize.lsq_linear``) and checked against its magnitude prior
(:meth:`~hyperstat.solver.diagnosis.effects.Effect.plausibility`).  Effects are added one
at a time while they lower the cross-validated error by at least 5 % and BIC by at
least 10 (:func:`select_effects`).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.calibration.identify import IdentificationResult, MeasurementModel
from hyperstat.solver.calibration.measurements import MeasurementSet
from hyperstat.solver.diagnosis.effects import Effect, is_library_effect, make_effect
from hyperstat.solver.diagnosis.observations import oriented, stack_rows
from hyperstat.solver.errors import DataError

__all__ = ["Screen", "folds", "region_blocks", "cv_rms", "absorbed", "effect_columns", "bounded_fit", "name_violated",
           "black_box_ceiling", "screen_candidates", "select_effects", "plugin_guard", "UnitActuators", "score_entry",
           "atom_key", "split_key", "make_atom", "bic_of",
           "PRIOR_LENGTH", "PRIOR_ANGLE", "DOMAIN_SIGMAS", "AMBIGUOUS_SHARE"]

PRIOR_LENGTH = 0.5  # mm, prior std of a geometric length parameter in the screening refits
PRIOR_ANGLE = 1e-3  # rad
DOMAIN_SIGMAS = 3.0  # an estimate this many std beyond a bound of its domain rejects the candidate
AMBIGUOUS_SHARE = 0.8  # a second candidate explaining this share of what the best explains is a tie


@contextlib.contextmanager
def plugin_guard(name: str, stage: str):
    """Turn any failure of a user plug-in effect into one sentence naming it (never a traceback).

    Library effects are not guarded: their failures are bugs and must show.
    """
    if is_library_effect(name):
        yield
        return
    try:
        yield
    except DataError:
        raise
    except Exception as exc:  # a broken plug-in is the user's input at fault: say which and where
        raise DataError(f"the effect plug-in '{name}' failed at the {stage} stage: {type(exc).__name__}: {exc}") \
            from exc


def region_blocks(q: np.ndarray, n_blocks: int = 4, seed: int = 0) -> np.ndarray:
    """Workspace regions: k-means (Lloyd, k-means++ start) on the actuated values scaled to [0, 1].

    >>> import numpy as np
    >>> q = np.r_[np.zeros((5, 2)), np.ones((5, 2))]
    >>> sorted(set(region_blocks(q, 2).tolist()))
    [0, 1]
    """
    span = np.ptp(q, axis=0)
    x = (q - q.min(axis=0)) / np.where(span > 0, span, 1.0)
    rng = np.random.default_rng(seed)
    centres = [x[rng.integers(len(x))]]
    for _ in range(1, n_blocks):
        d2 = np.min(((x[:, None, :] - np.array(centres)[None]) ** 2).sum(-1), axis=1)
        centres.append(x[rng.choice(len(x), p=d2 / d2.sum())] if d2.sum() > 0 else x[rng.integers(len(x))])
    c = np.array(centres)
    for _ in range(50):
        label = np.argmin(((x[:, None, :] - c[None]) ** 2).sum(-1), axis=1)
        new = np.array([x[label == b].mean(axis=0) if np.any(label == b) else c[b] for b in range(n_blocks)])
        if np.allclose(new, c):
            break
        c = new
    return label


def folds(data: MeasurementSet, n_blocks: int, seed: int) -> list[tuple[str, np.ndarray]]:
    """Blocked cross-validation schemes: (name, group label per row).

    Workspace regions always; payload, session and temperature groups when recorded.  The
    rows of one pose (several targets) always share a fold.
    """
    schemes = [("workspace region", region_blocks(data.q, n_blocks, seed))]
    for column in ("payload", "session"):
        values = data.metadata.get(column)
        if values is not None and len(set(values.tolist())) >= 2:
            schemes.append((column, np.unique(values, return_inverse=True)[1].ravel()))
    temp = data.metadata.get("temperature")
    if temp is not None and np.ptp(temp) > 1.0:
        edges = np.quantile(temp, [1 / 3, 2 / 3])
        schemes.append(("temperature", np.digitize(temp, edges)))
    return schemes


@dataclass
class Screen:
    """Weighted rigid residuals and Jacobians at the rigid solution, shared by all candidates."""

    w: np.ndarray  # (K,) 1/sigma
    resid: np.ndarray  # (K, 3) prediction - measurement (mm)
    base_jac: np.ndarray  # (K, 3, n_base) unweighted
    base_prior: np.ndarray  # (n_base,) prior std
    schemes: list
    q: np.ndarray | None = None  # assembled configurations at the rigid solution (warm start)
    cache: dict = field(default_factory=dict)
    #: factor of each row in the cross-validated RMS: 1 for position rows (mm); for orientation
    #: rows (rad) the position noise over the orientation noise (mm/rad), so that both count alike
    cv_scale: np.ndarray | None = None

    def prepared(self) -> dict:
        """Weighted base columns, their QR basis and per-fold Gram matrices (computed once)."""
        if self.cache:
            return self.cache
        k, _, n = self.base_jac.shape
        jw = (self.base_jac * self.w[:, None, None]).reshape(3 * k, n)
        rw = (self.resid * self.w[:, None]).reshape(3 * k)
        fold_list = []
        for _, labels in self.schemes:
            for g in np.unique(labels):
                test = labels == g
                if test.all():
                    continue
                rows = np.repeat(test, 3)
                fold_list.append((test, rows, jw[rows].T @ jw[rows], jw[rows].T @ rw[rows]))
        qb, _ = np.linalg.qr(jw / np.linalg.norm(jw, axis=0).clip(min=1e-300))
        self.cache.update(jw=jw, rw=rw, gram=jw.T @ jw, rhs=jw.T @ rw, folds=fold_list, qb=qb)
        return self.cache

    def weighted(self, cols: np.ndarray) -> np.ndarray:
        """Columns (K, 3, n) weighted by 1/sigma and flattened to (3K, n)."""
        return (cols * self.w[:, None, None]).reshape(3 * len(self.w), -1)


def cv_rms(screen: Screen, extra: np.ndarray | None, extra_prior: np.ndarray | None, with_cov: bool = False):
    """Cross-validated RMS (mm), BIC and rank of the refit with the base columns plus ``extra``,
    and the estimates of the ``extra`` parameters refitted on all the data (and their
    covariance for unit-variance weighted residuals, and the chi-square, when ``with_cov``).

    The training-fold normal equations are the full ones minus the held-out rows', so
    the base block is formed once per diagnosis.
    """
    pre = screen.prepared()
    jb, rw = pre["jw"], pre["rw"]
    k = len(screen.w)
    nb = jb.shape[1]
    if extra is None:
        ew = np.zeros((3 * k, 0))
        prior = screen.base_prior
    else:
        ew = screen.weighted(extra)
        prior = np.r_[screen.base_prior, extra_prior]
    ne = ew.shape[1]
    gram = np.zeros((nb + ne, nb + ne))
    gram[:nb, :nb] = pre["gram"]
    gram[:nb, nb:] = jb.T @ ew
    gram[nb:, :nb] = gram[:nb, nb:].T
    gram[nb:, nb:] = ew.T @ ew
    rhs = np.r_[pre["rhs"], ew.T @ rw]
    reg = np.diag(1.0 / prior**2)
    sq, count = 0.0, 0
    for test, rows, g_test, r_test in pre["folds"]:
        et = ew[rows]
        bt = jb[rows]
        gt = np.zeros_like(gram)
        gt[:nb, :nb] = g_test
        gt[:nb, nb:] = bt.T @ et
        gt[nb:, :nb] = gt[:nb, nb:].T
        gt[nb:, nb:] = et.T @ et
        rt = np.r_[r_test, et.T @ rw[rows]]
        delta = np.linalg.solve(gram - gt + reg, -(rhs - rt))
        jac_t = np.concatenate([screen.base_jac[test], extra[test]], axis=2) if ne else screen.base_jac[test]
        held = screen.resid[test] + jac_t @ delta
        if screen.cv_scale is not None:
            held = held * screen.cv_scale[test][:, None]
        sq += float(np.sum(held**2))
        count += int(test.sum())
    inv = np.linalg.inv(gram + reg)
    delta = -inv @ rhs
    full = np.concatenate([jb, ew], axis=1)
    chi = float(np.sum((rw + full @ delta) ** 2))
    rank = nb if not ne else nb + _extra_rank(pre["qb"], ew)
    estimates = delta[nb:]
    out = (float(np.sqrt(sq / max(count, 1))), chi + rank * np.log(3 * k), rank, estimates)
    if with_cov:
        return out + (inv[nb:, nb:], chi)
    return out


def bic_of(screen: Screen, extra: np.ndarray, extra_prior: np.ndarray) -> float:
    """The BIC of :func:`cv_rms` alone (the refit on all the data, no folds): a cheap first look at a candidate."""
    pre = screen.prepared()
    jb, rw = pre["jw"], pre["rw"]
    nb = jb.shape[1]
    ew = screen.weighted(extra)
    ne = ew.shape[1]
    gram = np.zeros((nb + ne, nb + ne))
    gram[:nb, :nb] = pre["gram"]
    gram[:nb, nb:] = jb.T @ ew
    gram[nb:, :nb] = gram[:nb, nb:].T
    gram[nb:, nb:] = ew.T @ ew
    rhs = np.r_[pre["rhs"], ew.T @ rw]
    reg = np.diag(1.0 / np.r_[screen.base_prior, extra_prior] ** 2)
    delta = -np.linalg.solve(gram + reg, rhs)
    chi = float(np.sum((rw + np.concatenate([jb, ew], axis=1) @ delta) ** 2))
    rank = nb + _extra_rank(pre["qb"], ew)
    return chi + rank * np.log(len(rw))


def _refit(screen: Screen, extra: np.ndarray, extra_prior: np.ndarray) -> tuple:
    """BIC, estimates, covariance and chi-square of the refit of :func:`cv_rms` on all the data (no folds)."""
    pre = screen.prepared()
    jb, rw = pre["jw"], pre["rw"]
    nb = jb.shape[1]
    ew = screen.weighted(extra)
    gram = np.block([[pre["gram"], jb.T @ ew], [ew.T @ jb, ew.T @ ew]])
    rhs = np.r_[pre["rhs"], ew.T @ rw]
    inv = np.linalg.inv(gram + np.diag(1.0 / np.r_[screen.base_prior, extra_prior] ** 2))
    delta = -inv @ rhs
    chi = float(np.sum((rw + np.concatenate([jb, ew], axis=1) @ delta) ** 2))
    rank = nb + _extra_rank(pre["qb"], ew)
    return chi + rank * np.log(len(rw)), delta[nb:], inv[nb:, nb:], chi


def _extra_rank(qb: np.ndarray, ew: np.ndarray) -> int:
    """Number of independent directions the extra columns add to the base columns."""
    norms = np.linalg.norm(ew, axis=0)
    if not np.any(norms > 0):
        return 0
    e = ew[:, norms > 0] / norms[norms > 0]
    rest = e - qb @ (qb.T @ e)
    s = np.linalg.svd(rest, compute_uv=False)
    return int(np.sum(s > 1e-6))


def absorbed(screen: Screen, extra: np.ndarray) -> float:
    """Largest fraction of an effect column (weighted, unit norm) that the geometry does not span."""
    qb = screen.prepared()["qb"]
    e = screen.weighted(extra)
    norms = np.linalg.norm(e, axis=0)
    if not np.any(norms > 0):
        return 0.0
    e = e[:, norms > 0] / norms[norms > 0]
    rest = e - qb @ (qb.T @ e)
    return float(np.linalg.svd(rest, compute_uv=False)[0])


def _only_actuator(effect: Effect) -> bool:
    """Whether the effect enters through the actuated values alone (its columns follow from ``dq/dtheta``)."""
    cls = type(effect)
    return (cls.defect_directions is Effect.defect_directions and cls.output_correction is Effect.output_correction
            and cls.measurement_correction is Effect.measurement_correction
            and cls.actuator_correction is not Effect.actuator_correction)


def _only_output(effect: Effect) -> bool:
    """Whether the effect moves the target point in the base frame alone (``output_correction``)."""
    cls = type(effect)
    return (cls.output_correction is not Effect.output_correction and cls.defect_directions is Effect.defect_directions
            and cls.measurement_correction is Effect.measurement_correction
            and cls.actuator_correction is Effect.actuator_correction)


class UnitActuators(Effect):
    """Helper effect ``dq = theta`` (one parameter per actuator): its columns are ``d position / d q_a``."""

    name = "unit-actuators"

    def __init__(self, n_act: int) -> None:
        super().__init__([f"_dq{a}" for a in range(n_act)], ["-"] * n_act, np.ones(n_act))

    def actuator_correction(self, model, theta, data):
        k = len(data)
        return np.broadcast_to(theta, (k, len(theta))).copy(), np.broadcast_to(np.eye(len(theta)),
                                                                                (k, len(theta), len(theta))).copy()


def effect_columns(mech, analysis, kin, rigid: IdentificationResult, data, effect,
                   q_start: np.ndarray | None = None, act_jac: np.ndarray | None = None,
                   at_rigid: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Unweighted Jacobian columns (R, 3, n_e) of ``effect`` on the rows at the rigid solution, and their prior std.

    The rows are the position rows of ``data``, then its orientation rows for a 6-D rigid
    model (:mod:`.observations`).  An effect entering through the actuated values alone is
    ``d row / d q_a`` times its ``d dq / d theta`` (``act_jac`` given, on the same rows):
    no new evaluation of the model.  An effect that moves the target point in the base frame
    alone (``output_correction``) is its ``d dp / d theta`` turned into the tracker frame, at the
    rigid solution's configurations, state and target points (``at_rigid``: ``q``, ``state``,
    ``world``, ``r_trk``); it turns no orientation.
    """
    prior = 1000.0 * np.maximum(effect.magnitude, 1e-12)
    if getattr(effect, "sign_of_load", False):
        # a step with the sign of a load: in a fold where that sign never changes, the column is a constant offset
        # the geometry also fits; with a vague prior the fold's refit puts the offset into the effect and the
        # held-out rows of the other sign get it twice (the hexapod's clearance: CV 257 um against 33 um rigid).
        # Its physical bound as prior leaves the offset to the geometry there.
        prior = np.asarray(effect.plausible, dtype=float).copy()
    six_d = oriented(rigid.model, data)
    with plugin_guard(effect.name, "columns"):
        if act_jac is not None and _only_actuator(effect):
            model = MeasurementModel(mech, analysis, kin)
            theta0 = np.zeros(len(effect.parameter_names(None)))
            _, dt = effect.actuator_correction(model, theta0, data)
            dt = np.asarray(dt, float)
            return np.einsum("kia,kae->kie", act_jac, stack_rows(dt, dt if six_d else None)), prior
        if at_rigid is not None and _only_output(effect):
            model = MeasurementModel(mech, analysis, kin)
            theta0 = np.zeros(len(effect.parameter_names(None)))
            _, dp = effect.output_correction(model, theta0, data, at_rigid["q"], at_rigid["state"], at_rigid["world"],
                                             True)
            cols = np.einsum("ij,kia->kja", at_rigid["r_trk"], np.asarray(dp, float))
            cols = stack_rows(cols, np.zeros_like(cols) if six_d else None)
            if not np.all(np.isfinite(cols)):
                raise DataError(f"the effect '{effect.name}' gives non-finite derivatives on these poses.")
            return cols, prior
        model = MeasurementModel(mech, analysis, kin, effects=(effect,), targets=list(data.target_names),
                                 orientation=six_d)
        theta = model.initial()
        theta[: rigid.model.n] = rigid.theta
        pred = model.predict(theta, data, jacobian=True, q_start=q_start)
        sl = model._effect_slices[0]
        cols = stack_rows(pred.jacobian[:, :, sl], pred.rotation_jacobian[:, :, sl] if six_d else None)
    if not np.all(np.isfinite(cols)):
        raise DataError(f"the effect '{effect.name}' gives non-finite derivatives on these poses.")
    return cols, prior


def bounded_fit(screen: Screen, jac_e: np.ndarray, prior_e: np.ndarray, effect: Effect) -> np.ndarray:
    """Effect estimates refitted with the geometry within the effect's domain (``lsq_linear``, ridge rows)."""
    from scipy.optimize import lsq_linear

    pre = screen.prepared()
    ew = screen.weighted(jac_e)
    prior = np.r_[screen.base_prior, prior_e]
    a = np.vstack([np.concatenate([pre["jw"], ew], axis=1), np.diag(1.0 / prior)])
    b = np.r_[-pre["rw"], np.zeros(len(prior))]
    nb = pre["jw"].shape[1]
    lo = np.r_[np.full(nb, -np.inf), effect.lower]
    hi = np.r_[np.full(nb, np.inf), effect.upper]
    return lsq_linear(a, b, bounds=(lo, hi), method="bvls").x[nb:]


def black_box_ceiling(resid: np.ndarray, data: MeasurementSet, schemes: list) -> float:
    """CV RMS of the rigid position residuals after a ridge regression on joints (quadratic) and metadata (mm)."""
    def scaled(v):
        return (v - v.mean()) / max(float(v.std()), 1e-12)

    x = np.stack([scaled(data.q[:, a]) for a in range(data.q.shape[1])], axis=1)
    feats = [np.ones(len(x))] + [x[:, i] for i in range(x.shape[1])]
    feats += [x[:, i] * x[:, j] for i in range(x.shape[1]) for j in range(i, x.shape[1])]
    for v in data.metadata.values():  # metadata: linear, and quadratic when not two-valued
        if np.ptp(v) > 0:
            feats.append(scaled(v))
            if len(set(v.tolist())) > 2:
                feats.append(scaled(v) ** 2)
    f = np.stack(feats, axis=1)
    lams = (1e-1, 1.0, 10.0, 100.0)
    sq = np.zeros(len(lams))
    count = 0
    for _, labels in schemes:
        for g in np.unique(labels):
            test = labels == g
            if test.all():
                continue
            a = f[~test]
            evals, evecs = np.linalg.eigh(a.T @ a)
            proj = evecs.T @ (a.T @ resid[~test])
            for n, lam in enumerate(lams):
                coef = evecs @ (proj / (evals + lam)[:, None])
                sq[n] += float(np.sum((resid[test] - f[test] @ coef) ** 2))
            count += int(test.sum())
    return float(np.sqrt(sq.min() / max(count, 1)))


def name_violated(mech, analysis, kin, rigid, data, screen: Screen, base_cv: float) -> dict | None:
    """The single forced defect whose violation best explains the residuals (blocked CV).

    Each forced defect is tried alone (one parameter, refitted with the geometry); the
    columns of all of them come from one evaluation of the model.  Those that explain at
    least ``AMBIGUOUS_SHARE`` of the gap the best one explains (``base_cv**2 - cv**2``)
    cannot be told apart by the data; among them the one that needs the smallest
    violation relative to its realistic magnitude (5e-4 rad or 0.05 mm) is named, the
    most probable a priori, and the others are listed in ``ambiguous_with``.  The
    runner-ups are returned with their CV RMS and estimate (in the defect's own unit).
    """
    effect = make_effect("violated-constraint", mech, analysis, data)
    jac_all, prior_all = effect_columns(mech, analysis, kin, rigid, data, effect, screen.q)
    units = {p.name: p.unit for p in mech.parameters}
    entries = []
    for e, name in enumerate(effect.defects):
        je = jac_all[:, :, e:e + 1]
        if not np.any(je):
            continue
        cv, _, _, estimates = cv_rms(screen, je, prior_all[e:e + 1])
        estimate = float(estimates[0])
        realistic = float(effect.magnitude[e])
        entries.append({"defect": name, "cv_rms": cv, "estimate": estimate, "unit": units[name],
                        "realistic_magnitude": realistic, "times_realistic": abs(estimate) / realistic})
    if not entries:
        return None
    entries.sort(key=lambda e: e["cv_rms"])
    best_gain = base_cv**2 - entries[0]["cv_rms"] ** 2
    tied = [e for e in entries if e is entries[0]
            or (best_gain > 0 and base_cv**2 - e["cv_rms"] ** 2 >= AMBIGUOUS_SHARE * best_gain)]
    named = min(tied, key=lambda e: e["times_realistic"])
    rest = [e for e in entries if e is not named]
    how = "cross-validation" if named is entries[0] else "smallest violation among the candidates the data cannot tell apart"
    return {**named, "named_by": how, "alternatives": rest[:3],
            "ambiguous_with": [e["defect"] for e in tied if e is not named]}


def score_entry(screen: Screen, name: str, effect: Effect, jac_e: np.ndarray, prior_e: np.ndarray, rank: int,
                base_bic: float, cross_validate: bool = True) -> dict:
    """The screening entry of one candidate (its columns given): CV RMS, delta BIC, estimates, std, the domain check.

    ``rank`` is the rigid fit's; ``entry["rejected"]`` is set (with ``bounded_estimates``) when the
    unconstrained estimate leaves the effect's domain or prior by more than :data:`DOMAIN_SIGMAS`.
    Without ``cross_validate`` (a per-joint candidate: the selection cross-validates it when it
    competes) the CV RMS is left out (None).
    """
    params = effect.parameter_names(None)
    free = absorbed(screen, jac_e)
    if cross_validate:
        cv, bic, _, est, cov, chi = cv_rms(screen, jac_e, prior_e, with_cov=True)
    else:
        cv = None
        bic, est, cov, chi = _refit(screen, jac_e, prior_e)
    dof = max(3 * len(screen.w) - rank - len(prior_e), 1)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None) * max(1.0, chi / dof))
    entry = {"effect": name, "cv_rms": cv, "criterion": bic - base_bic, "criterion_name": "delta BIC",
             "parameters": len(prior_e), "unexplained_by_geometry": free,
             "estimates": dict(zip(params, map(float, est))), "std": dict(zip(params, map(float, std)))}
    if free < 1e-3:
        entry["note"] = "absorbed by the geometric parameters: not identifiable against them"
    elif free < 0.1:
        entry["absorbed_share"] = 1.0 - free
    why = effect.plausibility(est, std, DOMAIN_SIGMAS) if free >= 1e-3 else None
    if why is not None:
        entry["rejected"] = why
        entry["bounded_estimates"] = dict(zip(params, map(float, bounded_fit(screen, jac_e, prior_e, effect))))
    return entry


def atom_key(name: str, joint: str) -> str:
    """Key of a per-joint candidate: ``angle-harmonic-1@2`` is ``angle-harmonic-1`` on joint 2 alone.

    >>> atom_key("angle-scale", "3")
    'angle-scale@3'
    """
    return f"{name}@{joint}"


def split_key(key: str) -> tuple[str, str | None]:
    """The effect name and the joint of a candidate key (None for a whole effect).

    >>> split_key("angle-harmonic-1.5@1"), split_key("compliance")
    (('angle-harmonic-1.5', '1'), ('compliance', None))
    """
    name, _, joint = key.partition("@")
    return name, (joint or None)


def screen_candidates(mech, analysis, kin, rigid, data, screen: Screen, act_jac: np.ndarray, base_cv: float,
                      base_bic: float, names: list, not_applicable: dict, options: dict | None = None,
                      with_atoms: bool = True, at_rigid: dict | None = None) -> dict:
    """Linearise, score and check every candidate: ``ranking`` (sorted), ``columns``, ``rejected``, ``effects``,
    and the per-joint candidates ``atoms``.

    ``options`` gives per-name keyword arguments of :func:`make_effect` (e.g. the joints of
    an ``angle-harmonic-<k>`` from the spectrum).  A candidate whose unconstrained estimate
    leaves its domain or its magnitude prior is kept in the ranking with ``rejected`` set.
    An effect with parameters per actuated joint (:func:`~.effects.is_jointwise`) is also
    screened on each joint alone (with ``with_atoms``) (``atoms``: key ``name@joint`` -> ``{"entry", "columns",
    "effect", "name", "joint"}``; its columns are the whole effect's columns of that joint).
    """
    from hyperstat.solver.diagnosis.effects import is_jointwise

    options = options or {}
    columns, effects, ranking, rejected, atoms = {}, {}, [], [], {}
    violated = None
    for name in names:
        if name in not_applicable:
            continue
        if name == "violated-constraint":
            # one forced defect at a time: the best explains the gap with one parameter and is named
            violated = name_violated(mech, analysis, kin, rigid, data, screen, base_cv)
            if violated is None:
                not_applicable[name] = "no forced defect moves the measured point"
                continue
            effect = make_effect(name, mech, analysis, data, only=[violated["defect"]])
        else:
            kw = dict(options.get(name, {}))
            if name in ("link-bending", "guide-straightness", "base-deformation"):
                kw["kin"] = kin
            effect = make_effect(name, mech, analysis, data, **kw)
        params = effect.parameter_names(None)
        if not params:
            not_applicable[name] = "no parameter applies to this mechanism and data"
            continue
        jac_e, prior_e = effect_columns(mech, analysis, kin, rigid, data, effect, screen.q, act_jac, at_rigid)
        if not np.any(jac_e):
            not_applicable[name] = "its signature is zero on these poses (e.g. no gravity moment on its joints)"
            continue
        columns[name] = (jac_e, prior_e)
        effects[name] = effect
        entry = score_entry(screen, name, effect, jac_e, prior_e, rigid.rank, base_bic)
        if name == "violated-constraint":
            entry["defect"] = violated["defect"]
        if "rejected" in entry:
            rejected.append({"effect": name, "stage": "screening", "reason": entry["rejected"]})
        ranking.append(entry)
        if with_atoms and is_library_effect(name) and is_jointwise(name) and hasattr(effect, "param_joints"):
            joints = list(dict.fromkeys(effect.param_joints))
            if len(joints) > 1:
                for joint in joints:
                    atoms[atom_key(name, joint)] = make_atom(screen, mech, analysis, data, name, effect, columns[name],
                                                             joint, kw, rigid.rank, base_bic)
    ranking.sort(key=lambda e: (e.get("note") is not None, e["cv_rms"]))
    return {"ranking": ranking, "columns": columns, "effects": effects, "rejected": rejected, "violated": violated,
            "atoms": atoms}


def make_atom(screen: Screen, mech, analysis, data, name: str, effect: Effect, whole: tuple, joint: str, kw: dict,
              rank: int, base_bic: float) -> dict:
    """The per-joint candidate ``name@joint``: the effect on that joint alone, its columns cut from the whole's."""
    idx = [i for i, j in enumerate(effect.param_joints) if j == joint]
    cols, prior = whole[0][:, :, idx], whole[1][idx]
    kw = {k: v for k, v in kw.items() if k != "joints"}
    if name in ("guide-straightness",):
        kw["kin"] = getattr(effect, "kin", None)
    atom = make_effect(name, mech, analysis, data, joints=[joint], **kw)
    entry = score_entry(screen, atom_key(name, joint), atom, cols, prior, rank, base_bic, cross_validate=False)
    return {"entry": entry, "columns": (cols, prior), "effect": atom, "name": name, "joint": joint}


def select_effects(screen: Screen, ranking: list, columns: dict, base_cv: float, base_bic: float,
                   max_effects: int, refuse=None) -> tuple[list, list, list]:
    """Forward selection: add the candidate with the lowest cross-validated RMS while it lowers it by 5 %
    and BIC by 10.

    ``refuse(name, selected)`` may refuse a candidate at the moment it would be added (a
    reason string; it is then marked rejected and the next best is tried).  Returns the
    selected names, the ties (two candidates explaining the same part of the gap), and
    the refusals ``{"effect", "stage", "reason"}``.
    """
    selected: list[str] = []
    ties: list = []
    refused: list = []
    current_cv, current_bic = base_cv, base_bic
    extra, extra_prior = None, None
    for _ in range(max_effects):
        trials = []
        for entry in ranking:
            name = entry["effect"]
            if name in selected or entry.get("note") or entry.get("rejected"):
                continue
            je, pe = columns[name]
            ex = je if extra is None else np.concatenate([extra, je], axis=2)
            pr = pe if extra_prior is None else np.r_[extra_prior, pe]
            cv, bic, _, _ = cv_rms(screen, ex, pr)
            trials.append((cv, bic, name, ex, pr))
        trials.sort(key=lambda t: t[0])
        chosen = None
        for n, trial in enumerate(trials):
            cv, bic, name, ex, pr = trial
            if not (cv < 0.95 * current_cv and bic < current_bic - 10.0):
                break
            why = refuse(name, selected) if refuse is not None else None
            if why is None:
                chosen = (n, trial)
                break
            refused.append(why)
            for entry in ranking:
                if entry["effect"] == name:
                    entry["rejected"] = why["reason"]
        if chosen is None:
            break
        n, (cv, bic, name, ex, pr) = chosen
        gain = current_cv**2 - cv**2
        for cv2, _, name2, _, _ in trials[n + 1:n + 2]:
            gain2 = current_cv**2 - cv2**2
            if gain2 >= AMBIGUOUS_SHARE * gain:
                both, *_ = cv_rms(screen, np.concatenate([ex, columns[name2][0]], axis=2),
                                  np.r_[pr, columns[name2][1]])
                if cv**2 - both**2 < 0.2 * gain2:
                    ties.append({"effects": [name, name2], "cv_rms": [cv, cv2],
                                 "note": f"{name} and {name2} explain the same part of the gap"})
        selected.append(name)
        extra, extra_prior, current_cv, current_bic = ex, pr, cv, bic
    return selected, ties, refused
