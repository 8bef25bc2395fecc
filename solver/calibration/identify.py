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
from hyperstat.solver.threads import limited_blas

__all__ = ["MeasurementModel", "Prediction", "IdentificationResult", "identify", "error_stats", "kabsch", "register_targets",
           "observability_indices", "fit_quality", "FIT_QUALITY", "SIGMA_WARN", "SIGMA_INPUTS", "SIZE_INPUTS"]

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
    rotation : ndarray, (K, 3, 3) or None
        Predicted target-frame orientations in the tracker frame (6-D models only).
    rotation_jacobian : ndarray, (K, 3, n_params) or None
        Tracker-frame angular velocity per unit parameter (left perturbation, rad).
    """

    position: np.ndarray
    jacobian: np.ndarray | None
    q: np.ndarray
    converged: np.ndarray
    world: np.ndarray
    rotation: np.ndarray | None = None
    rotation_jacobian: np.ndarray | None = None


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
    targets : list of str, optional
        Target names (several targets on one output frame: one offset each); one unnamed
        target by default.
    orientation : bool
        6-D measurements: each target also has a rotation offset (rotation vector, 3 unknowns
        ``target_rx...``), and :meth:`predict` returns the target frame's orientation in the
        tracker frame, ``R_trk^T R_out R_target``, with its Jacobian.
    """

    def __init__(self, mechanism: Mechanism, analysis: StationarityResult, kinematics: Kinematics | None = None,
                 effects: tuple = (), geometry: str = "influential", targets: list | None = None,
                 orientation: bool = False) -> None:
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
        self.targets = list(targets) if targets else [""]
        nt = len(self.targets)
        target_names = TARGET_NAMES if self.targets == [""] else \
            [f"target_{t}_{a}" for t in self.targets for a in "xyz"]
        self.names = list(self.geometry_names) + TRACKER_NAMES + target_names
        self.units = [units[n] for n in self.geometry_names] + ["rad"] * 3 + ["mm"] * (3 + 3 * nt)
        self.kinds = ["geometry"] * len(self.geometry_names) + ["tracker"] * 6 + ["target"] * 3 * nt
        self.orientation = bool(orientation)
        if self.orientation:
            rot_names = ["target_rx", "target_ry", "target_rz"] if self.targets == [""] else \
                [f"target_{t}_r{a}" for t in self.targets for a in "xyz"]
            self.names += rot_names
            self.units += ["rad"] * len(rot_names)
            self.kinds += ["target_rotation"] * len(rot_names)
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
        self.sl_target = slice(ng + 6, ng + 6 + 3 * nt)
        self.sl_target_rotation = slice(ng + 6 + 3 * nt, ng + 6 + 6 * nt) if self.orientation else slice(0, 0)

    # ------------------------------------------------------------------ parameters
    def defects(self, theta: np.ndarray) -> np.ndarray:
        """Full defect vector ``xi`` (rad / mm) of parameters ``theta`` (geometry and defect-type effects)."""
        theta = np.asarray(theta)
        xi = self.geometry_matrix @ theta[self.sl_geometry]
        for sl, directions in self._effect_defects:
            xi = xi + directions @ theta[sl]
        return xi

    def initial(self, tracker: np.ndarray | None = None, target: np.ndarray | dict | None = None) -> np.ndarray:
        """Parameter vector with zero defects and the given tracker pose and target offset(s).

        ``target`` is one offset (3,) or, for several targets, a dict name -> offset (mm).
        """
        theta = np.zeros(self.n)
        if tracker is not None:
            theta[self.sl_tracker] = tracker[[3, 4, 5, 0, 1, 2]]  # file order x y z rx ry rz -> rx ry rz x y z
        if isinstance(target, dict):
            offsets = theta[self.sl_target].reshape(-1, 3)
            for t, v in target.items():
                if t in self.targets:
                    offsets[self.targets.index(t)] = v
            theta[self.sl_target] = offsets.ravel()
        elif target is not None:
            theta[self.sl_target] = np.tile(np.asarray(target, float), len(self.targets))
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
        tidx = self._target_index(data)
        p_t = theta[self.sl_target].reshape(-1, 3)[tidx]
        world = org_out + np.einsum("kij,kj->ki", rot_out, p_t)
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
        rot_pred = rot_jac = None
        if self.orientation:
            from hyperstat.solver.kinematics.frames import so3_exp as _exp

            v = theta[self.sl_target_rotation].reshape(-1, 3)
            r_tgt = _exp(v)[tidx]
            rot_pred = np.einsum("ji,kjl,klm->kim", r_trk, rot_out, r_tgt)
        if not jacobian:
            return Prediction(position, None, q, res.converged, world, rot_pred)
        # output twist with the passive joints following (implicit function theorem)
        k_xi, k_a = self.twist_maps(st)
        arm = world - org_out  # target relative to the output origin

        def point(rows: np.ndarray) -> np.ndarray:  # (K, 6, n) -> (K, 3, n) target velocity
            return rows[:, 3:, :] + np.cross(rows[:, :3, :], arm[:, :, None], axis=1)

        dworld[:, :, self.sl_geometry] += point(k_xi) @ self.geometry_matrix
        for sl, directions in self._effect_defects:
            dworld[:, :, sl] += point(k_xi) @ directions
        for t in range(len(self.targets)):
            rows = tidx == t
            c0 = self.sl_target.start + 3 * t
            dworld[rows, :, c0:c0 + 3] += rot_out[rows]
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
        if self.orientation:
            # left perturbation of R_trk^T R_out R_target, written in the tracker frame
            rot_jac = np.zeros((k, 3, self.n))
            rot_jac[:, :, self.sl_geometry] = np.einsum("ji,kjn->kin", r_trk, k_xi[:, :3, :] @ self.geometry_matrix)
            rot_jac[:, :, self.sl_tracker.start:self.sl_tracker.start + 3] = -(r_trk.T @ jl)[None]
            jt = so3_left_jacobian(theta[self.sl_target_rotation].reshape(-1, 3))
            for t in range(len(self.targets)):
                rows = tidx == t
                c0 = self.sl_target_rotation.start + 3 * t
                rot_jac[rows, :, c0:c0 + 3] = np.einsum("ji,kjl,lm->kim", r_trk, rot_out[rows], jt[t])
            # effects turn the output through the actuated values (and defect-type effects through the
            # geometry); thermal growth, tracker scale and drift move points, they turn nothing
            if self.effects:
                rot_jac += np.einsum("ji,kjn->kin", r_trk, np.einsum("kan,knj->kaj", k_a[:, :3, :], dqa_dtheta))
            for sl, directions in self._effect_defects:
                rot_jac[:, :, sl] += np.einsum("ji,kjn->kin", r_trk, k_xi[:, :3, :] @ directions)
        return Prediction(position, jac, q, res.converged, world, rot_pred, rot_jac)

    def _target_index(self, data: MeasurementSet) -> np.ndarray:
        """Target of each row of ``data`` as an index into :attr:`targets`."""
        idx = getattr(data, "target_index", None)
        k = len(data)
        if idx is None or (len(self.targets) == 1 and len(getattr(data, "target_names", [""])) == 1):
            return np.zeros(k, dtype=int)
        names = getattr(data, "target_names", None)
        if names is not None and list(names) != self.targets:
            if self.targets == [""]:
                raise DataError(f"{data.source}: this step models one target per pose, the file has "
                                f"{len(names)} ({', '.join(names)}); give it one target's columns.")
            raise DataError(f"{data.source}: targets {', '.join(names)} differ from the model's "
                            f"{', '.join(self.targets)}.")
        return np.asarray(idx, dtype=int)

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


