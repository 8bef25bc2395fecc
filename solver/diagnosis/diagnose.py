"""Diagnosis of the sim-to-real gap: is there one, where it lies, which effect causes it, how far it shrinks.

Units: lengths in mm (residuals reported in mm; the text output prints um), angles in rad.

1. **Is there a gap?**  After the rigid identification the weighted residuals follow a
   chi-square law with ``3K - rank`` degrees of freedom when the noise model of the data
   is right and nothing is missing; validation points give a second, independent test.
   "No significant gap" is the answer when neither p-value is below 1e-3 (Bonferroni).
2. **Where?**  Residual RMS per workspace region (k-means blocks of the normalised
   actuated values), per base-frame direction, the share of the residual variance each
   joint variable and metadata column explains (a quadratic fit), and a spectrum of the
   residuals along every actuator: a harmonic regression at each frequency, in cycles
   per revolution for a revolute and per millimetre for a screw, with its F-test
   (:func:`structure_tests`).
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
   (below 10 %) carries its ``absorbed_share``: only the rest of it can be seen.
   **Physical plausibility**: each candidate is fitted within its physical domain
   (bounded least squares, ``scipy.optimize.lsq_linear``: compliance and backlash >= 0,
   a thermal coefficient within the range of structural materials, ...); a candidate
   whose data ask for a value beyond a bound by more than 3 standard deviations (the
   bounded fit then sits at the bound) or beyond a plausible magnitude is rejected, and
   the reason is given.  Effects are added one at a time while they lower the
   cross-validated error by at least 5 % and BIC by at least 10; two effects that
   explain the same part of the gap are reported as ambiguous.
4. **How far it shrinks.**  The selected effects are identified together with the
   geometry by the full nonlinear fit; validation mean / max / RMS before and after, the
   share of the gap explained ``(before^2 - after^2) / (before^2 - noise^2)`` and the
   ceiling a flexible black-box regression of the residuals reaches under the same folds.
   An effect whose nonlinear estimate leaves its domain, or that makes the validation
   error worse, is removed again (never selected), with the reason.
5. **The answer** (``Diagnosis.outcome``), one of :data:`OUTCOMES`, each with its evidence:
   ``no significant gap``; ``explained`` (the gap test repeated after adding the
   effects passes on the identification and the validation points); ``partly explained``
   (a significant gap remains: how much and where); ``unexplained`` (no candidate fits;
   where: the joint variable, the direction, the frequency of the residual);
   ``understated noise`` (the excess has no structure: equal in every direction,
   uncorrelated with the joints and the metadata, a black-box fit explains nothing; the
   noise level that would make the data consistent is given).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.special import chdtrc, fdtrc  # survival functions; scipy.stats costs 1.3 s more to import

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.diagnosis.effects import Effect, applicable_effects, available_effects, make_effect
from hyperstat.solver.errors import DataError
from hyperstat.solver.calibration.identify import IdentificationResult, MeasurementModel, _weights, error_stats, identify
from hyperstat.solver.calibration.measurements import MeasurementSet
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.analysis.stationarity import StationarityResult
from hyperstat.solver.threads import limited_blas

__all__ = ["Diagnosis", "diagnose", "region_blocks", "structure_tests", "describe_where", "format_outcome", "OUTCOMES"]

PRIOR_LENGTH = 0.5  # mm, prior std of a geometric length parameter in the screening refits
PRIOR_ANGLE = 1e-3  # rad
P_THRESHOLD = 1e-3
OUTCOMES = ("no significant gap", "explained", "partly explained", "unexplained", "understated noise")
DOMAIN_SIGMAS = 3.0  # an estimate this many std beyond a bound of its domain rejects the candidate
BLACK_BOX_NOTHING = 0.05  # a black-box regression "explains nothing" below this share of the residual variance


@dataclass
class Diagnosis:
    """Outcome of :func:`diagnose`; ``to_dict`` gives the JSON of ``hyperstat diagnose``.

    ``outcome`` is one of :data:`OUTCOMES`; ``verdict`` holds its evidence (the gap tests
    after the effects, the remaining gap and where it lies, or the noise level that
    would make the data consistent); ``rejected`` lists the candidates refused for
    physical implausibility or for making the validation error worse, with the reason.
    """

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
    outcome: str = "no significant gap"
    verdict: dict = field(default_factory=dict)
    rejected: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready dictionary (units: mm, rad)."""
        return {
            "units": {"length": "mm", "angle": "rad"},
            "outcome": self.outcome,
            "verdict": self.verdict,
            "gap_significant": self.gap_significant,
            "gap_test": self.gap_test,
            "where": self.where,
            "ranking": self.ranking,
            "selected": self.selected,
            "rejected": self.rejected,
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
    cache: dict = field(default_factory=dict)

    def prepared(self) -> dict:
        """Weighted base columns, their QR basis and per-fold Gram matrices (computed once)."""
        if self.cache:
            return self.cache
        k, _, n = self.base_jac.shape
        jw = (self.base_jac * self.w[:, None, None]).reshape(3 * k, n)
        rw = (self.resid * self.w[:, None]).reshape(3 * k)
        folds = []
        for _, labels in self.schemes:
            for g in np.unique(labels):
                test = labels == g
                if test.all():
                    continue
                rows = np.repeat(test, 3)
                folds.append((test, rows, jw[rows].T @ jw[rows], jw[rows].T @ rw[rows]))
        qb, _ = np.linalg.qr(jw / np.linalg.norm(jw, axis=0).clip(min=1e-300))
        self.cache.update(jw=jw, rw=rw, gram=jw.T @ jw, rhs=jw.T @ rw, folds=folds, qb=qb)
        return self.cache


AMBIGUOUS_SHARE = 0.8  # a second candidate explaining this share of what the best explains is reported as ambiguous


def _cv_rms(screen: _Screen, extra: np.ndarray | None,
            extra_prior: np.ndarray | None, with_cov: bool = False):
    """Cross-validated RMS (mm), BIC and rank of the refit with the base columns plus ``extra``,
    and the estimates of the ``extra`` parameters refitted on all the data (and their
    covariance for unit-variance weighted residuals when ``with_cov``).

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
        ew = (extra * screen.w[:, None, None]).reshape(3 * k, -1)
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


def _extra_rank(qb: np.ndarray, ew: np.ndarray) -> int:
    """Number of independent directions the extra columns add to the base columns."""
    norms = np.linalg.norm(ew, axis=0)
    if not np.any(norms > 0):
        return 0
    e = ew[:, norms > 0] / norms[norms > 0]
    rest = e - qb @ (qb.T @ e)
    s = np.linalg.svd(rest, compute_uv=False)
    return int(np.sum(s > 1e-6))


def _absorbed(screen: _Screen, extra: np.ndarray) -> float:
    """Largest fraction of an effect column (weighted, unit norm) that the geometry does not span."""
    k = len(screen.w)
    qb = screen.prepared()["qb"]
    e = (extra * screen.w[:, None, None]).reshape(3 * k, -1)
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


class _UnitActuators(Effect):
    """Helper effect ``dq = theta`` (one parameter per actuator): its columns are ``d position / d q_a``."""

    name = "unit-actuators"

    def __init__(self, n_act: int) -> None:
        super().__init__([f"_dq{a}" for a in range(n_act)], ["-"] * n_act, np.ones(n_act))

    def actuator_correction(self, model, theta, data):
        k = len(data)
        return np.broadcast_to(theta, (k, len(theta))).copy(), np.broadcast_to(np.eye(len(theta)),
                                                                                (k, len(theta), len(theta))).copy()


def _effect_columns(mech, analysis, kin, rigid: IdentificationResult, data, effect,
                    q_start: np.ndarray | None = None, act_jac: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Unweighted Jacobian columns (K, 3, n_e) of ``effect`` at the rigid solution, and their prior std.

    An effect entering through the actuated values alone is ``d position / d q_a`` times
    its ``d dq / d theta`` (``act_jac`` given): no new evaluation of the model.
    """
    prior = 1000.0 * np.maximum(effect.magnitude, 1e-12)
    if act_jac is not None and _only_actuator(effect):
        model = MeasurementModel(mech, analysis, kin)
        theta0 = np.zeros(len(effect.parameter_names(None)))
        _, dt = effect.actuator_correction(model, theta0, data)
        return np.einsum("kia,kae->kie", act_jac, dt), prior
    model = MeasurementModel(mech, analysis, kin, effects=(effect,))
    theta = model.initial()
    theta[: rigid.model.n] = rigid.theta
    pred = model.predict(theta, data, jacobian=True, q_start=q_start)
    sl = model._effect_slices[0]
    return pred.jacobian[:, :, sl], prior


def structure_tests(mech: Mechanism, data: MeasurementSet, resid: np.ndarray, w: np.ndarray, basis: np.ndarray,
                    r_trk: np.ndarray, act_jac: np.ndarray, target_jac: np.ndarray | None = None,
                    candidates: dict | None = None) -> dict:
    """Does the residual field have structure?  F-tests of regressions the fit cannot absorb, and isotropy.

    Three families of regressors, each projected off the fitted columns (``basis``, an
    orthonormal basis of the weighted Jacobian of the fit) before it is tested:

    * **joint errors**: the residual an error of actuator ``j`` would leave,
      ``d position / d q_j`` times ``g(v)``, with ``g`` a linear and quadratic trend in
      every joint value and metadata column ``v`` (a gear ratio error, a coupling between
      two joints, a load-dependent error), or ``sin, cos`` of the joint's own value at each
      frequency of a grid (0.5 to 8 cycles per revolution for a revolute; periods 2 mm to a
      third of the travel for a screw): the spectrum per revolute and per screw;
    * **base-frame trends**: a displacement along x, y, z of the base that follows a joint
      value or a metadata column (linear and quadratic);
    * **tool-frame trends**: a displacement along an axis of the output frame that follows
      a joint value or a metadata column (a tool that grows with the temperature);
    * **candidate signatures**: the columns of each candidate effect (``candidates``), so
      that a residual an effect fits in sample but cannot predict in held-out blocks is
      not taken for noise.

    Each regression has its F-test against the rest of the residual variance
    (scale-free: it holds whatever the true noise level); the family is judged at
    ``1e-3 / number of tests`` (Bonferroni).  Isotropy: Bartlett's test of equal variance
    in the three base-frame directions, each component divided by ``sqrt(1 - leverage)``.

    Parameters
    ----------
    mech : Mechanism
        The model (joint types).
    data : MeasurementSet
        Poses and metadata.
    resid : ndarray, (K, 3)
        Residuals in the tracker frame (mm).
    w : ndarray, (K,)
        Weights 1/sigma (1/mm).
    basis : ndarray, (3K, r)
        Orthonormal basis of the fitted (weighted) columns; ``r`` is the rank used.
    r_trk : ndarray, (3, 3)
        Tracker rotation in the base frame.
    act_jac : ndarray, (K, 3, n_act)
        ``d position / d q_a`` (tracker frame, unweighted).
    target_jac : ndarray, (K, 3, 3), optional
        ``d position / d target offset`` (the output frame's axes in the tracker frame).
    candidates : dict, optional
        Effect name -> its columns (K, 3, n_e) (tracker frame, unweighted).

    Returns
    -------
    dict
        ``tests`` (the 12 most significant: family, variable, joint, frequency or period,
        share, F, p_value, direction), ``best``, ``structured``, ``threshold``,
        ``n_tests``, ``isotropy``, ``isotropic``, ``spectra`` (screws, periods in mm) and
        ``revolute_spectra`` (cycles per revolution).
    """
    k = len(w)
    y = (resid * w[:, None]).reshape(3 * k)
    y = y - basis @ (basis.T @ y)
    total = float(y @ y)
    dof_res = max(3 * k - basis.shape[1], 10)
    tests = []

    fits: dict = {}

    def ftest(cols: np.ndarray) -> tuple[float, float, float, int]:
        x = (cols * w[:, None, None]).reshape(3 * k, -1)
        x = x - basis @ (basis.T @ x)
        norms = np.linalg.norm(x, axis=0)
        keep = norms > 1e-9 * max(float(norms.max()), 1e-300)
        x = x[:, keep] / norms[keep]
        if x.shape[1] == 0 or total <= 0:
            return 0.0, 0.0, 1.0, -1
        gram = x.T @ x
        coef = np.linalg.lstsq(gram, x.T @ y, rcond=1e-10)[0] if x.shape[1] > 1 else (x.T @ y) / gram[0, 0]
        fit = x @ coef
        explained = float(fit @ fit)
        p = x.shape[1]
        d2 = max(dof_res - p, 1)
        f = (explained / p) / max((total - explained) / d2, 1e-300)
        key = len(fits)
        fits[key] = fit
        return explained / total, float(f), float(fdtrc(p, d2, f)), key

    def direction(key: int) -> list:
        """Dominant base-frame direction of a fitted field (first right singular vector)."""
        if key < 0:
            return [0.0, 0.0, 0.0]
        field_base = (fits[key].reshape(k, 3) / w[:, None]) @ r_trk.T
        _, _, vt = np.linalg.svd(field_base, full_matrices=False)
        return (vt[0] * np.sign(vt[0][np.argmax(np.abs(vt[0]))])).tolist()

    def scaled(v: np.ndarray) -> np.ndarray:
        return (v - v.mean()) / max(float(np.std(v)), 1e-300)

    variables = {f"q{j}": data.q[:, a] for a, j in enumerate(data.joints) if np.ptp(data.q[:, a]) > 0}
    variables.update({name: v for name, v in data.metadata.items() if np.ptp(v) > 0})
    trends = {}
    for name, v in variables.items():
        x = scaled(v)
        trends[name] = x[:, None] if len(set(v.tolist())) <= 2 else np.column_stack([x, x**2])
    spectra, rspectra = [], []
    for a, i in enumerate(mech.actuated):
        joint = data.joints[a]
        col = act_jac[:, :, a]
        for name, g in trends.items():
            share, f, p, d = ftest(col[:, :, None] * g[:, None, :])
            tests.append({"family": "joint error", "joint": joint, "variable": name, "kind": "trend", "share": share,
                          "F": f, "p_value": p, "direction": d})
        qv = data.q[:, a]
        if np.ptp(qv) <= 0:
            continue
        revolute = mech.joints[i].type == "R"
        if revolute:
            freqs = np.arange(0.5, 8.01, 0.25)
            phase = np.outer(qv, freqs)  # cycles per revolution: q in rad
        else:
            periods = np.linspace(2.0, max(4.0, np.ptp(qv) / 3.0), 40)
            freqs = 1.0 / periods
            phase = 2.0 * np.pi * np.outer(qv, freqs)
        shares, ps = [], []
        for n, fr in enumerate(freqs):
            g = np.column_stack([np.sin(phase[:, n]), np.cos(phase[:, n])])
            share, f, p, d = ftest(col[:, :, None] * g[:, None, :])
            entry = {"family": "joint error", "joint": joint, "variable": f"q{joint}", "kind": "periodic",
                     "share": share, "F": f, "p_value": p, "direction": d}
            if revolute:
                entry["cycles_per_revolution"] = float(fr)
            else:
                entry["period_mm"] = float(1.0 / fr)
            tests.append(entry)
            shares.append(share)
            ps.append(p)
        best = int(np.argmin(ps))
        if revolute:
            rspectra.append({"joint": joint, "cycles_per_revolution": freqs.tolist(), "share": shares,
                             "peak_cycles_per_revolution": float(freqs[best]), "peak_share": float(shares[best]),
                             "peak_p_value": float(ps[best])})
        else:
            spectra.append({"joint": joint, "peak_period_mm": float(1.0 / freqs[best]),
                            "peak_share": float(shares[best]), "peak_p_value": float(ps[best]),
                            "periods_mm": (1.0 / freqs).tolist(), "power": shares,
                            "method": "share of the residual variance a periodic error of this joint explains"})
    frames = [("base frame", np.broadcast_to(r_trk.T, (k, 3, 3)))]
    if target_jac is not None:
        frames.append(("tool frame", target_jac))
    for family, axes in frames:
        for name, g in trends.items():
            cols = np.concatenate([axes[:, :, c, None] * g[:, None, :] for c in range(3)], axis=2)
            share, f, p, d = ftest(cols)
            tests.append({"family": f"{family} trend", "variable": name, "kind": "trend", "share": share, "F": f,
                          "p_value": p, "direction": d})
    for name, cols in (candidates or {}).items():
        share, f, p, d = ftest(cols)
        tests.append({"family": "candidate signature", "variable": name, "kind": "effect", "share": share, "F": f,
                      "p_value": p, "direction": d})
    threshold = P_THRESHOLD / max(len(tests), 1)
    n_tests = len(tests)
    tests.sort(key=lambda t: t["p_value"])
    tests = tests[:12]
    for t in tests:
        t["direction"] = direction(t["direction"])
    # isotropy (Bartlett), leverage-corrected components, base-frame directions
    lev = np.sum(basis**2, axis=1).reshape(k, 3) @ (r_trk.T**2)
    z = ((resid * w[:, None]) @ r_trk.T) / np.sqrt(1.0 - np.clip(lev, 0.0, 0.95))
    s2 = np.sum(z**2, axis=0) / k
    pooled = float(np.mean(s2))
    stat = (3 * k * np.log(pooled) - float(np.sum(k * np.log(s2)))) / (1.0 + (3.0 / k - 1.0 / (3 * k)) / 6.0)
    iso = {"statistic": float(stat), "p_value": float(chdtrc(2, stat)),
           "weighted_variance": dict(zip("xyz", map(float, s2))), "threshold": P_THRESHOLD}
    return {"tests": tests, "n_tests": n_tests, "threshold": threshold,
            "best": tests[0] if tests else None,
            "structured": bool(tests and tests[0]["p_value"] < threshold),
            "isotropy": iso, "isotropic": bool(iso["p_value"] >= P_THRESHOLD),
            "spectra": spectra, "revolute_spectra": rspectra}


def describe_where(test: dict | None) -> str:
    """One sentence for a structure test: joint, variable, frequency, direction (base frame)."""
    if test is None:
        return "nowhere in particular"
    d = np.asarray(test["direction"])
    axis = "xyz"[int(np.argmax(np.abs(d)))]
    direction = f"mostly along {axis} of the base frame ({', '.join(f'{v:+.2f}' for v in d)})"
    var = test["variable"]
    follows = f"joint {var[1:]}" if var.startswith("q") else f"the metadata column '{var}'"
    if test["family"] == "candidate signature":
        what = f"the signature of the candidate '{var}' (its columns, fitted in sample)"
    elif test["family"] == "joint error":
        if test["kind"] == "periodic" and "cycles_per_revolution" in test:
            c = test["cycles_per_revolution"]
            what = f"an error of joint {test['joint']} at {c:g} cycle{'s' if c != 1 else ''} per revolution of joint {test['joint']}"
        elif test["kind"] == "periodic":
            what = f"an error of joint {test['joint']} with a period of {test['period_mm']:.1f} mm along its travel"
        else:
            what = f"an error of joint {test['joint']} that follows {follows}"
    else:
        what = f"a displacement along an axis of the {test['family'].split(' trend')[0]} that follows {follows}"
    return (f"{what}, {direction}: {100 * test['share']:.0f} % of the residual variance "
            f"(F-test p = {test['p_value']:.2g})")


def _where(mech: Mechanism, rigid: IdentificationResult, data: MeasurementSet, labels: np.ndarray,
           structure: dict) -> dict:
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
    return {"regions": regions, "direction_rms": direction, "explained_by": explained,
            "spectra": structure["spectra"], "revolute_spectra": structure["revolute_spectra"],
            "structure": {k: structure[k] for k in ("tests", "n_tests", "threshold", "best", "structured",
                                                     "isotropy", "isotropic")}}


def _black_box_ceiling(screen: _Screen, data: MeasurementSet, schemes: list | None = None) -> float:
    """CV RMS of the rigid residuals after a ridge regression on joints (quadratic) and metadata (mm)."""
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
    for _, labels in (screen.schemes if schemes is None else schemes):
        for g in np.unique(labels):
            test = labels == g
            if test.all():
                continue
            a = f[~test]
            evals, evecs = np.linalg.eigh(a.T @ a)
            proj = evecs.T @ (a.T @ screen.resid[~test])
            for n, lam in enumerate(lams):
                coef = evecs @ (proj / (evals + lam)[:, None])
                sq[n] += float(np.sum((screen.resid[test] - f[test] @ coef) ** 2))
            count += int(test.sum())
    return float(np.sqrt(sq.min() / max(count, 1)))


def _gap_after(result: IdentificationResult, data: MeasurementSet, validation: MeasurementSet | None) -> dict:
    """The gap test of step 1 on a fit's identification residuals and, if given, its validation residuals."""
    w = _weights(data)
    chi_id = float(np.sum((result.residuals * w[:, None]) ** 2))
    dof = 3 * len(data) - result.rank
    test = {"identification": {"chi2": chi_id, "dof": dof, "p_value": float(chdtrc(dof, chi_id)),
                               "noise_factor": float(np.sqrt(chi_id / dof))}}
    if validation is not None and len(validation) and result.validation_residuals is not None:
        wv = _weights(validation)
        chi_v = float(np.sum((result.validation_residuals * wv[:, None]) ** 2))
        scale = 1.0 + result.rank / (3.0 * len(data))
        dof_v = 3 * len(validation)
        test["validation"] = {"chi2": chi_v, "dof": dof_v, "p_value": float(chdtrc(dof_v, chi_v / scale)),
                              "variance_inflation": scale, "noise_factor": float(np.sqrt(chi_v / scale / dof_v))}
    test["threshold"] = P_THRESHOLD / (len(test))
    test["significant"] = bool(min(v["p_value"] for k, v in test.items() if isinstance(v, dict)) < test["threshold"])
    return test


def _plausibility(effect: Effect, estimate: np.ndarray, std: np.ndarray) -> str | None:
    """Why an estimate is physically implausible (None when it is plausible)."""
    names = effect.parameter_names(None)
    units = effect.parameter_units(None)
    for j, (e, s) in enumerate(zip(estimate, std)):
        s = float(s) if np.isfinite(s) else 0.0
        for bound, side in ((effect.lower[j], -1.0), (effect.upper[j], 1.0)):
            if np.isfinite(bound) and side * (e - bound) > DOMAIN_SIGMAS * s:
                sig = side * (e - bound) / s if s > 0 else np.inf
                return (f"the data ask for {names[j]} = {e:.3g} {units[j]}, {sig:.0f} std "
                        f"{'below' if side < 0 else 'above'} its physical bound {bound:g} "
                        f"({effect.domain_note}); fitted within its domain it sits at the bound")
        if abs(e) - DOMAIN_SIGMAS * s > effect.plausible[j]:
            return (f"{names[j]} = {e:.3g} {units[j]} is {abs(e) / effect.magnitude[j]:.0f}x its realistic magnitude "
                    f"{effect.magnitude[j]:g}, beyond the plausible {effect.plausible[j]:g} ({effect.domain_note})")
    return None


def _bounded_fit(screen: _Screen, jac_e: np.ndarray, prior_e: np.ndarray, effect: Effect) -> np.ndarray:
    """Effect estimates refitted with the geometry within the effect's domain (``lsq_linear``, ridge rows)."""
    from scipy.optimize import lsq_linear

    pre = screen.prepared()
    k = len(screen.w)
    ew = (jac_e * screen.w[:, None, None]).reshape(3 * k, -1)
    prior = np.r_[screen.base_prior, prior_e]
    a = np.vstack([np.concatenate([pre["jw"], ew], axis=1), np.diag(1.0 / prior)])
    b = np.r_[-pre["rw"], np.zeros(len(prior))]
    nb = pre["jw"].shape[1]
    lo = np.r_[np.full(nb, -np.inf), effect.lower]
    hi = np.r_[np.full(nb, np.inf), effect.upper]
    return lsq_linear(a, b, bounds=(lo, hi), method="bvls").x[nb:]


# ---------------------------------------------------------------------------- main entry
@limited_blas
def diagnose(
    mechanism: Mechanism,
    analysis: StationarityResult,
    data: MeasurementSet,
    validation: MeasurementSet | None = None,
    candidates: tuple | None = None,
    kinematics: Kinematics | None = None,
    n_blocks: int = 4,
    seed: int = 0,
    max_effects: int = 3,
    progress=None,
) -> Diagnosis:
    """Diagnose the gap left by the rigid model (see the module docstring for the method).

    Parameters
    ----------
    mechanism, analysis : Mechanism, StationarityResult
        Nominal model and its stationarity analysis.
    data : MeasurementSet
        Identification measurements; its noise model is needed for the gap test.
    validation : MeasurementSet, optional
        Held-out points for the before / after numbers and the gap test after the
        effects (never used to choose among candidates, only to refuse one that makes
        them worse).
    candidates : tuple of str, optional
        Effect names to consider (default: the library and the plug-ins of the
        ``hyperstat.effects`` entry-point group).
    n_blocks : int
        Workspace regions of the blocked cross-validation.
    max_effects : int
        Most effects added.
    progress : callable, optional
        Called with a short stage name as the diagnosis advances (a progress bar).

    Returns
    -------
    Diagnosis

    Raises
    ------
    DataError
        If the data state no noise model (the gap test needs one) or name an unknown effect.
    """
    return _diagnose(mechanism, analysis, data, validation, candidates, kinematics, n_blocks, seed, max_effects,
                         progress)


def _diagnose(mechanism, analysis, data, validation, candidates, kinematics, n_blocks, seed, max_effects,
              progress) -> Diagnosis:
    """Body of :func:`diagnose` (BLAS single-threaded by the caller)."""
    t0 = time.perf_counter()
    step = progress or (lambda _name: None)
    if data.noise is None:
        raise DataError(f"{data.source}: the diagnosis needs the header line '# noise: A mm + B mm/m' (the tracker's "
                        f"noise model) to tell a gap from noise.")
    known = available_effects()
    candidates = known if candidates is None else tuple(candidates)
    for c in candidates:
        if c not in known:
            raise DataError(f"unknown effect '{c}'; effects are {', '.join(known)}.")
    kin = kinematics or Kinematics(mechanism)
    step("rigid fit")
    rigid = identify(mechanism, analysis, data, validation, kinematics=kin)
    w = _weights(data)
    test = _gap_after(rigid, data, validation)
    significant = test.pop("significant")

    step("where")
    schemes = _folds(data, n_blocks, seed)
    base_idx = [rigid.model.names.index(b) for b in rigid.base]
    full = rigid.model.predict(rigid.theta, data, jacobian=True, q_start=rigid.configurations)
    units = rigid.model.units
    kinds = rigid.model.kinds
    prior = np.array([(PRIOR_ANGLE if units[j] == "rad" else PRIOR_LENGTH) if kinds[j] == "geometry" else 1e3
                      for j in base_idx])
    screen = _Screen(w, rigid.residuals, full.jacobian[:, :, base_idx], prior, schemes, full.q)
    r_trk, _ = rigid.model.tracker_pose(rigid.theta)
    n_act = data.q.shape[1]
    unit_model = MeasurementModel(mechanism, analysis, kin, effects=(_UnitActuators(n_act),))
    theta_u = unit_model.initial()
    theta_u[: rigid.model.n] = rigid.theta
    act_jac = unit_model.predict(theta_u, data, jacobian=True, q_start=screen.q).jacobian[:, :, rigid.model.n:]
    target_jac = full.jacobian[:, :, rigid.model.sl_target]
    base_cv, base_bic, _, _ = _cv_rms(screen, None, None)

    step("candidates")
    violated = None
    not_applicable = {k: v for k, v in applicable_effects(mechanism, analysis, data).items() if k in candidates}
    columns = {}
    ranking, rejected = [], []
    for name in candidates:
        if name in not_applicable:
            continue
        if name == "violated-constraint":
            # one forced defect at a time: the best explains the gap with one parameter and is named
            violated = _name_violated(mechanism, analysis, kin, rigid, data, screen, base_cv)
            if violated is None:
                not_applicable[name] = "no forced defect moves the measured point"
                continue
            effect = make_effect(name, mechanism, analysis, data, only=[violated["defect"]])
        else:
            effect = make_effect(name, mechanism, analysis, data)
        if not effect.parameter_names(None):
            not_applicable[name] = "no parameter applies to this mechanism and data"
            continue
        jac_e, prior_e = _effect_columns(mechanism, analysis, kin, rigid, data, effect, screen.q, act_jac)
        free = _absorbed(screen, jac_e)
        cv, bic, _, est, cov, chi = _cv_rms(screen, jac_e, prior_e, with_cov=True)
        columns[name] = (jac_e, prior_e)
        dof = max(3 * len(data) - rigid.rank - len(prior_e), 1)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None) * max(1.0, chi / dof))
        entry = {"effect": name, "cv_rms": cv, "criterion": bic - base_bic, "criterion_name": "delta BIC",
                 "parameters": len(prior_e), "unexplained_by_geometry": free,
                 "estimates": dict(zip(effect.parameter_names(None), map(float, est))),
                 "std": dict(zip(effect.parameter_names(None), map(float, std)))}
        if name == "violated-constraint":
            entry["defect"] = violated["defect"]
        if free < 1e-3:
            entry["note"] = "absorbed by the geometric parameters: not identifiable against them"
        elif free < 0.1:
            entry["absorbed_share"] = 1.0 - free
        why = _plausibility(effect, est, std) if free >= 1e-3 else None
        if why is not None:
            entry["rejected"] = why
            bounded = _bounded_fit(screen, jac_e, prior_e, effect)
            entry["bounded_estimates"] = dict(zip(effect.parameter_names(None), map(float, bounded)))
            rejected.append({"effect": name, "stage": "screening", "reason": why})
        ranking.append(entry)
    ranking.sort(key=lambda e: (e.get("note") is not None, e["cv_rms"]))

    signatures = {e["effect"]: columns[e["effect"]][0] for e in ranking if not e.get("note")}
    structure = structure_tests(mechanism, data, rigid.residuals, w, screen.prepared()["qb"], r_trk, act_jac,
                                target_jac, signatures)
    where = _where(mechanism, rigid, data, schemes[0][1], structure)
    # the structure tests are a second, scale-free gap test: under a right model they hold at
    # 1e-3 whatever the noise, so a structured residual is a gap even below the chi-square's power
    test["structure"] = {"p_value": structure["best"]["p_value"] if structure["best"] else 1.0,
                         "threshold": structure["threshold"], "tests": structure["n_tests"]}
    if structure["structured"] and not significant:
        significant = True
        test["significant_by"] = "structure"

    step("selection")
    selected: list[str] = []
    ambiguous: list = []
    current_cv, current_bic = base_cv, base_bic
    extra, extra_prior = None, None
    if significant:
        for _ in range(max_effects):
            trials = []
            for entry in ranking:
                name = entry["effect"]
                if name in selected or entry.get("note") or entry.get("rejected"):
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

    # how far it shrinks: nonlinear fit with the selected effects; an effect that leaves its
    # domain there, or that makes the validation error worse, is removed again
    step("nonlinear fit")
    before = rigid.validation
    final = None
    while selected:
        effects = tuple(make_effect(n, mechanism, analysis, data, **({"only": [violated["defect"]]}
                                                                      if n == "violated-constraint" else {}))
                        for n in selected)
        final = identify(mechanism, analysis, data, validation, effects=effects, kinematics=kin)
        dropped = None
        for eff, sl in zip(final.model.effects, final.model._effect_slices):
            est = final.theta[sl]
            std = np.array([p["std"] if p["std"] is not None else np.inf for p in final.parameters[sl]])
            why = _plausibility(eff, est, std)
            if why is not None:
                dropped = (eff.name, "nonlinear fit", why)
                break
        if dropped is None and before is not None and final.validation is not None \
                and final.validation["rms"] > before["rms"]:
            dropped = (selected[-1], "validation",
                       f"adding it made the validation error worse (RMS {1000 * before['rms']:.1f} -> "
                       f"{1000 * final.validation['rms']:.1f} um)")
        if dropped is None:
            break
        rejected.append({"effect": dropped[0], "stage": dropped[1], "reason": dropped[2]})
        selected.remove(dropped[0])
        for entry in ranking:
            if entry["effect"] == dropped[0]:
                entry["rejected"] = dropped[2]
        final = None
    if selected:
        extra = np.concatenate([columns[n][0] for n in selected], axis=2)
        current_cv, current_bic, _, _ = _cv_rms(screen, extra, np.concatenate([columns[n][1] for n in selected]))
    else:
        current_cv, current_bic = base_cv, base_bic
    effect_parameters = []
    validation_after = None
    if "violated-constraint" not in selected:
        violated = None
    if final is not None:
        validation_after = final.validation
        for p in final.parameters:
            if p["kind"].startswith("effect:"):
                effect_parameters.append({"effect": p["kind"][7:], **{k: p[k] for k in ("name", "unit", "estimate",
                                                                                           "std", "identifiable")}})
        if violated is not None:
            est = next(p for p in final.parameters if p["name"] == f"violated_{violated['defect']}")
            violated.update({"estimate": est["estimate"], "std": est["std"], "unit": est["unit"],
                             "times_realistic": abs(est["estimate"]) / violated["realistic_magnitude"]})
    noise = rigid.noise_rms
    share = None
    reference = before["rms"] if before else base_cv
    after_rms = validation_after["rms"] if validation_after else None
    if after_rms is not None and noise is not None and reference**2 > noise**2:
        share = float((reference**2 - after_rms**2) / (reference**2 - noise**2))
    bb = _black_box_ceiling(screen, data)
    rms_resid = float(np.sqrt(np.mean(np.sum(rigid.residuals**2, axis=1))))
    random_folds = [("random", np.random.default_rng(seed).permutation(len(data)) % 5)]
    bb_random = _black_box_ceiling(screen, data, random_folds)
    ceiling = {"cv_rms_rigid": base_cv, "cv_rms_black_box": bb, "cv_rms_selected": current_cv,
               "method": "ridge quadratic regression of the residuals on joint values and metadata, same folds",
               "black_box_share_of_residual": float(1.0 - bb_random**2 / rms_resid**2) if rms_resid > 0 else 0.0,
               "black_box_share_method": "the same regression under 5 random folds (interpolation), share of the "
                                         "rigid residual variance"}
    if noise is not None and base_cv**2 > noise**2:
        ceiling["share_black_box"] = float((base_cv**2 - bb**2) / (base_cv**2 - noise**2))
        ceiling["share_selected"] = float((base_cv**2 - current_cv**2) / (base_cv**2 - noise**2))
    for entry in ranking:
        entry["validation_rms"] = entry["cv_rms"]  # blocked cross-validation on the identification data
    step("verdict")
    equivalent = _equivalence(mechanism, analysis, kin, rigid, data, screen, selected, columns, act_jac) \
        if final is not None else []
    after_structure = None
    if final is not None:
        pre = screen.prepared()
        k = len(w)
        ew = (np.concatenate([columns[n][0] for n in selected], axis=2) * w[:, None, None]).reshape(3 * k, -1)
        both = np.concatenate([pre["jw"], ew], axis=1)
        basis, _ = np.linalg.qr(both / np.linalg.norm(both, axis=0).clip(min=1e-300))
        r_f, _ = final.model.tracker_pose(final.theta)
        others = {e["effect"]: columns[e["effect"]][0] for e in ranking
                  if not e.get("note") and e["effect"] not in selected}
        after_structure = structure_tests(mechanism, data, final.residuals, w, basis, r_f, act_jac, target_jac,
                                          others)
    outcome, verdict = _verdict(data, validation, significant, test, final, selected, structure, after_structure,
                                ceiling, noise, share, equivalent)
    return Diagnosis(significant, test, where, ranking, selected, ambiguous, not_applicable, before,
                     validation_after, share, ceiling, effect_parameters, violated, rigid, final,
                     time.perf_counter() - t0, outcome, verdict, rejected)


