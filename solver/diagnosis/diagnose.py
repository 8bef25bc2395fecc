"""Diagnosis of the sim-to-real gap: is there one, where it lies, which effect causes it, how far it shrinks.

Units: lengths in mm (residuals reported in mm; the text output prints um), angles in rad.

1. **Is there a gap?**  After the rigid identification the weighted residuals follow a
   chi-square law with ``3K - rank`` degrees of freedom when the noise model of the data
   is right and nothing is missing; validation points give a second, independent test.
   "No significant gap" is the answer when neither p-value is below 1e-3 (Bonferroni).
2. **Where?**  Residual RMS per workspace region (k-means blocks of the normalised
   actuated values), per base-frame direction, the share of the residual variance each
   joint variable and metadata column explains (a quadratic fit), and a Lomb-Scargle
   spectrum of the residuals along each prismatic actuator's travel.
3. **Which effect?**  Each candidate effect (:mod:`hyperstat.solver.diagnosis.effects`) is linearised at the
   rigid solution (its Jacobian columns next to the base geometric ones) and scored by
   blocked cross-validation: folds are workspace regions and, when recorded, payload,
   session and temperature groups; the refit on each training fold is a ridge-regularised
   Gauss-Newton step (prior standard deviations 0.5 mm and 1e-3 rad on the geometry, a
   thousand times the realistic magnitude on the effect: practically none), so that extrapolating weakly identifiable
   geometric directions into an unseen region does not dominate the score.  BIC (known
   noise variance: ``chi2 + k ln n``) is reported beside.  An effect whose columns the
   geometry spans (its residual part after projection on the geometric columns is below
   0.1 %) is reported as absorbed by the geometry and never selected; one mostly absorbed
   (below 10 %) carries its ``absorbed_share``: only the rest of it can be seen.  Effects are added one at a time while
   they lower the cross-validated error by at least 5 % and BIC by at least 10; two
   effects that explain the same part of the gap are reported as ambiguous.
4. **How far it shrinks.**  The selected effects are identified together with the
   geometry by the full nonlinear fit; validation mean / max / RMS before and after, the
   share of the gap explained ``(before^2 - after^2) / (before^2 - noise^2)`` and the
   ceiling a flexible black-box regression of the residuals reaches under the same folds.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.special import chdtrc  # chi-square survival function; scipy.stats costs 1.3 s more to import

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.diagnosis.effects import EFFECT_NAMES, applicable_effects, make_effect
from hyperstat.solver.errors import DataError
from hyperstat.solver.calibration.identify import IdentificationResult, MeasurementModel, _weights, error_stats, identify
from hyperstat.solver.calibration.measurements import MeasurementSet
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.analysis.stationarity import StationarityResult

__all__ = ["Diagnosis", "diagnose", "region_blocks"]

PRIOR_LENGTH = 0.5  # mm, prior std of a geometric length parameter in the screening refits
PRIOR_ANGLE = 1e-3  # rad
P_THRESHOLD = 1e-3


@dataclass
class Diagnosis:
    """Outcome of :func:`diagnose`; ``to_dict`` gives the JSON of ``hyperstat diagnose``."""

    gap_significant: bool
    gap_test: dict
    where: dict
    ranking: list
    selected: list
    ambiguous: list
    not_applicable: dict
    validation_before: dict | None
    validation_after: dict | None
    share_explained: float | None
    ceiling: dict
    effect_parameters: list
    violated_defect: dict | None
    rigid: IdentificationResult = field(repr=False)
    final: IdentificationResult | None = field(default=None, repr=False)
    elapsed: float = 0.0

    def to_dict(self) -> dict:
        """JSON-ready dictionary (units: mm, rad)."""
        return {
            "units": {"length": "mm", "angle": "rad"},
            "gap_significant": self.gap_significant,
            "gap_test": self.gap_test,
            "where": self.where,
            "ranking": self.ranking,
            "selected": self.selected,
            "ambiguous": self.ambiguous,
            "not_applicable": self.not_applicable,
            "validation_before": self.validation_before,
            "validation_after": self.validation_after,
            "share_explained": self.share_explained,
            "ceiling": self.ceiling,
            "effect_parameters": self.effect_parameters,
            "violated_defect": self.violated_defect,
            "rigid_identification": {"rank": self.rigid.rank, "condition_number": self.rigid.condition_number,
                                     "identification": self.rigid.identification},
        }


# ---------------------------------------------------------------------------- helpers
def region_blocks(q: np.ndarray, n_blocks: int = 4, seed: int = 0) -> np.ndarray:
    """Workspace regions: k-means (Lloyd, k-means++ start) on the actuated values scaled to [0, 1]."""
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


def _folds(data: MeasurementSet, n_blocks: int, seed: int) -> list[tuple[str, np.ndarray]]:
    """Blocked cross-validation schemes: (name, group label per pose)."""
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
class _Screen:
    """Weighted rigid residuals and Jacobians at the rigid solution, shared by all candidates."""

    w: np.ndarray  # (K,) 1/sigma
    resid: np.ndarray  # (K, 3) prediction - measurement (mm)
    base_jac: np.ndarray  # (K, 3, n_base) unweighted
    base_prior: np.ndarray  # (n_base,) prior std
    schemes: list
    q: np.ndarray | None = None  # assembled configurations at the rigid solution (warm start)


AMBIGUOUS_SHARE = 0.8  # a second candidate explaining this share of what the best explains is reported as ambiguous


def _cv_rms(screen: _Screen, extra: np.ndarray | None,
            extra_prior: np.ndarray | None) -> tuple[float, float, int, np.ndarray]:
    """Cross-validated RMS (mm), BIC and rank of the refit with the base columns plus ``extra``,
    and the estimates of the ``extra`` parameters refitted on all the data."""
    jac = screen.base_jac if extra is None else np.concatenate([screen.base_jac, extra], axis=2)
    prior = screen.base_prior if extra is None else np.r_[screen.base_prior, extra_prior]
    k, _, n = jac.shape
    w = screen.w
    jw = (jac * w[:, None, None]).reshape(3 * k, n)
    rw = (screen.resid * w[:, None]).reshape(3 * k)
    reg = np.diag(1.0 / prior**2)
    sq, count = 0.0, 0
    for _, labels in screen.schemes:
        for g in np.unique(labels):
            test = labels == g
            if test.all():
                continue
            train = np.repeat(~test, 3)
            a = jw[train]
            delta = np.linalg.solve(a.T @ a + reg, -a.T @ rw[train])
            held = screen.resid[test] + jac[test] @ delta
            sq += float(np.sum(held**2))
            count += int(test.sum())
    delta = np.linalg.solve(jw.T @ jw + reg, -jw.T @ rw)
    chi = float(np.sum((rw + jw @ delta) ** 2))
    s = np.linalg.svd(jw / np.linalg.norm(jw, axis=0).clip(min=1e-300), compute_uv=False)
    rank = int(np.sum(s > 1e-8 * s[0]))
    estimates = delta[len(screen.base_prior):]
    return float(np.sqrt(sq / max(count, 1))), chi + rank * np.log(3 * k), rank, estimates


def _absorbed(screen: _Screen, extra: np.ndarray) -> float:
    """Largest fraction of an effect column (weighted, unit norm) that the geometry does not span."""
    k = len(screen.w)
    b = (screen.base_jac * screen.w[:, None, None]).reshape(3 * k, -1)
    e = (extra * screen.w[:, None, None]).reshape(3 * k, -1)
    norms = np.linalg.norm(e, axis=0)
    if not np.any(norms > 0):
        return 0.0
    e = e[:, norms > 0] / norms[norms > 0]
    qb, _ = np.linalg.qr(b / np.linalg.norm(b, axis=0).clip(min=1e-300))
    rest = e - qb @ (qb.T @ e)
    return float(np.linalg.svd(rest, compute_uv=False)[0])


def _effect_columns(mech, analysis, kin, rigid: IdentificationResult, data, effect,
                    q_start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Unweighted Jacobian columns (K, 3, n_e) of ``effect`` at the rigid solution, and their prior std."""
    model = MeasurementModel(mech, analysis, kin, effects=(effect,))
    theta = model.initial()
    theta[: rigid.model.n] = rigid.theta
    pred = model.predict(theta, data, jacobian=True, q_start=q_start)
    sl = model._effect_slices[0]
    return pred.jacobian[:, :, sl], 1000.0 * np.maximum(effect.magnitude, 1e-12)