def register_targets(model: MeasurementModel, theta: np.ndarray, data: MeasurementSet, q: np.ndarray,
                     r: np.ndarray, t: np.ndarray, iterations: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Tracker frame and target offsets of the nominal model, whatever the prior: the starting guess.

    Block coordinate descent on ``sum |R_trk^T (o_k + R_k p_target(k) - t_trk) - m_k|^2`` with the
    nominal geometry (output poses ``R_k, o_k`` fixed): the tracker frame by Kabsch, then each
    target offset in closed form, ``p = mean_k R_k^T (R_trk m_k + t_trk - o_k)`` over its
    observations.  Every step lowers the cost, so the prior (or its absence: targets at the
    output origin, on the wrist axis of a 6R) only starts the descent; the identifiable set
    chosen at the start then no longer depends on it (issue 21).  ``theta``'s target offsets
    are overwritten; returns the tracker rotation and origin in the base frame.
    """
    st = model.kin.evaluate(q, model.defects(theta), jacobians=False)
    rot, org = st.output_pose[:, :3, :3], st.output_pose[:, :3, 3]
    tidx = model._target_index(data)
    offsets = theta[model.sl_target].reshape(-1, 3).copy()
    for _ in range(iterations):
        measured_world = data.position @ r.T + t
        local = np.einsum("kji,kj->ki", rot, measured_world - org)  # R_k^T (w_k - o_k)
        new = offsets.copy()
        for ti in range(len(offsets)):
            rows = tidx == ti
            if rows.any():
                new[ti] = local[rows].mean(axis=0)
        world = org + np.einsum("kij,kj->ki", rot, new[tidx])
        r, t = kabsch(data.position, world)
        step = float(np.abs(new - offsets).max())
        offsets = new
        if step < 1e-9 * max(model.kin.length_scale, 1.0):
            break
    theta[model.sl_target] = offsets.ravel()
    return r, t


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
    nominal : dict or None
        The nominal model's error ("before"): only the measurement set-up (tracker frame,
        target offsets) fitted, geometry at its nominal value; ``identification`` and
        ``validation`` stats (mm) and ``sigma``.
    residual_table : list of dict
        Per observation (pose, target): residual components and norm (mm), weighted norm,
        robust z-score (median / MAD of the weighted norms) and ``outlier`` flag.
    base_rounds : list of int
        Rank found at each round of the base-set decision (the last at the solution).
    held_back : dict or None
        Directions numerically independent at the solution whose fit did not explain
        significantly more (chi-square test of the nested fits): kept out of the base set.
    converged : bool
        Whether the fit converged (cost not increased, iteration limit not hit).
    fit_quality : str
        Machine-readable severity of the fit (:func:`fit_quality`): ``"ok"``, ``"model misses
        an effect"`` (sigma a few times the stated noise: run the diagnosis) or ``"inputs
        wrong"`` (sigma in the hundreds or residuals of a link's size: joint map, units,
        targets); export commands refuse the last two without ``--force``.
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
    nominal: dict | None = None
    residual_table: list = field(default_factory=list)
    validation_table: list = field(default_factory=list)
    base_rounds: list = field(default_factory=list)
    converged: bool = True
    model_selection: dict | None = None
    orientation: dict | None = None
    held_back: dict | None = None
    fit_quality: str = "ok"

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
            "fit_quality": self.fit_quality,
            "converged": self.converged,
            "nominal": self.nominal,
            "base_rounds": self.base_rounds,
            "held_back": self.held_back,
            "model_selection": self.model_selection,
            "orientation": self.orientation,
            "iterations": self.iterations,
            "warnings": self.warnings,
            "residuals": self.residual_table,
            "validation_residuals": self.validation_table,
        }

    def residuals_csv(self) -> str:
        """Per-observation residuals as CSV text (mm), identification then validation rows."""
        out = ["set,pose,target,dx[mm],dy[mm],dz[mm],norm[mm],weighted_norm,robust_z,outlier"]
        for label, table in (("identification", self.residual_table), ("validation", self.validation_table)):
            for r in table:
                out.append(f"{label},{r['pose']},{r['target']},{r['dx']:.9g},{r['dy']:.9g},{r['dz']:.9g},"
                           f"{r['norm']:.9g},{r['weighted_norm']:.6g},{r['robust_z']:.4g},{int(r['outlier'])}")
        return "\n".join(out) + "\n"

    def estimates(self) -> dict:
        """Parameter name -> estimate."""
        return {p["name"]: p["estimate"] for p in self.parameters}


def _sigma_rows(data: MeasurementSet) -> np.ndarray | None:
    """Per-row 1-sigma (mm): a set's own ``row_sigma`` (points derived from 6-D rows), else the noise model."""
    rows = getattr(data, "row_sigma", None)
    if rows is not None:
        return np.asarray(rows, dtype=float)
    if data.noise is None:
        return None
    return data.noise.sigma(np.linalg.norm(data.position, axis=1))


def _weights(data: MeasurementSet) -> np.ndarray:
    """Per-point weights 1/sigma (1/mm) from the noise model, ones without one."""
    s = _sigma_rows(data)
    return np.ones(len(data)) if s is None else 1.0 / s


def noise_rms(data: MeasurementSet) -> float | None:
    """RMS of the 3-D noise the data's noise model implies (mm)."""
    s = _sigma_rows(data)
    if s is None:
        return None
    return float(np.sqrt(np.mean(3.0 * s**2)))


def _column_scale(model: MeasurementModel) -> np.ndarray:
    """Column scale making angles and lengths comparable: angles times the length scale."""
    lc = model.kin.length_scale
    return np.array([lc if u == "rad" else 1.0 for u in model.units])


def base_parameters(jacobian: np.ndarray, preferred: list, rank_tol: float = 1e-8,
                    keep: list | None = None) -> tuple[list, int, float, np.ndarray]:
    """Identifiable (base) parameter columns by QR with column pivoting, preferred columns first.

    The preferred columns (the measurement set-up: tracker frame, target offset) are
    pivoted first; then the ``keep`` columns (a base set chosen earlier, so that a re-check
    at the solution does not swap equivalent representatives); the remaining columns are
    pivoted on what the chosen columns leave unexplained.  A machine defect that only
    duplicates the tracker frame is so reported as seen in combination with the tracker,
    not the other way round.

    Parameters
    ----------
    jacobian : ndarray, (m, n)
        Column-scaled identification Jacobian.
    preferred : list of int
        Columns to keep in the base set when they are independent.
    rank_tol : float
        Relative threshold on the normalised singular values and R diagonal.
    keep : list of int, optional
        Second tier of preferred columns.

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
    # A column joins the base set when what it adds is above the middle of the singular-value
    # gap (geometric mean of s[rank-1] and s[rank]): the same cut as the rank decision, so that a
    # weak but real direction (1e-8) is not dropped in one round and taken in the next.
    cut = float(np.sqrt(sv[rank - 1] * max(sv[rank], 1e-300 * sv[0])) / sv[0]) if rank < len(sv) else \
        0.5 * float(sv[-1] / sv[0])
    cut = min(cut, rank_tol) if rank < len(sv) else cut
    chosen: list[int] = []
    used: set[int] = set()
    tiers = [list(preferred), [j for j in (keep or []) if j not in preferred]]
    tiers.append([j for j in range(jacobian.shape[1]) if j not in tiers[0] and j not in tiers[1]])
    for tier in tiers:
        cols = [j for j in tier if visible[j] and j not in used]
        used.update(tier)
        if not cols or len(chosen) >= rank:
            continue
        if chosen:
            qc, _ = np.linalg.qr(jn[:, chosen])
            resid = jn[:, cols] - qc @ (qc.T @ jn[:, cols])
        else:
            resid = jn[:, cols]
        _, rr, piv = scipy.linalg.qr(resid, mode="economic", pivoting=True)
        d = np.abs(np.diag(rr))
        take = min(int(np.sum(d > cut)), rank - len(chosen))
        chosen += [cols[p] for p in piv[:take]]
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


OUTLIER_Z = 3.5  #: robust z-score above which an observation is flagged (Iglewicz and Hoaglin)
SIGMA_WARN = 3.0  #: weighted-residual standard deviation above which the rigid model misses something
SIGMA_INPUTS = 100.0  #: sigma from which the inputs (joint map, units, targets), not the model, are at fault
SIZE_INPUTS = 0.01  #: residual RMS above this share of the machine's length scale: the inputs are at fault
FIT_QUALITY = ("ok", "model misses an effect", "inputs wrong")


def fit_quality(sigma: float, rms: float, length_scale: float, noise_stated: bool) -> str:
    """Severity of a fit, one of :data:`FIT_QUALITY`.

    ``"inputs wrong"`` when the residual RMS (mm) exceeds :data:`SIZE_INPUTS` of the
    machine's length scale (a wrong joint sign, offset or coupling, a unit error, targets
    stacked in one column move the point by a fraction of a link) or, with a stated noise,
    sigma reaches :data:`SIGMA_INPUTS`; ``"model misses an effect"`` when sigma exceeds
    :data:`SIGMA_WARN` otherwise (compliance, gear errors, temperature: a few times the
    noise, well below a link's size); ``"ok"`` else.  Without a stated noise only the size
    test applies.

    >>> fit_quality(6.6, 0.57, 1500.0, True), fit_quality(1840.0, 40.0, 1500.0, True), fit_quality(1.02, 0.03, 1500.0, True)
    ('model misses an effect', 'inputs wrong', 'ok')
    """
    if rms > SIZE_INPUTS * length_scale or (noise_stated and sigma >= SIGMA_INPUTS):
        return "inputs wrong"
    if noise_stated and sigma > SIGMA_WARN:
        return "model misses an effect"
    return "ok"


def residual_table(data: MeasurementSet, resid: np.ndarray, w: np.ndarray) -> list:
    """Per-observation residuals with robust outlier flags (mm).

    The weighted residual norm ``|r| / sigma`` of each observation is compared with the
    median of all of them through the median absolute deviation (MAD, scaled by 1.4826 so
    that it estimates a standard deviation): ``z = (e - median) / (1.4826 MAD)``, flagged
    above :data:`OUTLIER_Z` (Iglewicz and Hoaglin's modified z-score).  A robust statistic:
    a few gross errors do not hide themselves by inflating the scale, as they would with
    the mean and standard deviation.
    """
    e = np.linalg.norm(resid, axis=1)
    ew = e * w
    med = float(np.median(ew)) if len(ew) else 0.0
    mad = float(np.median(np.abs(ew - med))) * 1.4826 if len(ew) else 0.0
    z = (ew - med) / max(mad, 1e-12 * max(med, 1e-300))
    names = data.target_names
    idx = data.target_index
    return [{"pose": data.pose_id[i], "target": names[int(idx[i])], "dx": float(resid[i, 0]), "dy": float(resid[i, 1]),
             "dz": float(resid[i, 2]), "norm": float(e[i]), "weighted_norm": float(ew[i]), "robust_z": float(z[i]),
             "outlier": bool(z[i] > OUTLIER_Z)} for i in range(len(e))]


def orientation_residual(rotation: np.ndarray, data: MeasurementSet) -> np.ndarray:
    """Orientation error ``log(R_pred R_meas^T)`` (rotation vectors in the tracker frame, rad), (K, 3)."""
    return so3_log(rotation @ np.swapaxes(so3_exp(data.rotation), -1, -2))


class _Fitter:
    """Weighted least squares over a subset of the parameters (Gauss-Newton, then MINPACK LM)."""

    def __init__(self, model: MeasurementModel, data: MeasurementSet, w: np.ndarray, q: np.ndarray) -> None:
        self.model, self.data, self.w = model, data, w
        self.q = q
        self.evaluations = 0

    def residual(self, theta: np.ndarray, jacobian: bool = True):
        """Prediction, weighted residual and weighted Jacobian (position rows, then orientation rows)."""
        p = self.model.predict(theta, self.data, jacobian=jacobian, q_start=self.q)
        if p.converged.all():
            self.q = p.q
        r = ((p.position - self.data.position) * self.w[:, None]).ravel()
        j = None if p.jacobian is None else (p.jacobian * self.w[:, None, None]).reshape(-1, self.model.n)
        if p.rotation is not None:
            wr = 1.0 / self.data.rotation_noise
            rr = orientation_residual(p.rotation, self.data)
            r = np.r_[r, (rr * wr).ravel()]
            if j is not None:
                j = np.vstack([j, (p.rotation_jacobian * wr).reshape(-1, self.model.n)])
        return p, r, j

    def fit(self, theta: np.ndarray, base_idx: np.ndarray, scale: np.ndarray, max_nfev: int) -> tuple[np.ndarray, bool]:
        """Fit the ``base_idx`` parameters from ``theta``; returns the estimate and whether it converged."""
        from scipy.optimize import least_squares  # imported here: import hyperstat.solver stays fast

        cache: dict = {}

        def unpack(x: np.ndarray) -> np.ndarray:
            full = theta.copy()
            full[base_idx] = x
            return full

        def evaluate(x: np.ndarray):
            key = x.tobytes()
            if key not in cache:
                cache.clear()
                self.evaluations += 1
                _, r, j = self.residual(unpack(x))
                cache[key] = (r, j[:, base_idx])
            return cache[key]

        r0 = evaluate(theta[base_idx])[0]
        cost0 = float(r0 @ r0)
        x0 = gauss_newton(evaluate, theta[base_idx], scale[base_idx])
        n_rows = len(r0)
        # Stopping rule: a relative decrease below 0.01 / n_rows changes the weighted sum of
        # squares (about n_rows at the optimum) by less than 0.01 of a chi-square unit.
        fit = least_squares(lambda x: evaluate(x)[0], x0, jac=lambda x: evaluate(x)[1], method="lm",
                            x_scale=1.0 / scale[base_idx], max_nfev=max_nfev * (len(x0) + 1), xtol=1e-10,
                            ftol=0.01 / n_rows)
        cost = float(fit.fun @ fit.fun)
        ok = bool(fit.status > 0 and np.isfinite(cost) and cost <= cost0 * (1 + 1e-9))
        return unpack(fit.x), ok


def _unidentifiable(model: MeasurementModel, js: np.ndarray, base: list, visible: np.ndarray,
                    scale: np.ndarray) -> list:
    out = []
    jb = js[:, base]
    for j in range(model.n):
        if j in base:
            continue
        if not visible[j]:
            out.append({"name": model.names[j], "reason": "no effect on the measured positions", "combination": {}})
            continue
        coef, *_ = np.linalg.lstsq(jb, js[:, j], rcond=None)
        coef = coef * scale[base] / scale[j]  # physical units
        comb = {model.names[b]: float(c) for b, c in zip(base, coef) if abs(c) > 1e-6}
        out.append({"name": model.names[j], "reason": "seen only in combination with base parameters",
                    "combination": comb})
    return out


@limited_blas
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
    nominal: bool = True,
    max_rounds: int = 5,
    select_size: str = "none",
    folds: int = 5,
) -> IdentificationResult:
    """Identify the base parameters from ``data`` (paper 1, eq. 10, Levenberg-Marquardt).

    The identifiable (base) set is decided **at the solution**: chosen at the start,
    fitted, chosen again with the Jacobian at the estimate, and refitted (parameters
    left out reset to their prior) until the set no longer changes (at most
    ``max_rounds``).  A set chosen at the starting guess depends on the prior: a target
    prior of zero puts the target on the wrist axis, where rotations about that axis are
    invisible, and the rank drops.

    Parameters
    ----------
    mechanism, analysis : Mechanism, StationarityResult
        Nominal model and its stationarity analysis.
    data : MeasurementSet
        Identification measurements (one or several targets).
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
    nominal : bool
        Also fit the measurement set-up alone on the nominal geometry (the "before" error).
    max_rounds : int
        Largest number of base-set decisions.
    select_size : {"none", "cv", "bic", "auto"}
        Model size for small data, among nested parameter sets (geometry columns in the
        pivoting order of the QR at the solution, i.e. the best-determined first): ``"cv"``
        by ``folds``-fold cross-validation over poses (the set that predicts held-out poses
        best), ``"bic"`` by the Bayesian information criterion with the file's noise model;
        ``"auto"`` uses BIC (CV without a noise model) when there are fewer than 5 equations
        per base parameter; ``"none"`` keeps the full base set.

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
    oriented = data.rotation is not None
    model = model or MeasurementModel(mechanism, analysis, kinematics, effects, targets=list(data.target_names),
                                      orientation=oriented)
    oriented = model.orientation and data.rotation is not None
    warns: list[str] = []
    prior = data.target_priors if data.n_targets > 1 else data.target
    theta = model.initial(data.tracker, prior) if theta0 is None else np.array(theta0, dtype=float)
    if theta0 is None:
        # rigid registration of the tracker frame on the nominal model (Kabsch), then refine
        nominal_pred = model.predict(theta, data)
        r, t = kabsch(data.position, nominal_pred.world)
        if not model.effects:
            r, t = register_targets(model, theta, data, nominal_pred.q, r, t)
        theta[model.sl_tracker] = np.r_[so3_log(r), t]
        q_start = nominal_pred.q
        if oriented:  # target rotations from the first observation of each target
            st = model.kin.evaluate(nominal_pred.q, model.defects(theta), jacobians=False)
            r_out = st.output_pose[:, :3, :3]
            meas = so3_exp(data.rotation)
            rots = theta[model.sl_target_rotation].reshape(-1, 3)
            for ti in range(len(model.targets)):
                rows = np.nonzero(data.target_index == ti)[0]
                if len(rows):
                    i = rows[0]
                    rots[ti] = so3_log(r_out[i].T @ r @ meas[i])
            theta[model.sl_target_rotation] = rots.ravel()
    else:
        q_start = None
    pred = model.predict(theta, data, jacobian=True, q_start=q_start)
    if not pred.converged.all():
        bad = [data.pose[i] for i in np.nonzero(~pred.converged)[0][:3]]
        raise DataError(f"{data.source}: the nominal model does not assemble at pose(s) {', '.join(bad)}.")
    theta_prior = theta.copy()
    w = _weights(data)
    scale = _column_scale(model)
    preferred = [j for j, kind in enumerate(model.kinds) if kind in ("tracker", "target", "target_rotation")]
    fitter = _Fitter(model, data, w, pred.q)
    _, _, j0 = fitter.residual(theta)
    js = j0 * scale
    n_rows = js.shape[0]
    rounds: list[int] = []
    converged = True
    chosen: list | None = None
    cost, rank_used, held_back = float("inf"), 0, None
    for _round in range(max_rounds):
        # re-check at the solution: the set fitted so far first (it stays when it is still a base
        # set there), then the measurement set-up, then the rest
        base_idx, rank, gap, visible = base_parameters(js, chosen or preferred, rank_tol,
                                                       keep=preferred if chosen else None)
        if imposed is not None:
            unknown = [b for b in imposed if b not in model.names]
            if unknown:
                raise DataError(f"base parameter(s) {', '.join(unknown)} are not unknowns of '{mechanism.name}'.")
            base_idx = sorted(model.names.index(b) for b in imposed)
        n_visible = int(visible.sum())
        if n_rows <= n_visible:
            per_pose = max(n_rows // max(data.n_poses, 1), 1)
            need = n_visible // per_pose + 1
            raise DataError(f"{data.source} has {data.n_poses} poses ({n_rows} equations), too few for the "
                            f"{n_visible} unknowns of '{mechanism.name}': give at least {need} poses (in practice "
                            f"3x more).")
        rounds.append(rank)
        if chosen is not None and base_idx == chosen:
            break  # the set decided at the solution is the one fitted
        previous = None
        if chosen is not None:
            previous = (theta.copy(), list(chosen), cost, rank_used, fitter.q.copy())
            # parameters that left the base set go back to their prior; the refit absorbs them
            left = [j for j in chosen if j not in base_idx]
            theta[left] = theta_prior[left]
        chosen = base_idx
        theta, ok = fitter.fit(theta, np.array(base_idx, dtype=int), scale, max_nfev)
        final, r_now, jw_all = fitter.residual(theta)
        new_cost = float(r_now @ r_now)
        if previous is not None:
            # A set that changed at the solution is kept only when its fit is sound: a swap of
            # equivalent representatives must reach the same cost, and extra directions must
            # explain significantly more (chi-square test of the nested fits, 0.1 % level).
            # Directions that only second-order effects separate (a perturbed over-constrained
            # machine) are numerically independent but carry no information: held back.
            extra = len(base_idx) - len(previous[1])
            dof = max(n_rows - len(base_idx), 1)
            s2 = 1.0 if data.noise is not None else new_cost / dof
            from scipy.special import chdtri  # imported here: import hyperstat.solver stays fast

            needed = chdtri(extra, 1e-3) * s2 if extra > 0 else -1e-6 * max(previous[2], 1.0) - 0.01 * s2
            if not (np.isfinite(new_cost) and previous[2] - new_cost > needed):
                theta, chosen, cost, rank_used, q_prev = previous
                fitter.q = q_prev
                final, _, jw_all = fitter.residual(theta)
                js = jw_all * scale
                held_back = (rank, extra, float(previous[2] - new_cost))
                break
        converged = converged and ok
        cost, rank_used = new_cost, rank
        js = jw_all * scale
        if imposed is not None:
            rounds.append(rank)
            break
    else:
        warns.append(f"the identifiable set still changed after {max_rounds} rounds (ranks {rounds}): the rank "
                     f"decision is fragile at this solution; read the singular-value gap.")
    rank = rank_used
    if held_back is not None:
        # the singular-value gap at the accepted rank, from the Jacobian at the solution
        norms = np.linalg.norm(js, axis=0)
        vis = norms > 1e-12 * max(norms.max(), 1e-300)
        sv = np.linalg.svd(js[:, vis] / norms[vis], compute_uv=False)
        gap = float(sv[rank - 1] / sv[rank]) if rank < len(sv) and sv[rank] > 0 else float("inf")
    selection = None
    if imposed is None and (select_size in ("cv", "bic") or (select_size == "auto" and n_rows < 5 * len(chosen))):
        how = "cv" if select_size == "cv" or (select_size == "auto" and data.noise is None) else "bic"
        selection, keep_geo = _select_size(model, data, theta, theta_prior, chosen, js, w, scale, fitter.q, max_nfev,
                                           folds, how)
        if keep_geo is not None:
            dropped = [j for j in chosen if model.kinds[j] == "geometry" and j not in keep_geo]
            chosen = [j for j in chosen if j not in dropped]
            theta[dropped] = theta_prior[dropped]
            theta, ok = fitter.fit(theta, np.array(chosen, dtype=int), scale, max_nfev)
            converged = converged and ok
            _, _, jw_all = fitter.residual(theta)
            js = jw_all * scale
            warns.append(f"small data ({n_rows} equations): {selection['method']} kept {selection['chosen']} of "
                         f"{selection['sizes'][-1]} geometry parameters; the others are held at their nominal value.")
    base_list = list(chosen)
    base_idx = np.array(base_list, dtype=int)
    if n_rows < 2 * len(base_list):
        warns.append(f"only {n_rows} equations for {len(base_list)} parameters: expect poor accuracy.")
    unident = _unidentifiable(model, js, base_list, visible, scale)
    if selection is not None and selection["chosen"] < selection["sizes"][-1]:
        left = set(selection["order"][selection["chosen"]:])
        for u in unident:
            if u["name"] in left:
                u["reason"] = "left out by the model-size selection (cross-validation); " + u["reason"]
    final, rw, jw_all = fitter.residual(theta)
    resid = final.position - data.position
    jw = jw_all[:, base_idx]
    dof = max(jw.shape[0] - len(base_list), 1)
    sigma2 = float(rw @ rw / dof)
    jtj = jw.T @ jw
    try:
        cov = sigma2 * np.linalg.inv(jtj)
    except np.linalg.LinAlgError:
        cov = sigma2 * np.linalg.pinv(jtj)
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    corr = cov / np.outer(std, std).clip(min=1e-300)
    correlations = []
    for a in range(len(base_list)):
        for b in range(a + 1, len(base_list)):
            if abs(corr[a, b]) > 0.9:
                correlations.append({"a": model.names[base_list[a]], "b": model.names[base_list[b]],
                                     "rho": float(corr[a, b])})
    js_final = jw * scale[base_idx]
    sv_b = np.linalg.svd(js_final / np.linalg.norm(js_final, axis=0), compute_uv=False)
    sv_raw = np.linalg.svd(jw, compute_uv=False)
    params = []
    std_of = dict(zip(base_list, std))
    for j, name in enumerate(model.names):
        params.append({"name": name, "kind": model.kinds[j], "unit": model.units[j], "estimate": float(theta[j]),
                       "std": float(std_of[j]) if j in std_of else None, "identifiable": j in std_of})
    val_stats = None
    val_res = None
    val_table: list = []
    if validation is not None and len(validation):
        vp = model.predict(theta, validation)
        if not vp.converged.all():
            warns.append("some validation poses did not assemble with the identified model.")
        val_res = vp.position - validation.position
        val_stats = error_stats(val_res)
        val_table = residual_table(validation, val_res, _weights(validation))
    sigma = float(np.sqrt(sigma2))
    table = residual_table(data, resid, w)
    orientation = None
    if oriented:
        ang = np.linalg.norm(orientation_residual(final.rotation, data), axis=1)
        orientation = {"identification": _angle_stats(ang), "validation": None,
                       "noise_rms": float(np.sqrt(3.0) * data.rotation_noise)}
        if validation is not None and len(validation) and validation.rotation is not None:
            vp = model.predict(theta, validation)
            orientation["validation"] = _angle_stats(np.linalg.norm(orientation_residual(vp.rotation, validation),
                                                                    axis=1))
    nominal_doc = None
    if nominal:
        nominal_doc = _nominal_error(model, data, validation, theta_prior, w, scale, preferred, fitter.q, rank_tol,
                                     max_nfev)
    quality = fit_quality(sigma, error_stats(resid)["rms"], model.kin.length_scale, data.noise is not None)
    warns += _trust_warnings(data, validation, sigma, converged, table, val_stats, nominal_doc, resid, quality,
                             model.kin.length_scale)
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
        sigma=sigma,
        iterations=fitter.evaluations,
        covariance=cov,
        configurations=final.q,
        elapsed=time.perf_counter() - t0,
        theta=theta,
        base=[model.names[b] for b in base_list],
        model=model,
        residuals=resid,
        validation_residuals=val_res,
        warnings=warns,
        nominal=nominal_doc,
        residual_table=table,
        validation_table=val_table,
        base_rounds=rounds,
        converged=converged,
        model_selection=selection,
        orientation=orientation,
        fit_quality=quality,
        held_back=None if held_back is None else {
            "rank_at_solution": held_back[0], "extra_directions": held_back[1], "chi2_decrease": held_back[2],
            "reason": "numerically independent at the solution but not significant (chi-square test, 0.1 %): "
                      "held at their prior"},
    )


def _angle_stats(ang: np.ndarray) -> dict:
    """Mean, max and RMS of orientation-error angles (rad)."""
    return {"mean": float(np.mean(ang)), "max": float(np.max(ang)), "rms": float(np.sqrt(np.mean(ang**2))),
            "n": int(ang.size)}


def _select_size(model: MeasurementModel, data: MeasurementSet, theta: np.ndarray, theta_prior: np.ndarray,
                 chosen: list, js: np.ndarray, w: np.ndarray, scale: np.ndarray, q: np.ndarray, max_nfev: int,
                 folds: int, method: str = "cv") -> tuple[dict, list | None]:
    """Nested model sizes compared by K-fold cross-validation over poses.

    Geometry base columns are ordered by QR with column pivoting on what the measurement
    set-up leaves unexplained (best-determined first); sizes 0 (the nominal geometry), a
    quarter, half, three quarters and all of them are fitted on K-1 folds of poses and
    predict the held-out fold.  The size with the smallest cross-validated RMS is kept
    (the smallest one within 2 % of it, preferring fewer parameters).

    Returns
    -------
    selection : dict
        ``method, folds, sizes, cv_rms`` (mm) and ``chosen``.
    keep : list of int or None
        Geometry columns kept (None when all are).
    """
    import scipy.linalg

    setup = [j for j in chosen if model.kinds[j] != "geometry"]
    geo = [j for j in chosen if model.kinds[j] == "geometry"]
    jn = js / np.linalg.norm(js, axis=0).clip(min=1e-300)
    qs, _ = np.linalg.qr(jn[:, setup])
    resid = jn[:, geo] - qs @ (qs.T @ jn[:, geo])
    _, _, piv = scipy.linalg.qr(resid, mode="economic", pivoting=True)
    order = [geo[p] for p in piv]
    g = len(order)
    sizes = sorted({0, g // 4, g // 2, (3 * g) // 4, g})
    if method == "bic":
        # Bayesian information criterion with the file's noise model: chi2 + p ln(n), every size
        # fitted on all the data (no fold is too small to fit, as K-fold CV is with a few poses)
        crit = []
        n_eq = 3 * len(data)
        for size in sizes:
            base = sorted(setup + order[:size])
            th = theta.copy()
            others = [j for j in chosen if j not in base]
            th[others] = theta_prior[others]
            fit = _Fitter(model, data, w, q)
            est, _ok = fit.fit(th, np.array(base, dtype=int), scale, max_nfev)
            _, r, _ = fit.residual(est, jacobian=False)
            crit.append(float(r @ r) + len(base) * float(np.log(n_eq)))
        pick = int(np.argmin(crit))
        selection = {"method": "Bayesian information criterion (chi2 + p ln n, the file's noise model)",
                     "sizes": sizes, "criterion": crit, "cv_rms": None, "chosen": sizes[pick],
                     "order": [model.names[j] for j in order]}
        return selection, (None if sizes[pick] == g else order[:sizes[pick]])
    poses = list(dict.fromkeys(data.pose_id))
    k = min(folds, len(poses))
    fold_of_pose = {p: i % k for i, p in enumerate(poses)}
    fold = np.array([fold_of_pose[p] for p in data.pose_id])
    cv = []
    for size in sizes:
        base = sorted(setup + order[:size])
        sq, n = 0.0, 0
        for f in range(k):
            train, test = fold != f, fold == f
            th = theta.copy()
            others = [j for j in chosen if j not in base]
            th[others] = theta_prior[others]
            fit = _Fitter(model, data.subset(train), w[train], q[train])
            try:
                est, _ok = fit.fit(th, np.array(base, dtype=int), scale, max_nfev)
            except np.linalg.LinAlgError:
                est = th
            pred = model.predict(est, data.subset(test))
            sq += float(np.sum((pred.position - data.position[test]) ** 2))
            n += int(test.sum())
        cv.append(float(np.sqrt(sq / max(n, 1))))
    best = min(cv)
    pick = next(i for i, v in enumerate(cv) if v <= 1.02 * best)
    selection = {"method": f"{k}-fold cross-validation over poses", "folds": k, "sizes": sizes, "cv_rms": cv,
                 "chosen": sizes[pick], "order": [model.names[j] for j in order]}
    return selection, (None if sizes[pick] == g else order[:sizes[pick]])


def _nominal_error(model: MeasurementModel, data: MeasurementSet, validation: MeasurementSet | None,
                   theta: np.ndarray, w: np.ndarray, scale: np.ndarray, preferred: list, q: np.ndarray,
                   rank_tol: float, max_nfev: int) -> dict:
    """The nominal model's error: tracker frame and target offsets fitted, geometry nominal."""
    fitter = _Fitter(model, data, w, q)
    _, _, j = fitter.residual(theta)
    js = j[:, preferred] * scale[preferred]
    sub, _, _, _ = base_parameters(js, list(range(len(preferred))), rank_tol)
    idx = np.array([preferred[i] for i in sub], dtype=int)
    est, _ok = fitter.fit(theta.copy(), idx, scale, max_nfev)
    p, r, _ = fitter.residual(est, jacobian=False)
    resid = p.position - data.position
    dof = max(len(r) - len(idx), 1)
    out = {"identification": error_stats(resid), "validation": None, "sigma": float(np.sqrt(float(r @ r) / dof)),
           "fitted": [model.names[i] for i in idx]}
    if validation is not None and len(validation):
        vp = model.predict(est, validation)
        out["validation"] = error_stats(vp.position - validation.position)
    return out


def _trust_warnings(data: MeasurementSet, validation, sigma: float, converged: bool, table: list,
                    val_stats: dict | None, nominal: dict | None, resid: np.ndarray, quality: str = "ok",
                    length_scale: float = 1.0) -> list:
    """Loud warnings: wrong inputs, a model that misses an effect, divergence, outliers, a calibration worse
    than the nominal model (the words follow :func:`fit_quality`)."""
    out = []
    if not converged:
        out.append("THE FIT DID NOT CONVERGE (the cost rose or the iteration limit was hit): the estimates are not "
                   "a least-squares solution; check the joint map, the units and the targets.")
    rms = error_stats(resid)["rms"]
    size = f"RMS {rms:.4g} mm, {100 * rms / length_scale:.2g} % of the machine's size"
    if quality == "inputs wrong":
        times = f"the residuals are {sigma:.3g} times the stated noise; " if data.noise is not None else ""
        out.append(f"ABSURD FIT: sigma = {sigma:.3g} ({times}{size}). The inputs are wrong, not the model: a wrong "
                   f"joint map (sign, offset, coupling such as FANUC's q3 = J3 + J2), wrong units, several targets "
                   f"stacked in one column, or a moved tracker. Do not use this calibration.")
    elif quality == "model misses an effect":
        gain = ""
        if nominal is not None and val_stats is not None and nominal.get("validation") is not None:
            before, after = nominal["validation"]["rms"], val_stats["rms"]
            change = "cuts" if after <= before else "raises"
            gain = (f" The calibration {change} the held-out error by {100 * abs(before - after) / before:.0f} % "
                    f"({before:.4g} -> {after:.4g} mm).")
        out.append(f"MODEL MISSES AN EFFECT: sigma = {sigma:.3g} (the residuals are {sigma:.3g} times the stated "
                   f"noise; {size}). The inputs look right (a wrong joint map or unit gives sigma in the hundreds and "
                   f"errors of a link's size), but the rigid model misses something (compliance, a gear error, "
                   f"temperature) or the stated noise is too small.{gain} Run `hyperstat diagnose` on the same files "
                   f"to find what is missing before using this calibration.")
    n_out = sum(r["outlier"] for r in table)
    if n_out:
        worst = sorted((r for r in table if r["outlier"]), key=lambda r: -r["robust_z"])[:5]
        out.append(f"{n_out} observation(s) flagged as outliers (robust z > {OUTLIER_Z}): "
                   + ", ".join(f"{r['pose']}{'/' + r['target'] if r['target'] else ''} (z = {r['robust_z']:.1f})"
                               for r in worst) + ".")
    if nominal is not None and val_stats is not None and nominal.get("validation") is not None:
        before, after = nominal["validation"]["rms"], val_stats["rms"]
        if after > before:
            out.append(f"CALIBRATION MAKES HELD-OUT POSES WORSE: validation RMS {after:.4g} mm calibrated against "
                       f"{before:.4g} mm with the nominal model (only the tracker frame and targets fitted). "
                       f"Too few poses for the parameters (over-fitting), or data the model does not describe: "
                       f"keep the nominal model, add poses, or identify fewer parameters (--select-size).")
    return out