def _noise_statement(data: MeasurementSet, factor: float) -> dict:
    """The noise model that would make the residuals consistent: the header's times ``factor``."""
    a, b = data.noise.a, data.noise.b
    return {"factor": factor, "a_mm": factor * a, "b_mm_per_m": factor * b,
            "text": f"{factor * a:.3g} mm + {factor * b:.3g} mm/m ({factor:.2f}x the header's {data.noise.text()})"}


EQUIVALENT_BIC = 10.0  # two models whose chi-square differ by less than this cannot be told apart (Kass-Raftery 'strong')


def _equivalence(mech, analysis, kin, rigid, data, screen: _Screen, selected: list, columns: dict,
                 act_jac: np.ndarray) -> list:
    """Physically different models that fit the data as well as the selected effects (equivalence check).

    For each selected effect with an alternative hypothesis (compliance: link bending,
    :class:`~hyperstat.solver.diagnosis.effects.actuator.LinkBendingAlternative`), the
    alternative's columns replace the effect's and the linearised fit with the geometry is
    redone.  The two have as many parameters, so ``delta BIC`` is the difference of their
    weighted chi-squares: below :data:`EQUIVALENT_BIC` (or the alternative better) the data
    cannot tell them apart, and the answer must not be "explained by" the effect.
    """
    from hyperstat.solver.diagnosis.effects.actuator import LinkBendingAlternative

    out = []
    for name in selected:
        if name != "compliance":
            continue
        alt = LinkBendingAlternative(mech, kin)
        if not alt.pairs:
            continue
        jac_alt, prior_alt = _effect_columns(mech, analysis, kin, rigid, data, alt, screen.q, act_jac)
        size = np.linalg.norm(jac_alt, axis=(0, 1))
        bending = [a for a in alt.pairs if size[a] > 1e-6 * max(float(size.max()), 1e-300)]
        if not bending:  # no gravity moment at the root of any such link (joints about the vertical)
            continue
        others = [n for n in selected if n != name]
        mine = np.concatenate([columns[n][0] for n in selected], axis=2)
        mine_prior = np.concatenate([columns[n][1] for n in selected])
        theirs = np.concatenate([columns[n][0] for n in others] + [jac_alt], axis=2)
        theirs_prior = np.concatenate([columns[n][1] for n in others] + [prior_alt])
        cv_x, bic_x, _, _ = _cv_rms(screen, mine, mine_prior)
        cv_a, bic_a, _, est_a = _cv_rms(screen, theirs, theirs_prior)
        delta = float(bic_a - bic_x)
        if delta < EQUIVALENT_BIC:
            names = alt.parameter_names(None)
            joints = ", ".join(mech.joints[mech.actuated[a]].name for a in bending)
            plural = "s" if len(bending) > 1 else ""
            how = ("fits the data better than" if delta <= -EQUIVALENT_BIC else "fits the data as well as")
            out.append({"effect": name, "alternative": "link bending", "delta_bic": delta,
                        "cv_rms": {name: cv_x, "link bending": cv_a},
                        "alternative_parameters": [names[a] for a in bending],
                        "alternative_estimates": {names[a]: float(est_a[a]) for a in bending},
                        "note": (f"link bending under the same gravity loads {how} {name} (delta BIC "
                                 f"{delta:+.1f}, not above {EQUIVALENT_BIC:g}; cross-validated RMS {1000 * cv_a:.1f} "
                                 f"against {1000 * cv_x:.1f} um): the data cannot tell joint stiffness from the "
                                 f"bending of the link{plural} after joint{plural} {joints}; loads at several lever "
                                 f"arms (a payload on a long and on a short tool) would separate them")})
    return out


