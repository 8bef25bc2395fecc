"""Identification (calibration) of the free geometric parameters from tracker measurements.

Units: lengths in mm, angles in rad.

The measurement model (paper 1, section 5, eq. 10): the target fixed to the output
frame is seen by a tracker at ``p = R_trk^T (T_out(q, xi) p_target - t_trk)``, where
``T_out`` is the forward model with the passive joints assembled (the geometric model
of eq. 2 closed as in eqs. 7, 9).  The unknowns are

* the admissible influential defects of the stationarity analysis, as independent
  coordinates (coupled defects follow their relations),
* the tracker frame (rotation vector and origin in the base frame, 6),
* the target offset in the output frame (3),
* and the parameters of any unmodelled effect added to the model (see
  :mod:`hyperstat.solver.diagnosis.effects`).

The Jacobian is analytic: defect and joint screws give the output twist with the
passive joints following by the implicit function theorem,
``K = O_xi - O_p B_s^+ A_s`` (``A_s, B_s`` of eq. 3).  The identifiable (base)
parameters come from a QR factorisation with column pivoting of the column-scaled
Jacobian; the others are fixed at zero and reported with the combination in which
they are seen.  The fit is Levenberg-Marquardt (``scipy.optimize.least_squares``),
weighted by the tracker noise model when the data state it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics, batched_lstsq
from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.frames import so3_exp, so3_left_jacobian, so3_log, skew
from hyperstat.solver.calibration.measurements import MeasurementSet
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.analysis.stationarity import StationarityResult

__all__ = ["MeasurementModel", "Prediction", "IdentificationResult", "identify", "error_stats", "kabsch",
           "observability_indices"]

TRACKER_NAMES = ["tracker_rx", "tracker_ry", "tracker_rz", "tracker_x", "tracker_y", "tracker_z"]
TARGET_NAMES = ["target_x", "target_y", "target_z"]


@dataclass
class Prediction:
    """Model output at a set of poses.

    Attributes
    ----------
    position : ndarray, (K, 3)
        Predicted target positions in the tracker frame (mm).
    jacobian : ndarray, (K, 3, n_params) or None
        ``d position / d theta``.
    q : ndarray, (K, n_q)
        Assembled configurations.
    converged : ndarray of bool, (K,)
        Whether the assembly closed.
    world : ndarray, (K, 3)
        Target positions in the base frame (mm).
    """

    position: np.ndarray
    jacobian: np.ndarray | None
    q: np.ndarray
    converged: np.ndarray
    world: np.ndarray


class MeasurementModel:
    """Tracker measurements of a target on the output frame, as a function of parameters.

    Parameters
    ----------
    mechanism : Mechanism
        Nominal model.
    analysis : StationarityResult
        Its stationarity analysis (gives the admissible influential defects).
    kinematics : Kinematics, optional
        Reuse a forward model.
    effects : sequence, optional
        Unmodelled-effect models (:mod:`hyperstat.solver.diagnosis.effects`) added to the geometry.
    geometry : {"influential", "full"}
        ``"influential"``: the independent admissible influential defects (identification
        unknowns); ``"full"``: every defect parameter of the model (a virtual machine's truth).
    """

    def __init__(self, mechanism: Mechanism, analysis: StationarityResult, kinematics: Kinematics | None = None,
                 effects: tuple = (), geometry: str = "influential") -> None:
        self.mechanism = mechanism
        self.analysis = analysis
        self.kin = kinematics or Kinematics(mechanism)
        if geometry == "full":
            self.geometry_names = [p.name for p in mechanism.parameters]
            self.geometry_matrix = np.eye(len(self.geometry_names))
        else:
            self.geometry_names, self.geometry_matrix = analysis.parameterization(mechanism, influential_only=True)
        units = {p.name: p.unit for p in mechanism.parameters}
        self.effects = tuple(effects)
        self.names = list(self.geometry_names) + TRACKER_NAMES + TARGET_NAMES
        self.units = [units[n] for n in self.geometry_names] + ["rad"] * 3 + ["mm"] * 6
        self.kinds = ["geometry"] * len(self.geometry_names) + ["tracker"] * 6 + ["target"] * 3
        self._effect_slices = []
        for eff in self.effects:
            start = len(self.names)
            self.names += eff.parameter_names(self)
            self.units += eff.parameter_units(self)
            self.kinds += [f"effect:{eff.name}"] * (len(self.names) - start)
            self._effect_slices.append(slice(start, len(self.names)))
        self._effect_defects = []  # (slice, (n_xi, n_e) defect directions) of defect-type effects
        for eff, sl in zip(self.effects, self._effect_slices):
            directions = eff.defect_directions(self)
            if directions is not None:
                self._effect_defects.append((sl, np.asarray(directions, dtype=float)))
        self.n = len(self.names)
        ng = len(self.geometry_names)
        self.sl_geometry = slice(0, ng)
        self.sl_tracker = slice(ng, ng + 6)
        self.sl_target = slice(ng + 6, ng + 9)

    # ------------------------------------------------------------------ parameters
    def defects(self, theta: np.ndarray) -> np.ndarray:
        """Full defect vector ``xi`` (rad / mm) of parameters ``theta`` (geometry and defect-type effects)."""
        theta = np.asarray(theta)
        xi = self.geometry_matrix @ theta[self.sl_geometry]
        for sl, directions in self._effect_defects:
            xi = xi + directions @ theta[sl]
        return xi

    def initial(self, tracker: np.ndarray | None = None, target: np.ndarray | None = None) -> np.ndarray:
        """Parameter vector with zero defects and the given tracker pose and target offset."""
        theta = np.zeros(self.n)
        if tracker is not None:
            theta[self.sl_tracker] = tracker[[3, 4, 5, 0, 1, 2]]  # file order x y z rx ry rz -> rx ry rz x y z
        if target is not None:
            theta[self.sl_target] = target
        for eff, sl in zip(self.effects, self._effect_slices):
            theta[sl] = eff.initial(self)
        return theta

    def tracker_pose(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotation and origin of the tracker frame in the base frame."""
        t = np.asarray(theta)[self.sl_tracker]
        return so3_exp(t[:3]), t[3:]

    # ------------------------------------------------------------------ prediction
    def predict(self, theta: np.ndarray, data: MeasurementSet, jacobian: bool = False,
                q_start: np.ndarray | None = None) -> Prediction:
        """Predicted tracker-frame target positions at the poses of ``data``.

        Parameters
        ----------
        theta : ndarray
            Parameters (see :attr:`names`).
        data : MeasurementSet
            Poses (actuated values and metadata).
        jacobian : bool
            Also return ``d position / d theta``.
        q_start : ndarray, (K, n_q), optional
            Previous assembled configurations (warm start of the passive joints).
        """
        theta = np.asarray(theta, dtype=float)
        m = self.mechanism
        kin = self.kin
        xi = self.defects(theta)
        k = len(data)
        qa = data.q.copy()
        dqa_dtheta = np.zeros((k, qa.shape[1], self.n))
        for eff, sl in zip(self.effects, self._effect_slices):
            corr = eff.actuator_correction(self, theta[sl], data)
            if corr is not None:
                dq, dq_dt = corr
                qa = qa + dq
                dqa_dtheta[:, :, sl] += dq_dt
        if q_start is None:
            res = kin.solve(qa, xi)
        else:
            q0 = q_start.copy()
            q0[:, m.actuated] = qa
            res = kin.assemble(q0, xi)
        # Over-constrained loops with inadmissible defects (second-order strain of the linear
        # coupled-defect relations, about 1e-4 mm on the Tripteor, or a violated forced defect)
        # close only in the least-squares sense, the minimum of the closure gap energy with
        # rotations weighted by the length scale.  A pose is lost only when the gap is of the
        # order of the links (above 1 % of the length scale).
        bad = res.residual > 1e-2 * kin.length_scale
        if q_start is not None and np.any(bad):  # fall back to continuation from home for those
            redo = kin.solve(qa[bad], xi)
            res.q[bad] = redo.q
            res.residual[bad] = redo.residual
            bad = res.residual > 1e-2 * kin.length_scale
        res.converged = ~bad
        q = res.q
        st = kin.evaluate(q, xi, jacobians=jacobian)
        rot_out = st.output_pose[:, :3, :3]
        org_out = st.output_pose[:, :3, 3]
        p_t = theta[self.sl_target]
        world = org_out + np.einsum("kij,j->ki", rot_out, p_t)
        dworld = np.zeros((k, 3, self.n)) if jacobian else None
        for eff, sl in zip(self.effects, self._effect_slices):
            corr = eff.output_correction(self, theta[sl], data, q, st, world, jacobian)
            if corr is not None:
                dp, dp_dt = corr
                world = world + dp
                if jacobian:
                    dworld[:, :, sl] += dp_dt
        r_trk, t_trk = self.tracker_pose(theta)
        rel = world - t_trk
        position = rel @ r_trk  # R^T (p - t) for each row
        measured_by = []  # (slice, d position / d theta_e, d position / d position before)
        for eff, sl in zip(self.effects, self._effect_slices):
            corr = eff.measurement_correction(self, theta[sl], data, position, jacobian)
            if corr is not None:
                position, dm_dt, dm_dpos = corr
                measured_by.append((sl, dm_dt, dm_dpos))
        if not jacobian:
            return Prediction(position, None, q, res.converged, world)
        # output twist with the passive joints following (implicit function theorem)
        k_xi, k_a = self.twist_maps(st)
        arm = world - org_out  # target relative to the output origin

        def point(rows: np.ndarray) -> np.ndarray:  # (K, 6, n) -> (K, 3, n) target velocity
            return rows[:, 3:, :] + np.cross(rows[:, :3, :], arm[:, :, None], axis=1)

        dworld[:, :, self.sl_geometry] += point(k_xi) @ self.geometry_matrix
        for sl, directions in self._effect_defects:
            dworld[:, :, sl] += point(k_xi) @ directions
        dworld[:, :, self.sl_target] += rot_out
        if self.effects:
            dworld += np.einsum("kan,knj->kaj", point(k_a), dqa_dtheta)
        jac = np.einsum("ij,kia->kja", r_trk, dworld)  # R^T d(world)
        # tracker: position = R^T (world - t), R = exp(w): d/dw = R^T [world - t]x J_l(w), d/dt = -R^T
        jl = so3_left_jacobian(theta[self.sl_tracker][:3])
        jac[:, :, self.sl_tracker.start:self.sl_tracker.start + 3] = np.einsum(
            "ij,kjl,lm->kim", r_trk.T, skew(rel), jl)
        jac[:, :, self.sl_tracker.start + 3:self.sl_tracker.stop] = -r_trk.T[None]
        for sl, dm_dt, dm_dpos in measured_by:
            jac = np.einsum("kij,kjn->kin", dm_dpos, jac)
            jac[:, :, sl] += dm_dt
        self._last_k_a = k_a
        return Prediction(position, jac, q, res.converged, world)

    def twist_maps(self, st) -> tuple[np.ndarray, np.ndarray]:
        """Output twist per unit defect and per unit actuated value (see :func:`hyperstat.solver.tolerances.accuracy.output_twist_maps`)."""
        from hyperstat.solver.tolerances.accuracy import output_twist_maps

        return output_twist_maps(self.kin, st)

    def actuation_twists(self, st) -> np.ndarray:
        """Output twist per unit actuated value (K, 6, n_actuated) at an evaluated state (see :meth:`twist_maps`)."""
        return self.twist_maps(st)[1]

    def actuation_jacobian(self) -> np.ndarray | None:
        """Output twist per unit actuated joint value at the last prediction (K, 6, n_actuated)."""
        return getattr(self, "_last_k_a", None)


def kabsch(source: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation ``R`` and translation ``t`` minimising ``sum |R source + t - target|^2`` (Kabsch)."""
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    h = (source - cs).T @ (target - ct)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return r, ct - r @ cs


def error_stats(error: np.ndarray) -> dict:
    """Mean, max and RMS of the Euclidean norms of error vectors (mm)."""
    e = np.linalg.norm(np.atleast_2d(error), axis=1)
    return {"mean": float(np.mean(e)), "max": float(np.max(e)), "rms": float(np.sqrt(np.mean(e**2))), "n": int(e.size)}


def observability_indices(s: np.ndarray, m: int) -> dict:
    """Observability indices of a column-scaled Jacobian with singular values ``s`` and ``m`` rows.

    O1 = (prod s)^(1/L) / sqrt(m) (Borm and Menq), O2 = s_min / s_max (inverse condition
    number, Driels and Pathre), O3 = s_min (Nahvi), O4 = s_min^2 / s_max (noise
    amplification, Nahvi and Hollerbach).
    """
    s = np.asarray(s, dtype=float)
    return {
        "O1": float(np.exp(np.mean(np.log(s))) / np.sqrt(m)),
        "O2": float(s[-1] / s[0]),
        "O3": float(s[-1]),
        "O4": float(s[-1] ** 2 / s[0]),
    }


@dataclass
class IdentificationResult:
    """Outcome of :func:`identify`; ``to_dict`` gives the JSON of ``hyperstat identify``.

    Attributes
    ----------
    rank : int
        Numerical rank of the identification Jacobian (identifiable combinations).
    n_unknowns : int
        Unknowns before the base-parameter selection.
    condition_number, condition_number_raw : float
        Of the base columns scaled to unit norm (angles times the length scale first),
        and of the unscaled weighted Jacobian.
    singular_value_gap : float
        ``s[rank-1] / s[rank]`` of the unit-norm columns (inf at full rank).
    observability : dict
        O1-O4 (:func:`observability_indices`).
    parameters : list of dict
        ``name, kind, unit, estimate, std, identifiable`` for every unknown (mm, rad).
    unidentifiable : list of dict
        ``name, reason, combination``: unknowns held at their prior value, with the base
        parameters that absorb them (``base += coefficient * (true - prior)``).
    correlations : list of dict
        Pairs of base parameters with ``|rho| > 0.9``.
    identification, validation : dict
        ``mean, max, rms, n`` of the 3-D residual norms (mm).
    noise_rms : float or None
        RMS of the 3-D noise the data's noise model implies (mm).
    sigma : float
        Standard deviation of the weighted residuals (1 when the noise model is right).
    iterations : int
        Model evaluations (each with its Jacobian).
    elapsed : float
        Wall time (s).
    theta : ndarray
        Estimated parameters in ``model.names`` order.
    base : list of str
        Base parameter names.
    covariance : ndarray
        Covariance of the base parameters (``base`` order).
    configurations : ndarray
        Assembled configurations (all joints) at the identification poses.
    """

    rank: int
    n_unknowns: int
    condition_number: float
    condition_number_raw: float
    singular_value_gap: float
    observability: dict
    parameters: list
    unidentifiable: list
    correlations: list
    identification: dict
    validation: dict | None
    noise_rms: float | None
    sigma: float
    iterations: int
    elapsed: float
    theta: np.ndarray
    base: list
    model: MeasurementModel = field(repr=False)
    covariance: np.ndarray | None = field(default=None, repr=False)
    configurations: np.ndarray | None = field(default=None, repr=False)
    residuals: np.ndarray | None = field(default=None, repr=False)
    validation_residuals: np.ndarray | None = field(default=None, repr=False)
    warnings: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready dictionary (units: mm, rad)."""
        return {
            "units": {"length": "mm", "angle": "rad"},
            "rank": self.rank,
            "unknowns": self.n_unknowns,
            "condition_number": self.condition_number,
            "condition_number_raw": self.condition_number_raw,
            "singular_value_gap": self.singular_value_gap,
            "observability": self.observability,
            "parameters": self.parameters,
            "unidentifiable": self.unidentifiable,
            "correlations": self.correlations,
            "identification": self.identification,
            "validation": self.validation,
            "noise_rms": self.noise_rms,
            "sigma": self.sigma,
            "iterations": self.iterations,
            "warnings": self.warnings,
        }

    def estimates(self) -> dict:
        """Parameter name -> estimate."""
        return {p["name"]: p["estimate"] for p in self.parameters}


def _weights(data: MeasurementSet) -> np.ndarray:
    """Per-point weights 1/sigma (1/mm) from the noise model, ones without one."""
    if data.noise is None:
        return np.ones(len(data))
    return 1.0 / data.noise.sigma(np.linalg.norm(data.position, axis=1))


def noise_rms(data: MeasurementSet) -> float | None:
    """RMS of the 3-D noise the data's noise model implies (mm)."""
    if data.noise is None:
        return None
    s = data.noise.sigma(np.linalg.norm(data.position, axis=1))
    return float(np.sqrt(np.mean(3.0 * s**2)))


def _column_scale(model: MeasurementModel) -> np.ndarray:
    """Column scale making angles and lengths comparable: angles times the length scale."""
    lc = model.kin.length_scale
    return np.array([lc if u == "rad" else 1.0 for u in model.units])


def base_parameters(jacobian: np.ndarray, preferred: list, rank_tol: float = 1e-8) -> tuple[list, int, float, np.ndarray]:
    """Identifiable (base) parameter columns by QR with column pivoting, preferred columns first.

    The preferred columns (the measurement set-up: tracker frame, target offset) are
    pivoted first; the remaining columns are pivoted on what the chosen preferred
    columns leave unexplained.  A machine defect that only duplicates the tracker frame
    is so reported as seen in combination with the tracker, not the other way round.

    Parameters
    ----------
    jacobian : ndarray, (m, n)
        Column-scaled identification Jacobian.
    preferred : list of int
        Columns to keep in the base set when they are independent.
    rank_tol : float
        Relative threshold on the normalised singular values and R diagonal.

    Returns
    -------
    base : list of int
        Sorted base column indices.
    rank : int
        Numerical rank (from singular values of the unit-norm columns).
    gap : float
        ``s[rank-1] / s[rank]`` (inf if full rank).
    visible : ndarray of bool
        Columns with a non-zero effect.
    """
    import scipy.linalg  # imported here: import hyperstat.solver stays fast

    norms = np.linalg.norm(jacobian, axis=0)
    visible = norms > 1e-12 * max(norms.max(), 1e-300)
    jn = np.zeros_like(jacobian)
    jn[:, visible] = jacobian[:, visible] / norms[visible]
    sv = np.linalg.svd(jn[:, visible], compute_uv=False)
    rank = int(np.sum(sv > rank_tol * sv[0]))
    gap = float(sv[rank - 1] / sv[rank]) if rank < len(sv) and sv[rank] > 0 else float("inf")
    first = [j for j in preferred if visible[j]]
    chosen: list[int] = []
    if first:
        _, rr, piv = scipy.linalg.qr(jn[:, first], mode="economic", pivoting=True)
        d = np.abs(np.diag(rr))
        chosen = [first[p] for p in piv[: int(np.sum(d > rank_tol * max(d[0], 1e-300)))]]
    rest = [j for j in range(jacobian.shape[1]) if visible[j] and j not in first]
    if rest and len(chosen) < rank:
        if chosen:
            qc, _ = np.linalg.qr(jn[:, chosen])
            resid = jn[:, rest] - qc @ (qc.T @ jn[:, rest])
        else:
            resid = jn[:, rest]
        _, _, piv = scipy.linalg.qr(resid, mode="economic", pivoting=True)
        chosen += [rest[p] for p in piv[: rank - len(chosen)]]
    return sorted(chosen), rank, gap, visible


def gauss_newton(evaluate, x0: np.ndarray, column_scale: np.ndarray, max_iter: int = 8,
                 chi2_tol: float = 0.01) -> np.ndarray:
    """Undamped Gauss-Newton iterations with step halving, the start of the Levenberg-Marquardt fit.

    Near-linear calibration problems converge in two or three full Gauss-Newton
    steps; MINPACK's trust region instead creeps along the flat valleys of weakly
    identifiable combinations (20+ evaluations on the Tripteor).  Starting the
    Levenberg-Marquardt polish from here leaves it one or two evaluations.

    Parameters
    ----------
    evaluate : callable
        ``x -> (weighted residual, weighted Jacobian)``.
    x0 : ndarray
        Start.
    column_scale : ndarray
        Column scale making the Jacobian's columns commensurate.
    max_iter : int
        Largest number of steps.
    chi2_tol : float
        Stop when the weighted sum of squares decreases by less than this.

    Returns
    -------
    ndarray
        The last accepted iterate.
    """
    x = np.array(x0, dtype=float)
    r, j = evaluate(x)
    cost = float(r @ r)
    for _ in range(max_iter):
        js = j * column_scale
        norms = np.linalg.norm(js, axis=0).clip(min=1e-300)
        step, *_ = np.linalg.lstsq(js / norms, -r, rcond=1e-12)
        step = step / norms * column_scale
        for _half in range(6):
            trial = x + step
            r_t, j_t = evaluate(trial)
            cost_t = float(r_t @ r_t)
            if np.isfinite(cost_t) and cost_t <= cost:
                break
            step = step / 2.0
        else:
            return x
        gain = cost - cost_t
        x, r, j, cost = trial, r_t, j_t, cost_t
        if gain < chi2_tol:
            break
    return x


def identify(
    mechanism: Mechanism,
    analysis: StationarityResult,
    data: MeasurementSet,
    validation: MeasurementSet | None = None,
    effects: tuple = (),
    kinematics: Kinematics | None = None,
    rank_tol: float = 1e-8,
    max_nfev: int = 50,
    model: MeasurementModel | None = None,
    theta0: np.ndarray | None = None,
    base: list | None = None,
) -> IdentificationResult:
    """Identify the base parameters from ``data`` (paper 1, eq. 10, Levenberg-Marquardt).

    Parameters
    ----------
    mechanism, analysis : Mechanism, StationarityResult
        Nominal model and its stationarity analysis.
    data : MeasurementSet
        Identification measurements.
    validation : MeasurementSet, optional
        Points never used to fit.
    effects : tuple
        Unmodelled-effect models to identify with the geometry.
    rank_tol : float
        Relative singular value below which a direction is not identifiable.
    max_nfev : int
        Largest number of model evaluations of the fit.
    model : MeasurementModel, optional
        Reuse a model; ``theta0`` an initial guess.
    base : list of str, optional
        Impose the base parameter names (e.g. to compare two fits); chosen by QR with
        column pivoting otherwise.

    Returns
    -------
    IdentificationResult

    Raises
    ------
    DataError
        If there are fewer measurements than identifiable parameters.
    """
    t0 = time.perf_counter()
    imposed = base
    model = model or MeasurementModel(mechanism, analysis, kinematics, effects)
    warns: list[str] = []
    theta = model.initial(data.tracker, data.target) if theta0 is None else np.array(theta0, dtype=float)
    if theta0 is None:
        # rigid registration of the tracker frame on the nominal model (Kabsch), then refine
        nominal = model.predict(theta, data)
        r, t = kabsch(data.position, nominal.world)
        theta[model.sl_tracker] = np.r_[so3_log(r), t]
        pred = model.predict(theta, data, jacobian=True, q_start=nominal.q)
    else:
        pred = model.predict(theta, data, jacobian=True)
    if not pred.converged.all():
        bad = [data.pose[i] for i in np.nonzero(~pred.converged)[0][:3]]
        raise DataError(f"{data.source}: the nominal model does not assemble at pose(s) {', '.join(bad)}.")
    w = _weights(data)
    scale = _column_scale(model)
    js = (pred.jacobian * w[:, None, None]).reshape(-1, model.n) * scale
    preferred = [j for j, kind in enumerate(model.kinds) if kind in ("tracker", "target")]
    base, rank, gap, visible = base_parameters(js, preferred, rank_tol)
    if base is not None and imposed is not None:
        unknown = [b for b in imposed if b not in model.names]
        if unknown:
            raise DataError(f"base parameter(s) {', '.join(unknown)} are not unknowns of '{mechanism.name}'.")
        base = sorted(model.names.index(b) for b in imposed)
    n_rows = js.shape[0]
    n_visible = int(visible.sum())
    if n_rows <= n_visible:
        need = n_visible // 3 + 1
        raise DataError(f"{data.source} has {len(data)} poses ({n_rows} equations), too few for the {n_visible} "
                        f"unknowns of '{mechanism.name}': give at least {need} poses (in practice 3x more).")
    if n_rows < 2 * len(base):
        warns.append(f"only {n_rows} equations for {len(base)} parameters: expect poor accuracy.")
    # parameters that cannot be seen, with the combination they are seen in
    unident = []
    jb = js[:, base]
    for j in range(model.n):
        if j in base:
            continue
        if not visible[j]:
            unident.append({"name": model.names[j], "reason": "no effect on the measured positions", "combination": {}})
            continue
        coef, *_ = np.linalg.lstsq(jb, js[:, j], rcond=None)
        coef = coef * scale[base] / scale[j]  # physical units
        comb = {model.names[b]: float(c) for b, c in zip(base, coef) if abs(c) > 1e-6}
        unident.append({"name": model.names[j], "reason": "seen only in combination with base parameters",
                         "combination": comb})

    state = {"q": pred.q}
    base_idx = np.array(base, dtype=int)

    def unpack(x: np.ndarray) -> np.ndarray:
        full = theta.copy()
        full[base_idx] = x
        return full

    cache: dict = {}
    n_evaluations = [0]

    def evaluate(x: np.ndarray):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            n_evaluations[0] += 1
            p = model.predict(unpack(x), data, jacobian=True, q_start=state["q"])
            state["q"] = p.q
            r = ((p.position - data.position) * w[:, None]).ravel()
            cache[key] = (r, (p.jacobian * w[:, None, None]).reshape(-1, model.n)[:, base_idx])
        return cache[key]

    x0 = gauss_newton(evaluate, theta[base_idx], scale[base_idx])
    # Stopping rule: the weighted sum of squares is about the number of equations at the
    # optimum; a relative decrease below 0.01 / n_rows changes it by less than 0.01 (a
    # chi-square unit), i.e. moves the estimates by well under a tenth of their std.
    ftol = 0.01 / n_rows
    from scipy.optimize import least_squares  # imported here: import hyperstat.solver stays fast

    fit = least_squares(lambda x: evaluate(x)[0], x0, jac=lambda x: evaluate(x)[1], method="lm",
                        x_scale=1.0 / scale[base_idx], max_nfev=max_nfev * (len(x0) + 1), xtol=1e-10, ftol=ftol)
    theta = unpack(fit.x)
    final = model.predict(theta, data, jacobian=True, q_start=state["q"])
    resid = final.position - data.position
    jw = (final.jacobian * w[:, None, None]).reshape(-1, model.n)[:, base_idx]
    rw = (resid * w[:, None]).ravel()
    dof = max(jw.shape[0] - len(base), 1)
    sigma2 = float(rw @ rw / dof)
    jtj = jw.T @ jw
    try:
        cov = sigma2 * np.linalg.inv(jtj)
    except np.linalg.LinAlgError:
        cov = sigma2 * np.linalg.pinv(jtj)
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    corr = cov / np.outer(std, std).clip(min=1e-300)
    correlations = []
    for a in range(len(base)):
        for b in range(a + 1, len(base)):
            if abs(corr[a, b]) > 0.9:
                correlations.append({"a": model.names[base[a]], "b": model.names[base[b]], "rho": float(corr[a, b])})
    js_final = jw * scale[base_idx]
    sv_b = np.linalg.svd(js_final / np.linalg.norm(js_final, axis=0), compute_uv=False)
    sv_raw = np.linalg.svd(jw, compute_uv=False)
    params = []
    std_of = dict(zip(base, std))
    for j, name in enumerate(model.names):
        params.append({"name": name, "kind": model.kinds[j], "unit": model.units[j], "estimate": float(theta[j]),
                       "std": float(std_of[j]) if j in std_of else None, "identifiable": j in std_of})
    val_stats = None
    val_res = None
    if validation is not None and len(validation):
        vp = model.predict(theta, validation)
        if not vp.converged.all():
            warns.append("some validation poses did not assemble with the identified model.")
        val_res = vp.position - validation.position
        val_stats = error_stats(val_res)
    return IdentificationResult(
        rank=rank,
        n_unknowns=model.n,
        condition_number=float(sv_b[0] / sv_b[-1]),
        condition_number_raw=float(sv_raw[0] / sv_raw[-1]),
        singular_value_gap=gap,
        observability=observability_indices(sv_b, js_final.shape[0]),
        parameters=params,
        unidentifiable=unident,
        correlations=correlations,
        identification=error_stats(resid),
        validation=val_stats,
        noise_rms=noise_rms(data),
        sigma=float(np.sqrt(sigma2)),
        iterations=n_evaluations[0],
        covariance=cov,
        configurations=final.q,
        elapsed=time.perf_counter() - t0,
        theta=theta,
        base=[model.names[b] for b in base],
        model=model,
        residuals=resid,
        validation_residuals=val_res,
        warnings=warns,
    )