def _where(mech: Mechanism, rigid: IdentificationResult, data: MeasurementSet, labels: np.ndarray) -> dict:
    """Residual field: by region, by direction, against joint variables and metadata, spectra."""
    resid = rigid.residuals
    r_trk, _ = rigid.model.tracker_pose(rigid.theta)
    base = resid @ r_trk.T  # tracker frame -> base frame directions
    total = float(np.sum(resid**2))
    regions = []
    for b in np.unique(labels):
        rows = labels == b
        regions.append({"region": int(b), "points": int(rows.sum()),
                        "centre": {f"q{data.joints[a]}": float(data.q[rows, a].mean()) for a in range(data.q.shape[1])},
                        "rms": float(np.sqrt(np.mean(np.sum(resid[rows] ** 2, axis=1))))})
    direction = {ax: float(np.sqrt(np.mean(base[:, a] ** 2))) for a, ax in enumerate("xyz")}
    variables = {f"q{j}": data.q[:, a] for a, j in enumerate(data.joints)}
    variables.update({k: v for k, v in data.metadata.items() if np.ptp(v) > 0})
    explained = []
    for name, v in variables.items():
        x = (v - v.mean()) / (np.std(v) or 1.0)
        design = np.stack([np.ones_like(x), x, x**2], axis=1)
        coef, *_ = np.linalg.lstsq(design, base, rcond=None)
        fit = design @ coef
        explained.append({"variable": name, "share": float(np.sum(fit**2) / total) if total > 0 else 0.0})
    explained.sort(key=lambda e: -e["share"])
    from scipy.signal import lombscargle  # heavy import, only needed here

    spectra = []
    for a, i in enumerate(mech.actuated):
        if mech.joints[i].type != "P":
            continue
        qv = data.q[:, a]
        if np.ptp(qv) <= 0:
            continue
        periods = np.linspace(2.0, max(4.0, np.ptp(qv) / 3.0), 200)
        freqs = 2.0 * np.pi / periods
        power = np.zeros_like(freqs)
        for c in range(3):
            y = base[:, c] - base[:, c].mean()
            if np.any(y):
                power += lombscargle(qv, y, freqs, normalize=False)
        best = int(np.argmax(power))
        spectra.append({"joint": data.joints[a], "peak_period_mm": float(periods[best]),
                        "peak_share": float(power[best] / power.sum()) if power.sum() > 0 else 0.0,
                        "periods_mm": periods.tolist(), "power": power.tolist()})
    return {"regions": regions, "direction_rms": direction, "explained_by": explained, "spectra": spectra}