def _verdict(data, validation, significant, test, final, selected, structure, rest, ceiling, noise,
             share, equivalent=()) -> tuple[str, dict]:
    """The honest answer among :data:`OUTCOMES` and its evidence."""
    if not significant:
        return "no significant gap", {"evidence": "the gap test passes: identification p = "
                                      f"{test['identification']['p_value']:.2g}"
                                      + (f", validation p = {test['validation']['p_value']:.2g}"
                                         if "validation" in test else "")
                                      + f" (threshold {test['threshold']:.1g}); no structure in the residuals "
                                      f"(smallest of {test['structure']['tests']} F-test p-values "
                                      f"{test['structure']['p_value']:.2g}, threshold "
                                      f"{test['structure']['threshold']:.1g})"}
    if selected and final is not None:
        after = _gap_after(final, data, validation)
        verdict = {"effects": list(selected), "gap_test_after": after, "share_explained": share}
        val = final.validation
        if equivalent:
            verdict["indistinguishable"] = list(equivalent)
        if not after["significant"] and not rest["structured"] and not equivalent:
            verdict["evidence"] = (f"after adding {' + '.join(selected)} the gap test passes: "
                                   + ", ".join(f"{k} p = {after[k]['p_value']:.2g}" for k in ("identification",
                                                                                              "validation")
                                               if k in after) + f" (threshold {after['threshold']:.1g}), and no "
                                   f"structure is left in the residuals (smallest of {rest['n_tests']} F-test "
                                   f"p-values {rest['best']['p_value']:.2g}, threshold {rest['threshold']:.1g})")
            notes = [f"{e.name} stands for {e.also_explains}" for e in final.model.effects if e.also_explains]
            if notes:
                verdict["same_signature"] = notes
                verdict["evidence"] += "; " + "; ".join(notes)
            return "explained", verdict
        remaining = None
        if val is not None and noise is not None:
            remaining = float(np.sqrt(max(val["rms"] ** 2 - noise**2, 0.0)))
        verdict["remaining_rms_above_noise"] = remaining
        verdict["where"] = describe_where(rest["best"]) if rest["structured"] else None
        verdict["remaining_structure"] = {k: rest[k] for k in ("best", "structured", "isotropy", "isotropic",
                                                               "threshold", "n_tests")}
        factor = max(v["noise_factor"] for k, v in after.items() if isinstance(v, dict))
        gap_left = after["significant"] or rest["structured"]
        verdict["evidence"] = ((f"a gap remains after adding {' + '.join(selected)}: " if gap_left else
                                f"after adding {' + '.join(selected)} the gap test passes, but what is at work is "
                                f"not established: ")
                               + ("; ".join(e["note"] for e in equivalent) + "; gap test after: " if equivalent
                                  else "")
                               + ", ".join(f"{k} p = {after[k]['p_value']:.2g}" for k in ("identification",
                                                                                          "validation") if k in after)
                               + (f"; validation RMS {1000 * val['rms']:.1f} um against a noise RMS "
                                  f"{1000 * noise:.1f} um ({1000 * remaining:.1f} um above it in quadrature)"
                                  if remaining is not None else ""))
        if equivalent and not gap_left:
            joints = [p[len("link_bending_"):] for e in equivalent for p in e["alternative_parameters"]]
            verdict["where"] = (f"joint {' and '.join(joints)} under gravity: the stiffness of the joint or the bending "
                                f"of the link after it, which the data cannot tell apart")
        if rest["structured"]:
            verdict["evidence"] += "; what remains follows " + verdict["where"]
        elif rest["isotropic"] and gap_left:
            verdict["evidence"] += ("; what remains has no structure (no joint, frequency or metadata trend, equal "
                                    "in every direction): consistent with a noise model of "
                                    + _noise_statement(data, factor)["text"])
            verdict["noise_consistent"] = _noise_statement(data, factor)
        return "partly explained", verdict
    # nothing selected: structure or noise?
    factor = test["identification"]["noise_factor"]  # 3K - rank degrees of freedom: the sharper estimate
    bb_share = ceiling["black_box_share_of_residual"]
    verdict = {"structure": {k: structure[k] for k in ("best", "structured", "isotropy", "isotropic", "threshold",
                                                       "n_tests")},
               "black_box_share": bb_share}
    if not structure["structured"] and structure["isotropic"] and bb_share < BLACK_BOX_NOTHING:
        verdict["noise_consistent"] = _noise_statement(data, factor)
        if "validation" in test:
            verdict["noise_consistent"]["factor_validation"] = test["validation"]["noise_factor"]
        verdict["evidence"] = (f"the excess (noise factor {factor:.2f}) has no structure: no F-test of "
                               f"{structure['n_tests']} (joint errors following any joint or metadata column, "
                               f"harmonics per revolution and per screw period, base- and tool-frame trends) below {structure['threshold']:.1g}, equal variance in x, y, z "
                               f"(Bartlett p = {structure['isotropy']['p_value']:.2g}), a black-box regression on joints and "
                               f"metadata explains {100 * max(bb_share, 0.0):.0f} % of the residual variance under "
                               f"cross-validation. A noise of "
                               f"{verdict['noise_consistent']['text']} would make the data consistent.")
        return "understated noise", verdict
    if structure["structured"]:
        verdict["where"] = describe_where(structure["best"])
    elif not structure["isotropic"]:
        s2 = structure["isotropy"]["weighted_variance"]
        axis = max(s2, key=s2.get)
        verdict["where"] = (f"mostly along {axis} of the base frame (weighted variance "
                            + ", ".join(f"{k} {v:.2f}" for k, v in s2.items())
                            + f", Bartlett p = {structure['isotropy']['p_value']:.2g})")
    else:
        verdict["where"] = (f"no single joint, frequency or direction; a black-box regression on joints and "
                            f"metadata explains {100 * bb_share:.0f} % of the residual variance under cross-validation")
    verdict["evidence"] = ("no candidate effect fits (none lowers the cross-validated error by 5 % within its "
                           "physical domain); the residual follows " + verdict["where"])
    best = structure["best"]
    if structure["structured"] and best["family"] == "candidate signature":
        verdict["evidence"] += (f"; '{best['variable']}' fits it in sample but was not added: it does not predict "
                                f"held-out blocks of the cross-validation, or its estimate is implausible (see rejected)")
    return "unexplained", verdict


