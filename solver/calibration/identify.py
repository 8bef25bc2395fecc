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

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics, batched_lstsq
from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.frames import so3_exp, so3_left_jacobian, so3_log, skew
from hyperstat.solver.calibration.fit_checks import (FIT_QUALITY, MAX_CONDITION, MIN_EQUATIONS_PER_PARAMETER,
                                                     POSE_EQUATIONS, SIGMA_INPUTS, SIGMA_WARN, SIZE_INPUTS,
                                                     TARGET_SEPARATION_MM, coinciding_targets, equation_count,
                                                     fit_quality, joint_region, noise_ratios, target_label,
                                                     target_stats)
from hyperstat.solver.calibration.measurements import MeasurementSet
from hyperstat.solver.calibration.outliers import (COPY_FRACTION, FAMILY_ALPHA, chi2_median, coincident_across,
                                                   coincident_poses, copied_reading, deleted_residual_test, threshold)
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.analysis.stationarity import StationarityResult
from hyperstat.solver.threads import limited_blas

__all__ = ["MeasurementModel", "Prediction", "IdentificationResult", "identify", "error_stats", "kabsch", "register_targets",
           "observability_indices", "fit_quality", "worse_than_nominal", "FIT_QUALITY", "SIGMA_WARN", "SIGMA_INPUTS",
           "SIZE_INPUTS"]

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
            res = self._on_nominal_branch(qa, xi)
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

    def _on_nominal_branch(self, qa: np.ndarray, xi: np.ndarray):
        """Assembly at actuated values ``qa`` with defects ``xi``, on the branch of the nominal machine.

        The nominal geometry is followed from home by continuation (kept for the last few sets of poses), then the
        defects are added at each pose by an assembly from there; poses where that assembly does not close are
        followed from home with the defects.  Following the defective geometry from home instead can leave the
        nominal branch where the defects break a mobility that only the nominal geometry has: the corpus' Bricard
        line, whose identified geometry assembled 8 of 30 held-out poses nowhere and the others up to 150 mm away,
        while from the nominal configurations every one closes and is predicted to the noise.
        """
        kin = self.kin
        nominal = self._nominal_assembly(qa)
        if not np.any(xi):  # a copy: the caller marks the poses it keeps
            return dataclasses.replace(nominal, q=nominal.q.copy(), residual=nominal.residual.copy(),
                                       converged=nominal.converged.copy())
        start, closed = nominal.q, nominal.residual <= 1e-2 * kin.length_scale
        res = kin.assemble(start.copy(), xi)
        redo = ~closed | (res.residual > 1e-2 * kin.length_scale)
        if np.any(redo):
            again = kin.solve(qa[redo], xi)
            res.q[redo] = again.q
            res.residual[redo] = again.residual
        return res

    def _nominal_assembly(self, qa: np.ndarray):
        """The nominal machine assembled at actuated values ``qa`` by continuation from home, kept for the last four
        sets of poses on the kinematics: the models of one mechanism that share it (a diagnosis' pooled fits of
        every candidate effect, each starting from the nominal geometry) follow the same machine to the same poses.
        """
        kin = self.kin
        memo = kin.__dict__.setdefault("_nominal_assemblies", {})
        k = (qa.shape, qa.tobytes())
        if k not in memo:
            if len(memo) >= 4:
                memo.pop(next(iter(memo)))
            memo[k] = kin.solve(qa, np.zeros(kin.n_xi))
        return memo[k]

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
        Directions numerically independent at the solution kept out of the base set: their
        standard errors exceed 1 % of the machine's size (:func:`undetermined_directions`, no
        refit; their number in ``undetermined_directions``), or their fit did not explain
        significantly more (chi-square test of the nested fits); ``reason`` says which.
    converged : bool
        Whether the fit converged (cost not increased, iteration limit not hit).
    fit_quality : str
        Machine-readable severity of the fit (:func:`fit_quality`): ``"ok"``, ``"model misses
        an effect"`` (sigma, or the residuals of a target on the fitted or held-out poses, a few
        times the stated noise: run the diagnosis) or ``"inputs wrong"`` (in the hundreds, or
        residuals of a link's size: joint map, units, targets copied or stacked); export
        commands refuse the last two without ``--force``.
    findings : list of dict
        What the numbers say, worst first: ``code``, ``message`` (the warning), ``refuses`` and
        ``reason`` (what the export gate says when it refuses); notes (``refuses`` false) are
        passed on all the same.  ``warnings`` holds the messages.
    targets : dict
        Per target (``"target"`` for a single unnamed one): ``identification`` and ``validation``
        stats of its 3-D residual norms with the ``noise_rms`` its rows state (mm).
    noise_ratios : dict
        ``identification`` and ``validation``: per target, RMS residual over RMS noise;
        ``reference``: ``"stated noise"`` or ``"fit"`` (no noise stated: the fit's residual scale).
    equations : dict
        :func:`~hyperstat.solver.calibration.fit_checks.equation_count` of the fit.
    distinct_poses : int
        Poses once repeats within the noise are counted once.
    repeated_poses : list of list of str
        Groups of poses that repeat one another within the noise.
    region : dict
        :func:`~hyperstat.solver.calibration.fit_checks.joint_region` of the identification poses.
    excluded : list of dict
        Observations excluded as outliers on request (``set, pose, target, deleted_z, norm``).
    outlier_scale : float
        Robust scale of the outlier test (weighted units).
    without_outliers : dict or None
        When outliers are flagged: the fit without them, as ``--exclude-outliers`` makes it
        (``excluded``, ``fit_quality``, ``sigma``, ``identification_rms`` and ``validation_rms`` in mm);
        the outliers named are those it takes out, one at a time, the worst first.
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
    findings: list = field(default_factory=list)
    targets: dict = field(default_factory=dict)
    noise_ratios: dict | None = None
    equations: dict | None = None
    distinct_poses: int | None = None
    repeated_poses: list = field(default_factory=list)
    region: dict | None = None
    excluded: list = field(default_factory=list)
    outlier_scale: float | None = None
    without_outliers: dict | None = None

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
            "noise_ratios": self.noise_ratios,
            "targets": self.targets,
            "equations": self.equations,
            "distinct_poses": self.distinct_poses,
            "repeated_poses": self.repeated_poses,
            "region": self.region,
            "excluded": self.excluded,
            "without_outliers": self.without_outliers,
            "findings": [{k: v for k, v in f.items()} for f in self.findings],
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
        out = ["set,pose,target,dx[mm],dy[mm],dz[mm],norm[mm],weighted_norm,robust_z,deleted_z,outlier"]
        for label, table in (("identification", self.residual_table), ("validation", self.validation_table)):
            for r in table:
                out.append(f"{label},{r['pose']},{r['target']},{r['dx']:.9g},{r['dy']:.9g},{r['dz']:.9g},"
                           f"{r['norm']:.9g},{r['weighted_norm']:.6g},{r['robust_z']:.4g},{r['deleted_z']:.4g},"
                           f"{int(r['outlier'])}")
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


def undetermined_directions(js: np.ndarray, r: np.ndarray, base: list, added: list, kinds: list, units: list, s2: float,
                            length_scale: float, limit: float = SIZE_INPUTS) -> tuple[list, list, float]:
    """Geometry columns that joined the base set at the solution but that the data do not determine.

    A machine whose nominal geometry makes some defects invisible (a hexapod's spherical and
    universal joints: the rotations about their centres) sees them again at a perturbed solution,
    through second-order terms: their columns are of the order of the defects times the first-order
    ones, so that the singular values they add form a continuum (the hexapod: 1.7e-5 down to
    2.6e-8 of the largest, no gap) which the rank threshold splits at random, and the direction of
    each such column, normalised, is set by the last digits of the assembled configurations (the
    assembly's convergence tolerance).  Numerically independent, they are not identified: their
    standard errors are metres and radians.  A column added at the solution is kept only while its
    standard error (linearised, ``sqrt(s2 (J^T J)^-1)`` of the set with it, physical units) is within
    ``limit`` of the machine's length scale (an angle: ``limit`` rad), the line beyond which
    :func:`fit_quality` calls residuals absurd; the worst is removed first, then the others are
    judged again.  One QR of the Jacobian at the solution per removal, no model evaluation.

    Parameters
    ----------
    js : ndarray, (m, n)
        Column-scaled weighted Jacobian at the solution.
    r : ndarray, (m,)
        Weighted residual at the solution.
    base : list of int
        The base set decided at the solution.
    added : list of int
        Its columns that the set fitted so far did not hold.
    kinds, units : list of str
        Kind and unit of every column (only ``"geometry"`` columns in mm or rad are judged).
    s2 : float
        Variance of the weighted residuals (1 with a stated noise).
    length_scale : float
        Machine's length scale (mm); also the column scale of the angles.
    limit : float
        Largest standard error, as a share of the length scale (mm) or in rad.

    Returns
    -------
    base : list of int
        The base set without the undetermined columns (sorted).
    dropped : list of int
        The columns removed, in the order removed.
    chi2 : float
        Linearised decrease of the weighted sum of squares the removed columns would have given on
        top of the others (the score statistic at the solution), for the record.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> a = rng.normal(size=(60, 2))
    >>> js = np.c_[a, a[:, 0] + 1e-9 * rng.normal(size=60)]  # a third column all but equal to the first
    >>> undetermined_directions(js, rng.normal(size=60), [0, 1, 2], [2], ["geometry"] * 3, ["mm"] * 3, 1.0, 1000.0)[:2]
    ([0, 1], [2])
    """
    import scipy.linalg  # imported here: import hyperstat.solver stays fast

    base = sorted(base)
    start = list(base)
    judged = [j for j in added if kinds[j] == "geometry" and units[j] in ("mm", "rad")]
    dropped: list[int] = []
    while judged:
        jb = js[:, base]
        norms = np.linalg.norm(jb, axis=0).clip(min=1e-300)
        _, rr = np.linalg.qr(jb / norms)
        rinv = scipy.linalg.solve_triangular(rr, np.eye(len(base)))
        std = np.sqrt(s2 * np.sum(rinv ** 2, axis=1)) / norms  # of the scaled unknowns: mm, rad / length scale
        ratio = {j: float(std[base.index(j)]) * length_scale / limit if units[j] == "rad" else
                 float(std[base.index(j)]) / (limit * length_scale) for j in judged}
        worst = max(judged, key=lambda j: (ratio[j], -j))
        if not ratio[worst] > 1.0:
            break
        base.remove(worst)
        judged.remove(worst)
        dropped.append(worst)
    chi2 = 0.0
    if dropped:
        kept = [j for j in start if j not in dropped]
        qk, _ = np.linalg.qr(js[:, kept])
        e = js[:, dropped] - qk @ (qk.T @ js[:, dropped])
        qe, _ = np.linalg.qr(e / np.linalg.norm(e, axis=0).clip(min=1e-300))
        chi2 = float(np.sum((qe.T @ r) ** 2))
    return base, dropped, chi2


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


#: Why directions independent at the solution stay out of the base set (``held_back["reason"]``).
HELD_BACK_REASONS = {
    "not significant": "numerically independent at the solution but not significant (chi-square test, 0.1 %): "
                       "held at their prior",
    "undetermined": "numerically independent at the solution but not determined by the data (standard error "
                    "beyond 1 % of the machine's length scale, or 0.01 rad; second-order directions of a perturbed "
                    "geometry): held at their prior without a refit; chi2_decrease is the linearised one",
    "both": "numerically independent at the solution: undetermined_directions of them not determined by the data "
            "(standard error beyond 1 % of the machine's length scale, or 0.01 rad), held without a refit; the others "
            "not significant (chi-square test, 0.1 %); chi2_decrease is the fitted one of the others"}
HELD_OUT_NOTE = 1.5  #: held-out noise ratio above which an "ok" fit gets a note (not a refusal) pointing at diagnose
MAX_EXCLUDED = 20  #: most observations --exclude-outliers takes out (beyond, the campaign itself is suspect)
OUTLIER_Z = 3.5  #: modified z-score (Iglewicz and Hoaglin) reported per observation as ``robust_z`` (informative)


def residual_table(data: MeasurementSet, resid: np.ndarray, w: np.ndarray) -> list:
    """Per-observation residuals (mm) with two outlier statistics.

    ``robust_z``: the weighted residual norm ``|r| / sigma`` of each observation against the
    median of all of them through the median absolute deviation (MAD, scaled by 1.4826 so that
    it estimates a standard deviation), ``z = (e - median) / (1.4826 MAD)`` (Iglewicz and
    Hoaglin's modified z-score; informative).  ``deleted_z`` and ``outlier`` are filled by
    :func:`identify`: the normalised residual with the observation left out and the flag of the
    test of :mod:`hyperstat.solver.calibration.outliers` (the one the export gate reads).
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
             "deleted_z": 0.0, "outlier": False} for i in range(len(e))]


def orientation_residual(rotation: np.ndarray, data: MeasurementSet) -> np.ndarray:
    """Orientation error ``log(R_pred R_meas^T)`` (rotation vectors in the tracker frame, rad), (K, 3)."""
    return so3_log(rotation @ np.swapaxes(so3_exp(data.rotation), -1, -2))


#: Largest change of a joint between two evaluations of a fit (rad; a slider's in units of the machine's length
#: scale) with which the new configuration of a pose becomes its next start.  A trial step of the fit can move the
#: geometry far enough for a pose to assemble on another branch (the corpus' RSSR: its rocker 1.4 rad away at every
#: pose); such a configuration must not start the next evaluations, or the fit's cost depends on the path and not on
#: its parameters alone, and the fit wanders off the machine's branch.
BRANCH_JUMP = 0.1


class _Fitter:
    """Weighted least squares over a subset of the parameters (Gauss-Newton, then MINPACK LM)."""

    def __init__(self, model: MeasurementModel, data: MeasurementSet, w: np.ndarray, q: np.ndarray) -> None:
        self.model, self.data, self.w = model, data, w
        self.q = q
        self.evaluations = 0
        kin = model.kin
        self._joint_unit = np.array([1.0 if j.type == "R" else max(kin.length_scale, 1e-12)
                                     for j in model.mechanism.joints])

    def _continued(self, q: np.ndarray) -> np.ndarray:
        """The next evaluation's start: ``q`` at the poses that moved continuously (:data:`BRANCH_JUMP`), the
        current start at those that jumped."""
        moved = np.max(np.abs(q - self.q) / self._joint_unit, axis=1)
        stayed = moved <= BRANCH_JUMP
        if stayed.all():
            return q
        out = self.q.copy()
        out[stayed] = q[stayed]
        return out

    def residual(self, theta: np.ndarray, jacobian: bool = True):
        """Prediction, weighted residual and weighted Jacobian (position rows, then orientation rows)."""
        p = self.model.predict(theta, self.data, jacobian=jacobian, q_start=self.q)
        if p.converged.all():
            self.q = self._continued(p.q)
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
    exclude_outliers: bool = False,
    _excluded: list | None = None,
    outlier_probe: bool = True,
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
    exclude_outliers : bool
        Refit without the observations the outlier test flags (identification and held-out),
        again until none is flagged; the excluded ones are listed in ``excluded`` (never removed
        otherwise: a flagged outlier stops an export).
    outlier_probe : bool
        When an observation is flagged and ``exclude_outliers`` is off, refit without the worst ones to say which
        are outliers (``without_outliers``, the ``outlier`` flags of the tables): a second identification.  A caller
        that reads neither (the diagnosis) turns it off; the fit itself is the same.

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
    early: list[dict] = []  # findings made before the end of the fit
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
    r_now = None
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
        if chosen is not None and imposed is None:
            # geometry directions that joined at the solution but that the data do not determine (second-order
            # ones, standard errors beyond 1 % of the machine): held at their prior without a refit, which would
            # creep along them (hundreds of evaluations) to a point set by round-off
            s2 = 1.0 if data.noise is not None else cost / max(n_rows - len(chosen), 1)
            base_idx, undetermined, chi2_lin = undetermined_directions(
                js, r_now, base_idx, [j for j in base_idx if j not in chosen], model.kinds, model.units, s2,
                model.kin.length_scale)
            if undetermined:
                held_back = (rank, len(undetermined), chi2_lin, "undetermined", len(undetermined))
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
                undetermined_before = held_back[4] if held_back is not None else 0
                held_back = (rank, extra + undetermined_before, float(previous[2] - new_cost),
                             "both" if undetermined_before else "not significant", undetermined_before)
                break
        converged = converged and ok
        cost, rank_used = new_cost, rank
        js = jw_all * scale
        if imposed is not None:
            rounds.append(rank)
            break
    else:
        early.append(_finding("fragile-rank", f"the identifiable set still changed after {max_rounds} rounds (ranks "
                                              f"{rounds}): the rank decision is fragile at this solution; read the "
                                              f"singular-value gap.",
                              f"its identifiable set still changed after {max_rounds} rounds (ranks {rounds}): the rank "
                              f"decision is fragile"))
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
            early.append(_finding("model-size", f"small data ({n_rows} equations): {selection['method']} kept "
                                                f"{selection['chosen']} of {selection['sizes'][-1]} geometry parameters; "
                                                f"the others are held at their nominal value."))
    base_list = list(chosen)
    base_idx = np.array(base_list, dtype=int)
    unident = _unidentifiable(model, js, base_list, visible, scale)
    if selection is not None and selection["chosen"] < selection["sizes"][-1]:
        left = set(selection["order"][selection["chosen"]:])
        for u in unident:
            if u["name"] in left:
                u["reason"] = "left out by the model-size selection (cross-validation); " + u["reason"]
    final, rw, jw_all = fitter.residual(theta)
    twists = model.actuation_jacobian()
    resid = final.position - data.position
    jw = jw_all[:, base_idx]
    # poses repeated within the noise count once (issue 37): their rows share one weight
    sigma_axis = _sigma_rows(data)
    unweighted = sigma_axis is None
    if unweighted:  # no stated noise: the fit's own residual scale per axis (mm)
        sigma_axis = np.full(len(data), float(np.sqrt(rw @ rw / max(len(rw) - len(base_list), 1))))
    act = model.mechanism.actuated
    width = np.ptp(model.mechanism.ranges[act], axis=1)
    groups = coincident_poses(data, twists, sigma_axis, width, model.kin.length_scale) if twists is not None else []
    copies = {p: len(g) for g in groups for p in g}
    row_factor = np.array([1.0 / copies.get(p, 1) for p in data.pose_id])
    c = np.tile(np.repeat(row_factor, 3), 2 if oriented else 1)
    dof = max(float(c.sum()) - len(base_list), 1.0)
    sigma2 = float((c * rw) @ rw / dof)
    jtj = jw.T @ (c[:, None] * jw)
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
    sigma = float(np.sqrt(sigma2))
    # outliers: each observation judged with itself (and its repeats) left out
    blocks, block_rows = _observation_blocks(data, groups, oriented)
    t2, out_scale, flagged = deleted_residual_test(rw, jw, blocks, not unweighted)
    table = residual_table(data, resid, w)
    limit = threshold(3 * (2 if oriented else 1), len(blocks))
    for b, rows in enumerate(block_rows):
        for i in rows:
            table[i]["deleted_z"] = float(np.sqrt(t2[b]))
            table[i]["outlier"] = bool(flagged[b])
    _systematic_not_outliers(table)
    val_stats = None
    val_res = None
    val_table: list = []
    val_targets = None
    repeated_held_out: list = []
    vp = None
    if validation is not None and len(validation):
        vp = model.predict(theta, validation)
        val_res = vp.position - validation.position
        val_stats = error_stats(val_res)
        val_table = residual_table(validation, val_res, _weights(validation))
        val_sigma = _sigma_rows(validation)
        val_targets = target_stats(validation, val_res, val_sigma)
        # held-out residuals are prediction errors already; their scale is their own robust one (a model that
        # predicts every held-out pose badly is judged by the noise ratios, not called a set of outliers), never
        # below the identification's
        vw = np.linalg.norm(val_res, axis=1) / (1.0 if unweighted else
                                                (val_sigma if val_sigma is not None else sigma_axis.mean()))
        val_scale = max(out_scale, float(np.sqrt(np.median(vw**2) / chi2_median(3))))
        limit_v = threshold(3, len(vw))
        for i, r in enumerate(val_table):
            r["deleted_z"] = float(vw[i] / val_scale)
            # held-out poses are judged against a fit free of identification outliers: one that pulls the fit also
            # spoils the prediction at nearby held-out poses (they are judged again once it is excluded)
            r["outlier"] = bool(vw[i] ** 2 / val_scale ** 2 > limit_v) and not any(t["outlier"] for t in table)
        _systematic_not_outliers(val_table)
        if twists is not None:
            repeated_held_out = coincident_across(data, validation, twists, sigma_axis, width, model.kin.length_scale)
    orientation = None
    if oriented:
        ang = np.linalg.norm(orientation_residual(final.rotation, data), axis=1)
        orientation = {"identification": _angle_stats(ang), "validation": None,
                       "noise_rms": float(np.sqrt(3.0) * data.rotation_noise)}
        if vp is not None and validation.rotation is not None:
            orientation["validation"] = _angle_stats(np.linalg.norm(orientation_residual(vp.rotation, validation),
                                                                    axis=1))
    nominal_doc = nominal_sq = None
    if nominal:
        nominal_doc = _nominal_error(model, data, validation, theta_prior, w, scale, preferred, fitter.q, rank_tol,
                                     max_nfev)
        nominal_sq = nominal_doc.pop("_validation_sq", None)
    id_targets = target_stats(data, resid, None if unweighted else sigma_axis)
    reference = None if not unweighted else float(np.sqrt(3.0) * sigma)
    ratios = {"identification": noise_ratios(id_targets, reference),
              "validation": None if val_targets is None else noise_ratios(val_targets, reference),
              "reference": "fit" if unweighted else "stated noise"}
    judged = list(ratios["validation"].values()) if ratios["validation"] else []
    if not unweighted:
        judged += list(ratios["identification"].values())
    quality = fit_quality(sigma, error_stats(resid)["rms"], model.kin.length_scale, data.noise is not None, judged,
                          None if val_stats is None else val_stats["rms"])
    counts = equation_count(_rows_per_pose(data, groups, oriented), [model.kinds[b] for b in base_list])
    offsets, offset_cov = _target_offsets(model, theta, base_list, cov)
    context = {"data": data, "validation": validation, "sigma": sigma, "converged": converged, "table": table,
               "val_table": val_table, "val_stats": val_stats, "nominal": nominal_doc, "resid": resid,
               "val_sq": None if val_res is None else np.sum(val_res ** 2, axis=1), "nominal_sq": nominal_sq,
               "quality": quality, "length_scale": model.kin.length_scale, "ratios": ratios, "counts": counts,
               "condition": float(sv_b[0] / sv_b[-1]), "groups": groups, "repeated_held_out": repeated_held_out,
               "sigma_axis": sigma_axis,
               "coinciding": coinciding_targets(offsets, offset_cov) if len(offsets) > 1 else [],
               "unassembled": 0 if vp is None else int((~vp.converged).sum()), "limit": limit,
               "excluded": list(_excluded or [])}
    if outlier_probe and not exclude_outliers and any(r["outlier"] for r in table + val_table):
        # A gross error pulls a weakly conditioned fit far from the linear regime, and observations near it then look
        # out of line too (swamping).  Which ones are outliers is decided the way --exclude-outliers takes them out:
        # the worst first, the fit redone without it (nonlinear), the others judged again; only those taken out are
        # named (the calibration itself is left as fitted: nothing is removed without --exclude-outliers).
        drop, drop_v, gone = _exclusion_step(table, val_table, list(_excluded or []))
        probe = identify(mechanism, analysis, data.subset(~drop),
                         None if drop_v is None else validation.subset(~drop_v), effects=effects,
                         kinematics=kinematics, rank_tol=rank_tol, max_nfev=max_nfev, base=imposed, nominal=False,
                         max_rounds=max_rounds, select_size=select_size, folds=folds, exclude_outliers=True,
                         _excluded=gone)
        named = {(e["set"], str(e["pose"]), str(e["target"])) for e in probe.excluded}
        for name, rows in (("identification", table), ("validation", val_table)):
            for r in rows:
                r["outlier"] = (name, str(r["pose"]), str(r["target"])) in named
        context["without_outliers"] = {
            "excluded": probe.excluded, "fit_quality": probe.fit_quality, "sigma": probe.sigma,
            "identification_rms": probe.identification["rms"],
            "validation_rms": None if probe.validation is None else probe.validation["rms"]}
    findings = early + _findings(context)
    result = IdentificationResult(
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
        warnings=[f["message"] for f in findings],
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
            "reason": HELD_BACK_REASONS[held_back[3]], "undetermined_directions": held_back[4]},
        findings=findings,
        targets={name: {"identification": id_targets[name],
                        "validation": None if val_targets is None else val_targets.get(name)} for name in id_targets},
        noise_ratios=ratios,
        equations=counts,
        distinct_poses=data.n_poses - sum(len(g) - 1 for g in groups),
        repeated_poses=groups,
        region=joint_region(model.mechanism, data),
        excluded=list(_excluded or []),
        outlier_scale=out_scale,
        without_outliers=context.get("without_outliers"),
    )
    if exclude_outliers and len(result.excluded) < MAX_EXCLUDED and any(r["outlier"] for r in table + val_table):
        drop, drop_v, gone = _exclusion_step(table, val_table, result.excluded)
        return identify(mechanism, analysis, data.subset(~drop),
                        None if drop_v is None else validation.subset(~drop_v), effects=effects,
                        kinematics=kinematics, rank_tol=rank_tol, max_nfev=max_nfev, base=imposed,
                        nominal=nominal, max_rounds=max_rounds, select_size=select_size, folds=folds,
                        exclude_outliers=True, _excluded=gone)
    return result


def _exclusion_step(table: list, val_table: list, excluded: list) -> tuple:
    """What ``--exclude-outliers`` takes out next: the worst flagged identification observation (one at a time: a
    gross error pulls the fit and can make its neighbours look out of line; they are judged again without it), or,
    when none is, every flagged held-out one (they pull nothing).  Returns the masks of rows to drop from the
    identification and held-out sets (None without held-out data) and the excluded list so far."""
    worst = max((r["deleted_z"] for r in table if r["outlier"]), default=None)
    drop = np.array([bool(r["outlier"] and r["deleted_z"] == worst) for r in table], dtype=bool)
    drop_v = None if not val_table else np.array([bool(r["outlier"] and worst is None) for r in val_table],
                                                 dtype=bool)
    gone = list(excluded) + [
        {"set": name, "pose": r["pose"], "target": r["target"], "deleted_z": r["deleted_z"], "norm": r["norm"]}
        for name, rows, flags in (("identification", table, drop), ("validation", val_table, drop_v))
        if flags is not None for r, f in zip(rows, flags) if f]
    return drop, drop_v, gone


def _systematic_not_outliers(table: list, share: float = 0.25) -> None:
    """Unflag a target whose flagged observations are more than ``share`` of its own (at least 3): a whole target
    off is not a few gross errors but a target's data at fault (copied or stacked columns), which its noise ratio
    reports; excluding it observation by observation would hide that."""
    by_target: dict = {}
    for r in table:
        by_target.setdefault(r["target"], []).append(r)
    for rows in by_target.values():
        n = sum(r["outlier"] for r in rows)
        if n >= 3 and n > share * len(rows):
            for r in rows:
                r["outlier"] = False


def _observation_blocks(data: MeasurementSet, groups: list, oriented: bool) -> tuple[list, list]:
    """Residual rows of each observation (one target at one pose), repeats of one pose and target merged.

    Returns the blocks (arrays of rows of the weighted residual vector: 3 positions, then 3 orientations with
    6-D data) and, per block, the observations (rows of ``data``) it holds.
    """
    k = len(data)
    group_of = {p: g[0] for g in groups for p in g}
    members: dict = {}
    for i, (p, t) in enumerate(zip(data.pose_id, data.target_index)):
        members.setdefault((group_of.get(p, p), int(t)), []).append(i)
    blocks, rows = [], []
    for obs in members.values():
        idx = np.concatenate([np.arange(3 * i, 3 * i + 3) for i in obs])
        if oriented:
            idx = np.concatenate([idx, idx + 3 * k])
        blocks.append(idx)
        rows.append(obs)
    return blocks, rows


def _rows_per_pose(data: MeasurementSet, groups: list, oriented: bool) -> list:
    """Equation rows of each distinct pose (a group of repeated poses counted once, by its largest member)."""
    per = 6 if oriented else 3
    count: dict = {}
    for p in data.pose_id:
        count[p] = count.get(p, 0) + per
    group_of = {p: g[0] for g in groups for p in g}
    merged: dict = {}
    for p, n in count.items():
        key = group_of.get(p, p)
        merged[key] = max(merged.get(key, 0), n)
    return list(merged.values())


def _target_offsets(model: MeasurementModel, theta: np.ndarray, base: list, cov: np.ndarray) -> tuple[dict, dict]:
    """Identified target offsets (mm) and the covariance blocks between them (zero where not identified)."""
    offsets, where = {}, {}
    for t, name in enumerate(model.targets):
        cols = list(range(model.sl_target.start + 3 * t, model.sl_target.start + 3 * t + 3))
        offsets[target_label(name)] = theta[cols].tolist()
        where[target_label(name)] = [base.index(c) if c in base else None for c in cols]
    blocks = {}
    for a, ia in where.items():
        for b, ib in where.items():
            m = np.zeros((3, 3))
            for r, x in enumerate(ia):
                for cc, y in enumerate(ib):
                    if x is not None and y is not None:
                        m[r, cc] = cov[x, y]
            blocks[(a, b)] = m
    return offsets, blocks


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
        out["_validation_sq"] = np.sum((vp.position - validation.position) ** 2, axis=1)  # per observation (mm^2)
    return out


def worse_than_nominal(calibrated_sq: np.ndarray, nominal_sq: np.ndarray, level: float = 0.975) -> tuple[float, float]:
    """Whether the calibrated model predicts the held-out poses worse than the nominal one beyond chance.

    A paired test of the squared held-out errors of the two models at the same observations (mm^2):
    ``t = mean(d) / (std(d) / sqrt(n))``, ``d = |e_calibrated|^2 - |e_nominal|^2``, against Student's
    quantile of ``level`` with ``n - 1`` degrees of freedom.  Where the geometric defects move the target by less
    than the noise, the two models predict equally well and either wins by a few per cent by chance: that is
    no sign of over-fitting.

    Returns
    -------
    (t, critical) : float, float
        The statistic and the value it must exceed (``t = inf`` when every difference is equal and positive).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> a, b = rng.normal(size=30) ** 2, rng.normal(size=30) ** 2
    >>> t, critical = worse_than_nominal(a, b)  # two models alike: no significant difference
    >>> bool(t > critical)
    False
    >>> t, critical = worse_than_nominal(4.0 * a + 1.0, b)
    >>> bool(t > critical)
    True
    >>> from scipy.stats import t as student  # the quantile is Student's, as scipy.stats computes it
    >>> bool(abs(critical - student.ppf(0.975, 29)) < 1e-12)
    True
    """
    from scipy.special import stdtrit  # Student's quantile (scipy.stats would cost half a second of import)

    d = np.asarray(calibrated_sq, dtype=float) - np.asarray(nominal_sq, dtype=float)
    d = d[np.isfinite(d)]
    n = len(d)
    if n < 2:
        return (math.inf if n and d[0] > 0 else 0.0), math.inf
    spread = float(np.std(d, ddof=1))
    mean = float(np.mean(d))
    t = mean / (spread / math.sqrt(n)) if spread > 0 else (math.inf if mean > 0 else 0.0)
    return t, float(stdtrit(n - 1, level))


def _finding(code: str, message: str, reason: str | None = None, **details) -> dict:
    """One finding of a fit: ``code``, the warning ``message``, and the gate's ``reason`` (None: a note that
    does not stop an export, passed on all the same)."""
    return {"code": code, "refuses": reason is not None, "message": message, "reason": reason, **details}


def _observation_name(r: dict) -> str:
    return f"{r['pose']}/{r['target']}" if r["target"] else str(r["pose"])


def _worst(ratios: dict | None) -> tuple[str, float] | None:
    """The target with the largest noise ratio, or None."""
    items = [(k, v) for k, v in (ratios or {}).items() if v is not None]
    return max(items, key=lambda kv: kv[1]) if items else None


def _shown_worst(worst: tuple | None) -> tuple | None:
    """``(name, ratio)`` with the target named for a sentence: "the target" for a single unnamed one."""
    if worst is None:
        return None
    return ("the target" if worst[0] == "target" else f"target {worst[0]}", worst[1])


def _without(probe: dict | None) -> str:
    """`` (without them: ...)`` from the fit without the outliers, or nothing."""
    if not probe:
        return ""
    val = f", held-out RMS {probe['validation_rms']:.4g} mm" if probe["validation_rms"] is not None else ""
    return f" (without them: sigma {probe['sigma']:.3g}, fit quality {probe['fit_quality']}{val})"


def _findings(ctx: dict) -> list:
    """What the fit's numbers say about it, worst first (the words of :func:`fit_quality` and the gate's reasons).

    Every finding with a ``reason`` stops an export unless ``--force`` (:mod:`hyperstat.solver.export.calibration_gate`).
    """
    out = []
    data, sigma, quality, ratios = ctx["data"], ctx["sigma"], ctx["quality"], ctx["ratios"]
    flagged = [r for r in ctx["table"] if r["outlier"]]
    flagged_v = [r for r in ctx["val_table"] if r["outlier"]]
    pulled = ""
    if flagged or flagged_v:
        pulled = (f" {len(flagged) + len(flagged_v)} observation(s) are flagged as outliers (below): the fit without "
                  f"them may be sound (--exclude-outliers).")
    stated = data.noise is not None or getattr(data, "row_sigma", None) is not None
    noise_words = "the noise the data state" if stated else "the fit's own residual scale (the data state no noise)"
    rms = error_stats(ctx["resid"])["rms"]
    size = f"RMS {rms:.4g} mm, {100 * rms / ctx['length_scale']:.2g} % of the machine's size"
    val_stats, nominal = ctx["val_stats"], ctx["nominal"]
    if not ctx["converged"]:
        out.append(_finding("not-converged", "THE FIT DID NOT CONVERGE (the cost rose or the iteration limit was hit): "
                            "the estimates are not a least-squares solution; check the joint map, the units and the "
                            "targets.", "the fit did not converge (its estimates are not a least-squares solution)"))
    worst_val = _shown_worst(_worst(ratios["validation"]))
    worst_id = _shown_worst(_worst(ratios["identification"]) if stated else None)
    inputs = "a wrong joint map, wrong units, targets stacked in one column or a moved tracker"
    if quality == "inputs wrong":
        if rms > SIZE_INPUTS * ctx["length_scale"] or (stated and sigma >= SIGMA_INPUTS):
            times = f"the residuals are {sigma:.3g} times the stated noise; " if stated else ""
            message = (f"ABSURD FIT: sigma = {sigma:.3g} ({times}{size}). The inputs are wrong, not the model: a wrong "
                       f"joint map (sign, offset, coupling such as FANUC's q3 = J3 + J2), wrong units, several "
                       f"targets stacked in one column, or a moved tracker. Do not use this calibration.{pulled}")
            detail = (f"the residuals are {sigma:.3g} times {noise_words}" if stated else f"the residuals reach {size}")
        else:
            which, (name, r) = ("held-out", worst_val) if worst_val and (
                worst_val[1] >= SIGMA_INPUTS or val_stats["rms"] > SIZE_INPUTS * ctx["length_scale"]) else \
                ("identification", worst_id)
            v = ctx["val_stats"] if which == "held-out" else error_stats(ctx["resid"])
            message = (f"ABSURD FIT: the {which} residuals of {name} are {r:.3g} times {noise_words} (RMS "
                       f"{v['rms']:.4g} mm, {100 * v['rms'] / ctx['length_scale']:.2g} % of the machine's size; "
                       f"sigma on the fitted poses {sigma:.3g}). The inputs are wrong, not the model: one target's "
                       f"columns copied from another's or several stacked in one column, a wrong joint map, wrong "
                       f"units, a moved tracker, or held-out poses of another machine. Do not use this calibration."
                       f"{pulled}")
            detail = f"the {which} residuals of {name} are {r:.3g} times {noise_words}"
            inputs = ("one target's columns copied from another's, targets stacked in one column, a wrong joint map, "
                      "wrong units or a moved tracker")
        with_outliers = " with the outliers in" if pulled else ""
        out.append(_finding("inputs-wrong", message, f"identify calls the fit absurd{with_outliers}: {detail} (the "
                                                     f"inputs are wrong: {inputs})"))
    elif quality == "model misses an effect":
        gain = ""
        if nominal is not None and val_stats is not None and nominal.get("validation") is not None:
            before, after = nominal["validation"]["rms"], val_stats["rms"]
            change = "cuts" if after <= before else "raises"
            gain = (f" The calibration {change} the held-out error by {100 * abs(before - after) / before:.0f} % "
                    f"({before:.4g} -> {after:.4g} mm).")
        held = ""
        if worst_val is not None:
            held = f"; on the held-out poses {worst_val[1]:.3g} times it ({worst_val[0]})"
        if stated and sigma > SIGMA_WARN:
            message = (f"MODEL MISSES AN EFFECT: sigma = {sigma:.3g} (the residuals are {sigma:.3g} times the stated "
                       f"noise{held}; {size}). The inputs look right (a wrong joint map or unit gives sigma in the "
                       f"hundreds and errors of a link's size), but the rigid model misses something (compliance, a "
                       f"gear error, temperature) or the stated noise is too small.{gain} Run `hyperstat diagnose` on "
                       f"the same files to find what is missing before using this calibration.{pulled}")
            detail = f"its residuals are {sigma:.3g} times the noise the data state{held}"
        else:
            name, r = worst_val if worst_val and worst_val[1] > SIGMA_WARN else worst_id
            message = (f"MODEL MISSES AN EFFECT: on the held-out poses the residuals of {name} are {r:.3g} times "
                       f"{noise_words} (sigma on the fitted poses {sigma:.3g}; held-out RMS {val_stats['rms']:.4g} mm). "
                       f"The calibrated model does not predict poses it was not fitted to: an effect the fit absorbed "
                       f"on its own poses (compliance, a gear error, temperature), too few poses for the parameters, "
                       f"or held-out noise larger than stated.{gain} Run `hyperstat diagnose` on the same files before "
                       f"using this calibration." if worst_val and worst_val[1] > SIGMA_WARN else
                       f"MODEL MISSES AN EFFECT: the residuals of {name} are {r:.3g} times {noise_words} ({size}): the "
                       f"rigid model misses something for that target, or its noise is understated.{gain} Run "
                       f"`hyperstat diagnose` on the same files before using this calibration.")
            detail = f"the {'held-out ' if worst_val and worst_val[1] > SIGMA_WARN else ''}residuals of {name} are " \
                     f"{r:.3g} times {noise_words}"
        out.append(_finding("effect-missing", message,
                            f"{detail}{' with the outliers in' if pulled else ''}: the calibrated model is not what "
                            f"the data say the machine is (an effect it "
                            f"lacks: run 'hyperstat diagnose' and export with --diagnose or --effect; or too few poses; "
                            f"or the noise understated)"))
    if quality == "ok" and worst_val is not None and worst_val[1] > HELD_OUT_NOTE:
        out.append(_finding(
            "held-out-above-noise",
            f"the held-out residuals of {worst_val[0]} are {worst_val[1]:.3g} times {noise_words} (a calibration that "
            f"describes the machine gives about 1.0-1.3 on held-out poses): an effect the rigid model lacks may remain; "
            f"`hyperstat diagnose` on the same files tells."))
    counts = ctx["counts"]
    if not counts["enough"]:
        out.append(_finding(
            "too-few-equations",
            f"only {counts['equations']} equations for {counts['parameters']} parameters ({counts['machine_equations']} "
            f"from {counts['poses']} distinct poses for the machine's {counts['machine_parameters']}, at most "
            f"{POSE_EQUATIONS} a pose): expect poor accuracy; at least {MIN_EQUATIONS_PER_PARAMETER:g} equations per "
            f"parameter are needed, i.e. at least {counts['min_poses']} poses like these.",
            f"it has {counts['per_parameter']:.2g} equations per identified parameter ({counts['equations']} for "
            f"{counts['parameters']}, {counts['poses']} distinct poses), fewer than the "
            f"{MIN_EQUATIONS_PER_PARAMETER:g} needed: give at least {counts['min_poses']} poses"))
    if ctx["condition"] > MAX_CONDITION:
        out.append(_finding(
            "poor-conditioning",
            f"POORLY CONDITIONED: condition number {ctx['condition']:.3g} (scaled columns) above {MAX_CONDITION:.0e}: "
            f"the weakest identified combination is fitted from the noise; spread the poses over the workspace "
            f"(simulate --select d-optimal shows how) or identify fewer parameters.",
            f"its condition number {ctx['condition']:.3g} exceeds {MAX_CONDITION:.0e} (the weakest identified "
            f"combination is fitted from the noise)"))
    for c in ctx["coinciding"]:
        a, b = c["targets"]
        out.append(_finding(
            "coinciding-targets",
            f"TARGETS COINCIDE: {a} and {b} are identified {c['distance_mm']:.3g} mm apart (three standard deviations "
            f"or {TARGET_SEPARATION_MM:g} mm: {c['limit_mm']:.3g} mm); two reflectors cannot share a point: one "
            f"target's columns are likely a copy of the other's.",
            f"targets {a} and {b} coincide ({c['distance_mm']:.3g} mm apart): one's columns are likely a copy of the "
            f"other's", targets=[a, b]))
    groups = ctx["groups"]
    sigma_min = float(np.min(ctx["sigma_axis"])) if len(ctx["sigma_axis"]) else 0.0
    if groups:
        # a pose measured again at one place is two independent readings; a row copied is one reading counted twice
        copied = [g for g in groups if any(copied_reading(data, a, data, b, sigma_min) for i, a in enumerate(g)
                                           for b in g[i + 1:])]
        extra = sum(len(g) - 1 for g in groups)
        shown = ", ".join(" = ".join(g) for g in (copied or groups)[:4]) + (", ..." if len(copied or groups) > 4
                                                                            else "")
        if copied:
            out.append(_finding(
                "repeated-poses",
                f"REPEATED POSES: {extra} of {data.n_poses} poses repeat others within the noise (same metadata, "
                f"actuated values that move the target by less than one standard deviation), {len(copied)} group(s) "
                f"with the same reading to {COPY_FRACTION:g} of the noise, a row copied: {shown}. They are counted "
                f"once for sigma and the standard deviations ({data.n_poses - extra} distinct poses); a copied row is "
                f"not an independent measurement.",
                f"{extra} of its {data.n_poses} poses repeat others within the noise ({shown}), readings copied: they "
                f"are not independent measurements", groups=groups))
        else:
            out.append(_finding(
                "poses-measured-again",
                f"{extra} of {data.n_poses} poses were measured again within the noise of others (same metadata, "
                f"actuated values that move the target by less than one standard deviation, readings that differ as "
                f"independent ones do): {shown}. They are counted once for sigma and the standard deviations "
                f"({data.n_poses - extra} distinct poses), which understates what they add.", groups=groups))
    if ctx["repeated_held_out"]:
        pairs = ctx["repeated_held_out"]
        copied = [(v, i) for v, i in pairs if copied_reading(ctx["validation"], v, data, i, sigma_min)]
        n_held = ctx["validation"].n_poses
        shown = ", ".join(f"{v} = {i}" for v, i in (copied or pairs)[:4]) + (", ..." if len(copied or pairs) > 4
                                                                              else "")
        if copied or 2 * len({v for v, _ in pairs}) > n_held:
            why = (f"{len(copied)} with the fitted pose's reading copied" if copied else
                   f"more than half of the {n_held} held-out poses")
            out.append(_finding(
                "held-out-repeats-fitted",
                f"HELD-OUT POSES REPEAT FITTED ONES: {len(pairs)} validation pose(s) coincide with identification "
                f"poses within the noise ({shown}; {why}); they do not test the calibration on poses it was not fitted "
                f"to.",
                f"{len(pairs)} held-out pose(s) repeat identification poses ({shown}; {why}), so the validation is not "
                f"held out", pairs=[list(p) for p in pairs]))
        else:
            out.append(_finding(
                "held-out-measured-again",
                f"{len(pairs)} of the {n_held} held-out poses were measured within the noise of fitted ones ({shown}; "
                f"readings that differ as independent ones do): there the held-out residual tests the noise, not the "
                f"model between poses; the others test it.", pairs=[list(p) for p in pairs]))
    if flagged or flagged_v:
        worst = sorted(flagged, key=lambda r: -r["deleted_z"])[:5] + sorted(flagged_v, key=lambda r: -r["deleted_z"])[:3]
        shown = ", ".join(f"{'held-out ' if r in flagged_v else ''}{_observation_name(r)} (t = {r['deleted_z']:.3g}, "
                          f"{r['norm']:.4g} mm)" for r in worst)
        n = len(flagged) + len(flagged_v)
        out.insert(0, _finding(  # first: an outlier also makes the findings above (it pulls the fit)
            "outliers",
            f"OUTLIERS: {n} observation(s) out of line with the others (normalised residual with the observation left "
            f"out above {np.sqrt(ctx['limit']):.3g}, p < {FAMILY_ALPHA:g} over the campaign): {shown}. They pull the "
            f"fit{_without(ctx.get('without_outliers'))}; check them, then exclude them with --exclude-outliers (they "
            f"are never removed otherwise).",
            f"{n} observation(s) are outliers ({shown}): check them, then exclude them with --exclude-outliers",
            observations=[{"set": "validation" if r in flagged_v else "identification", "pose": r["pose"],
                           "target": r["target"], "deleted_z": r["deleted_z"], "norm": r["norm"]}
                          for r in flagged + flagged_v]))
    if ctx["unassembled"]:
        out.append(_finding("validation-not-assembled",
                            f"{ctx['unassembled']} validation pose(s) did not assemble with the identified model.",
                            f"{ctx['unassembled']} held-out pose(s) do not assemble with the identified model"))
    if nominal is not None and val_stats is not None and nominal.get("validation") is not None:
        before, after = nominal["validation"]["rms"], val_stats["rms"]
        t, critical = (math.inf, 0.0) if ctx.get("nominal_sq") is None else \
            worse_than_nominal(ctx["val_sq"], ctx["nominal_sq"])
        if after > before and not t > critical:
            out.append(_finding(
                "no-gain-over-nominal",
                f"the calibration does not measurably improve the held-out poses on the nominal model: validation RMS "
                f"{after:.4g} mm calibrated against {before:.4g} mm with the nominal geometry (only the tracker frame "
                f"and targets fitted), a difference the noise explains (paired t = {t:.2g} over "
                f"{len(ctx['val_sq'])} observations, below {critical:.3g}): what the identified defects change is below "
                f"what these poses resolve, and either geometry predicts them as well."))
        elif after > before:
            out.append(_finding(
                "worse-than-nominal",
                f"CALIBRATION MAKES HELD-OUT POSES WORSE: validation RMS {after:.4g} mm calibrated against "
                f"{before:.4g} mm with the nominal model (only the tracker frame and targets fitted"
                + (f"; paired t = {t:.3g} over {len(ctx['val_sq'])} observations, above {critical:.3g}"
                   if ctx.get("nominal_sq") is not None else "") + "). Too few poses for "
                f"the parameters (over-fitting), or data the model does not describe: keep the nominal model, add "
                f"poses, or identify fewer parameters (--select-size).",
                f"it predicts the held-out poses worse than the nominal model (validation RMS {after:.4g} mm against "
                f"{before:.4g} mm with the nominal geometry)"))
    if ctx["excluded"]:
        shown = ", ".join(f"{'held-out ' if e['set'] == 'validation' else ''}{_observation_name(e)} "
                          f"(t = {e['deleted_z']:.3g}, {e['norm']:.4g} mm)" for e in ctx["excluded"][:8])
        out.append(_finding("outliers-excluded", f"{len(ctx['excluded'])} outlier observation(s) excluded on request "
                                                 f"(--exclude-outliers): {shown}.",
                            observations=list(ctx["excluded"])))
    return out