def _black_box_ceiling(screen: _Screen, data: MeasurementSet) -> float:
    """CV RMS of the rigid residuals after a ridge quadratic regression on joints and metadata (mm)."""
    cols = [data.q[:, a] for a in range(data.q.shape[1])]
    cols += [v for v in data.metadata.values() if np.ptp(v) > 0]
    x = np.stack(cols, axis=1)
    x = (x - x.mean(axis=0)) / x.std(axis=0).clip(min=1e-12)
    feats = [np.ones(len(x))] + [x[:, i] for i in range(x.shape[1])]
    feats += [x[:, i] * x[:, j] for i in range(x.shape[1]) for j in range(i, x.shape[1])]
    f = np.stack(feats, axis=1)
    best = np.inf
    for lam in (1e-2, 1e-1, 1.0, 10.0, 100.0):
        sq, count = 0.0, 0
        for _, labels in screen.schemes:
            for g in np.unique(labels):
                test = labels == g
                if test.all():
                    continue
                a = f[~test]
                coef = np.linalg.solve(a.T @ a + lam * np.eye(f.shape[1]), a.T @ screen.resid[~test])
                sq += float(np.sum((screen.resid[test] - f[test] @ coef) ** 2))
                count += int(test.sum())
        best = min(best, float(np.sqrt(sq / max(count, 1))))
    return best