def format_outcome(diag: Diagnosis) -> str:
    """The answer in words, with its evidence and the rejected candidates (text output of ``diagnose``)."""
    lines = []
    st = diag.where.get("structure")
    if st:
        lines += ["", f"Structure of the rigid residuals ({st['n_tests']} F-tests, threshold {st['threshold']:.1g}; "
                      f"isotropy: Bartlett p = {st['isotropy']['p_value']:.2g})"]
        lines += [f"  {describe_where(t)}" for t in st["tests"][:3]]
        for sp in diag.where.get("revolute_spectra", []):
            lines.append(f"  spectrum of joint {sp['joint']}'s error: peak at {sp['peak_cycles_per_revolution']:g} "
                         f"cycles per revolution ({100 * sp['peak_share']:.0f} % of the residual variance, "
                         f"p = {sp['peak_p_value']:.2g})")
    lines += ["", "The answer"]
    o = diag.outcome
    v = diag.verdict
    if o == "no significant gap":
        lines.append("  no significant gap: " + v["evidence"])
    elif o == "explained":
        lines.append(f"  explained by {' + '.join(v['effects'])}: " + v["evidence"])
    elif o == "partly explained":
        lines.append(f"  partly explained by {' + '.join(v['effects'])}: " + v["evidence"])
    elif o == "unexplained":
        lines.append("  unexplained: " + v["evidence"])
    else:
        lines.append("  consistent with an understated noise model: " + v["evidence"])
    for r in diag.rejected:
        lines.append(f"  rejected {r['effect']} ({r['stage']}): {r['reason']}")
    return "\n".join(lines) + "\n"


def _name_violated(mech, analysis, kin, rigid, data, screen, base_cv: float) -> dict | None:
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
    jac_all, prior_all = _effect_columns(mech, analysis, kin, rigid, data, effect, screen.q)
    units = {p.name: p.unit for p in mech.parameters}
    entries = []
    for e, name in enumerate(effect.defects):
        je = jac_all[:, :, e:e + 1]
        if not np.any(je):
            continue
        cv, _, _, estimates = _cv_rms(screen, je, prior_all[e:e + 1])
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