# ---------------------------------------------------------------------------- main entry
def diagnose(
    mechanism: Mechanism,
    analysis: StationarityResult,
    data: MeasurementSet,
    validation: MeasurementSet | None = None,
    candidates: tuple = EFFECT_NAMES,
    kinematics: Kinematics | None = None,
    n_blocks: int = 4,
    seed: int = 0,
    max_effects: int = 3,
) -> Diagnosis:
    """Diagnose the gap left by the rigid model (see the module docstring for the method).

    Parameters
    ----------
    mechanism, analysis : Mechanism, StationarityResult
        Nominal model and its stationarity analysis.
    data : MeasurementSet
        Identification measurements; its noise model is needed for the gap test.
    validation : MeasurementSet, optional
        Held-out points for the before / after numbers (never used to choose).
    candidates : tuple of str
        Effect names to consider.
    n_blocks : int
        Workspace regions of the blocked cross-validation.
    max_effects : int
        Most effects added.

    Returns
    -------
    Diagnosis

    Raises
    ------
    DataError
        If the data state no noise model (the gap test needs one) or name an unknown effect.
    """
    t0 = time.perf_counter()
    if data.noise is None:
        raise DataError(f"{data.source}: the diagnosis needs the header line '# noise: A mm + B mm/m' (the tracker's "
                        f"noise model) to tell a gap from noise.")
    for c in candidates:
        if c not in EFFECT_NAMES:
            raise DataError(f"unknown effect '{c}'; effects are {', '.join(EFFECT_NAMES)}.")
    kin = kinematics or Kinematics(mechanism)
    rigid = identify(mechanism, analysis, data, validation, kinematics=kin)
    w = _weights(data)
    rw = rigid.residuals * w[:, None]
    dof = 3 * len(data) - rigid.rank
    chi_id = float(np.sum(rw**2))
    p_id = float(chdtrc(dof, chi_id))
    test = {"identification": {"chi2": chi_id, "dof": dof, "p_value": p_id}}
    p_min = p_id
    if validation is not None and len(validation):
        wv = _weights(validation)
        chi_v = float(np.sum((rigid.validation_residuals * wv[:, None]) ** 2))
        # prediction variance of the fitted model adds about rank/K to each point's variance
        scale = 1.0 + rigid.rank / (3.0 * len(data))
        p_v = float(chdtrc(3 * len(validation), chi_v / scale))
        test["validation"] = {"chi2": chi_v, "dof": 3 * len(validation), "p_value": p_v, "variance_inflation": scale}
        p_min = min(p_min, p_v)
    n_tests = len(test)
    significant = bool(p_min < P_THRESHOLD / n_tests)
    test["threshold"] = P_THRESHOLD / n_tests

    schemes = _folds(data, n_blocks, seed)
    base_idx = [rigid.model.names.index(b) for b in rigid.base]
    full = rigid.model.predict(rigid.theta, data, jacobian=True, q_start=rigid.configurations)
    units = rigid.model.units
    kinds = rigid.model.kinds
    prior = np.array([(PRIOR_ANGLE if units[j] == "rad" else PRIOR_LENGTH) if kinds[j] == "geometry" else 1e3
                      for j in base_idx])
    screen = _Screen(w, rigid.residuals, full.jacobian[:, :, base_idx], prior, schemes, full.q)
    where = _where(mechanism, rigid, data, schemes[0][1])
    base_cv, base_bic, _, _ = _cv_rms(screen, None, None)

    violated = None
    not_applicable = {k: v for k, v in applicable_effects(mechanism, analysis, data).items() if k in candidates}
    columns = {}
    ranking = []
    for name in candidates:
        if name in not_applicable:
            continue
        if name == "violated-constraint":
            # one forced defect at a time: the best explains the gap with one parameter and is named
            violated = _name_violated(mechanism, analysis, kin, rigid, data, screen, base_cv)
            effect = make_effect(name, mechanism, analysis, data, only=[violated["defect"]])
        else:
            effect = make_effect(name, mechanism, analysis, data)
        if not effect.parameter_names(None):
            not_applicable[name] = "no parameter applies to this mechanism and data"
            continue
        jac_e, prior_e = _effect_columns(mechanism, analysis, kin, rigid, data, effect, screen.q)
        free = _absorbed(screen, jac_e)
        cv, bic, _, _ = _cv_rms(screen, jac_e, prior_e)
        columns[name] = (jac_e, prior_e)
        entry = {"effect": name, "cv_rms": cv, "criterion": bic - base_bic, "criterion_name": "delta BIC",
                 "parameters": len(prior_e), "unexplained_by_geometry": free}
        if name == "violated-constraint":
            entry["defect"] = violated["defect"]
        if free < 1e-3:
            entry["note"] = "absorbed by the geometric parameters: not identifiable against them"
        elif free < 0.1:
            entry["absorbed_share"] = 1.0 - free
        ranking.append(entry)
    ranking.sort(key=lambda e: (e.get("note") is not None, e["cv_rms"]))

    selected: list[str] = []
    ambiguous: list = []
    current_cv, current_bic = base_cv, base_bic
    extra, extra_prior = None, None
    if significant:
        for _ in range(max_effects):
            best = None
            trials = []
            for entry in ranking:
                name = entry["effect"]
                if name in selected or entry.get("note"):
                    continue
                je, pe = columns[name]
                ex = je if extra is None else np.concatenate([extra, je], axis=2)
                pr = pe if extra_prior is None else np.r_[extra_prior, pe]
                cv, bic, _, _ = _cv_rms(screen, ex, pr)
                trials.append((cv, bic, name, ex, pr))
            trials.sort(key=lambda t: t[0])
            if not trials:
                break
            cv, bic, name, ex, pr = trials[0]
            if not (cv < 0.95 * current_cv and bic < current_bic - 10.0):
                break
            gain = current_cv**2 - cv**2
            for cv2, _, name2, ex2, pr2 in trials[1:2]:
                gain2 = current_cv**2 - cv2**2
                if gain2 >= AMBIGUOUS_SHARE * gain:
                    both, *_ = _cv_rms(screen, np.concatenate([ex, columns[name2][0]], axis=2),
                                         np.r_[pr, columns[name2][1]])
                    if cv**2 - both**2 < 0.2 * gain2:
                        ambiguous.append({"effects": [name, name2], "cv_rms": [cv, cv2],
                                          "note": f"{name} and {name2} explain the same part of the gap"})
            selected.append(name)
            extra, extra_prior, current_cv, current_bic = ex, pr, cv, bic

    # how far it shrinks: nonlinear fit with the selected effects
    final = None
    effect_parameters = []
    validation_after = None
    if "violated-constraint" not in selected:
        violated = None
    effects = tuple(make_effect(n, mechanism, analysis, data, **({"only": [violated["defect"]]}
                                                                  if n == "violated-constraint" else {}))
                    for n in selected)
    if effects:
        final = identify(mechanism, analysis, data, validation, effects=effects, kinematics=kin)
        validation_after = final.validation
        for p in final.parameters:
            if p["kind"].startswith("effect:"):
                effect_parameters.append({"effect": p["kind"][7:], **{k: p[k] for k in ("name", "unit", "estimate",
                                                                                           "std", "identifiable")}})
        if violated is not None:
            est = next(p for p in final.parameters if p["name"] == f"violated_{violated['defect']}")
            violated.update({"estimate": est["estimate"], "std": est["std"], "unit": est["unit"],
                             "times_realistic": abs(est["estimate"]) / violated["realistic_magnitude"]})
    before = rigid.validation
    noise = rigid.noise_rms
    share = None
    reference = before["rms"] if before else base_cv
    after_rms = validation_after["rms"] if validation_after else None
    if after_rms is not None and noise is not None and reference**2 > noise**2:
        share = float((reference**2 - after_rms**2) / (reference**2 - noise**2))
    bb = _black_box_ceiling(screen, data)
    ceiling = {"cv_rms_rigid": base_cv, "cv_rms_black_box": bb, "cv_rms_selected": current_cv,
               "method": "ridge quadratic regression of the residuals on joint values and metadata, same folds"}
    if noise is not None and base_cv**2 > noise**2:
        ceiling["share_black_box"] = float((base_cv**2 - bb**2) / (base_cv**2 - noise**2))
        ceiling["share_selected"] = float((base_cv**2 - current_cv**2) / (base_cv**2 - noise**2))
    for entry in ranking:
        entry["validation_rms"] = entry["cv_rms"]  # blocked cross-validation on the identification data
    return Diagnosis(significant, test, where, ranking, selected, ambiguous, not_applicable, before,
                     validation_after, share, ceiling, effect_parameters, violated, rigid, final,
                     time.perf_counter() - t0)


def _name_violated(mech, analysis, kin, rigid, data, screen, base_cv: float) -> dict:
    """The single forced defect whose violation best explains the residuals (blocked CV).

    Each forced defect is tried alone (one parameter, refitted with the geometry).  Those
    that explain at least ``AMBIGUOUS_SHARE`` of the gap the best one explains
    (``base_cv**2 - cv**2``) cannot be told apart by the data; among them the one that needs
    the smallest violation relative to its realistic magnitude (5e-4 rad or 0.05 mm) is
    named, the most probable a priori, and the others are listed in ``ambiguous_with``.
    The runner-ups are returned with their CV RMS and estimate (in the defect's own unit).
    """
    entries = []
    for p in analysis.parameters:
        if p.verdict != "forced":
            continue
        effect = make_effect("violated-constraint", mech, analysis, data, only=[p.name])
        je, pe = _effect_columns(mech, analysis, kin, rigid, data, effect, screen.q)
        if not np.any(je):
            continue
        cv, _, _, estimates = _cv_rms(screen, je, pe)
        estimate = float(estimates[0])
        realistic = float(effect.magnitude[0])
        entries.append({"defect": p.name, "cv_rms": cv, "estimate": estimate, "unit": p.unit,
                        "realistic_magnitude": realistic, "times_realistic": abs(estimate) / realistic})
    entries.sort(key=lambda e: e["cv_rms"])
    best_gain = base_cv**2 - entries[0]["cv_rms"] ** 2
    tied = [e for e in entries if e is entries[0]
            or (best_gain > 0 and base_cv**2 - e["cv_rms"] ** 2 >= AMBIGUOUS_SHARE * best_gain)]
    named = min(tied, key=lambda e: e["times_realistic"])
    rest = [e for e in entries if e is not named]
    how = "cross-validation" if named is entries[0] else "smallest violation among the candidates the data cannot tell apart"
    return {**named, "named_by": how, "alternatives": rest[:3],
            "ambiguous_with": [e["defect"] for e in tied if e is not named]}
