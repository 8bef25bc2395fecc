"""A virtual machine: the nominal model plus chosen defects, a tracker, a target and noise.

Units: lengths in mm, angles in rad.

It stands in for a real machine and its laser tracker: a "true" defect vector
(admissible defects only, drawn within tolerances), a tracker frame and a target
offset, a noise model ``sigma = a + b * distance`` per axis, and optionally
unmodelled effects (:mod:`hyperstat.solver.diagnosis.effects`) that a fitted model need not contain.  It
generates measurement sets over the workspace (random or grid poses); everything is
seeded and reproducible.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.errors import AnalysisError
from hyperstat.solver.calibration.identify import MeasurementModel
from hyperstat.solver.calibration.measurements import MeasurementSet, NoiseModel
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.kinematics.sampling import passive_conditioning
from hyperstat.solver.analysis.stationarity import StationarityResult

__all__ = ["VirtualMachine", "default_tracker", "workshop_metadata", "onto_closure", "prediction_metric"]


def workshop_metadata(mechanism: Mechanism, n: int, seed: int = 0, sessions: int = 2) -> dict:
    """Plausible metadata of ``n`` measured poses: what a measurement campaign records.

    * ``time[s]``: one pose every 60 s;
    * ``temperature[degC]``: a slow drift from 18 to 26 degC over the campaign plus 0.3 degC noise;
    * ``payload[kg]``: 0, 10 or 25 kg, random per pose;
    * ``dir<joint>``: approach direction of every actuator, random +-1;
    * ``session``: ``sessions`` consecutive blocks (the tracker is set up again between them).
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 60.0
    meta = {
        "time": t,
        "temperature": 18.0 + 8.0 * t / max(t[-1], 1.0) + rng.normal(0.0, 0.3, n),
        "payload": rng.choice([0.0, 10.0, 25.0], n),
        "session": np.floor(np.arange(n) * sessions / n) + 1.0,
    }
    for i in mechanism.actuated:
        meta[f"dir{mechanism.joints[i].name}"] = rng.choice([-1.0, 1.0], n)
    return meta


def default_tracker(kin: Kinematics) -> np.ndarray:
    """A plausible tracker pose ``(x, y, z, rx, ry, rz)``: 3 length scales away, turned 0.4 rad about z."""
    direction = np.array([1.0, -0.6, -0.3]) / np.linalg.norm([1.0, -0.6, -0.3])
    return np.r_[3.0 * kin.length_scale * direction, 0.0, 0.0, 0.4]


def onto_closure(kin: Kinematics, xi: np.ndarray, configurations: np.ndarray | None, count: int = 12,
                 iterations: int = 12, metric: "np.ndarray | Callable[[], np.ndarray] | None" = None) -> np.ndarray:
    """``xi`` moved the least so that every loop closes exactly at ``count`` of ``configurations``.

    Admissible defects keep an over-constrained mechanism assembled to first order only (paper 1,
    section 3: ``A_s xi`` in the range of ``B_s``).  Where the conditions that keep it mobile are
    not linear in the defects (the ratio of a Bennett linkage, the common point of a spherical
    four-bar's axes), a finite admissible defect misses the loops at second order and the machine
    it describes would not move without deforming.  A real machine that moves is on the nonlinear
    set, so the virtual one is put there: at the analysis' configurations (actuated joints held),
    the passive joints are assembled by least squares, the part of the closure residual they cannot
    absorb is projected on the left null space of ``B_s`` (as in eq. (11)) and cancelled by the
    least-norm defect change in dimensionless units (rad, and mm over the length scale), which
    lies in the constrained directions, not the admissible ones (with ``metric``, below, the least
    change in that metric); repeated until the loops close.
    The correction is of the order of ``|xi|^2`` times the length scale.  Defects with which the
    loops already close to 1e-8 of the length scale (a tenth of what assembly accepts) are
    returned unchanged.

    ``metric`` (n_xi, n_xi), symmetric positive definite, in the dimensionless columns (rad, and mm
    over the length scale), or a function computing it when the loops do not close already, measures
    the change instead of its norm: each step is the least
    ``d^T metric d`` among the changes that cancel the residual (the same constraint rows, the same
    rank decision).  An identification passes the information of its measurements
    (:func:`prediction_metric`: how far each change moves the predicted target), so that the loops
    are closed along what the measurements did not see; the least norm moves the identified
    geometry along what they saw as readily.

    Raises
    ------
    AnalysisError
        If the loops cannot be closed near ``xi`` (the defects are too large for the mechanism).

    Examples
    --------
    >>> import hyperstat as hs
    >>> from hyperstat.solver.kinematics.closure import Kinematics
    >>> mech = hs.load("slider_crank")
    >>> kin = Kinematics(mech)
    >>> bool(onto_closure(kin, np.zeros(len(mech.parameters)), None).any())
    False
    """
    m = kin.mechanism
    if configurations is None or not len(m.closures) or not len(m.passive) or not np.any(xi):
        return xi
    q = np.array(configurations[np.linspace(0, len(configurations) - 1, min(count, len(configurations))).astype(int)],
                 dtype=float)
    pas = np.asarray(m.passive)
    col_xi = kin.parameter_scale
    col_q = kin.joint_scale[pas]
    xi = np.array(xi, dtype=float)
    scale = kin.length_scale
    for _ in range(iterations):
        q = kin.assemble(q, xi).q  # passive joints by least squares: what is left is what they cannot absorb
        st = kin.evaluate(q, xi, jacobians=True)
        r = kin.scaled(st.residual)  # (K, m) mm
        if np.max(np.linalg.norm(r, axis=1)) <= (1e-8 if _ == 0 else 1e-10) * scale:
            return xi  # closes (at first already to a tenth of what assembly accepts: the drawn defects are kept)
        a = kin.scaled_rows(st.closure_xi) * col_xi  # (K, m, n_xi), columns dimensionless
        b = kin.scaled_rows(st.closure_q[:, :, pas]) * col_q  # (K, m, n_p)
        rows, rhs = [], []
        for c in range(len(q)):  # the residual's part outside the passive joints' reach, and the defects' part there
            u, sv, _vt = np.linalg.svd(b[c])
            left = u[:, int(np.sum(sv > 1e-9 * max(sv[0], 1e-300))):]
            rows.append(left.T @ a[c])
            rhs.append(-left.T @ r[c])
        if metric is None:
            step = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=1e-8)[0]
        else:
            metric = metric() if callable(metric) else metric
            step = _least_in_metric(np.vstack(rows), np.concatenate(rhs), metric)
        xi += step * col_xi
    q = kin.assemble(q, xi).q
    st = kin.evaluate(q, xi, jacobians=False)
    miss = float(np.max(kin.residual_norm(st.residual)))
    if miss > 1e-9 * scale:
        raise AnalysisError(f"the drawn defects of '{m.name}' cannot be brought onto a geometry whose loops close: "
                            f"they still miss by {miss:.3g} mm; draw smaller ones (--angle-tolerance, "
                            "--length-tolerance).")
    return xi


#: the defect change (dimensionless: rad, or mm over the length scale) that costs as much as moving the predicted
#: targets by one residual scale in all (:func:`prediction_metric`): a tenth of a milliradian; chosen on the corpus'
#: campaigns (1e-3 gives about the same, 1e-2 moves defects by 0.3-1.7 mm, 1e-5 loses the sarrus linkage)
UNSEEN_CHANGE = 1e-4


def prediction_metric(model: MeasurementModel, theta: np.ndarray, data: MeasurementSet,
                      unseen: float = UNSEEN_CHANGE, q_start: np.ndarray | None = None) -> np.ndarray:
    """How much a change of the defects moves the predicted targets, as a metric for :func:`onto_closure`.

    ``M = J^T J / s^2 + I / unseen^2`` in the dimensionless defect columns, ``J`` the predicted tracker-frame
    target positions' derivative with respect to every defect (the passive joints following, paper 1,
    eq. (3)) at the poses of ``data``, with the tracker frame and targets of ``theta`` held, and ``s`` the
    fit's residual scale per axis (mm, from the median absolute residual).  A change that moves the
    predictions by one residual scale in all costs as much as a change of ``unseen`` (rad, or length
    scales) along what the poses do not see: the loops are closed along what the measurements did not
    determine, the identified geometry kept where they did.  Positions only (a 6-D target's rotation is
    not weighed).

    Parameters
    ----------
    model : MeasurementModel
    theta : ndarray
        The fitted parameters.
    data : MeasurementSet
        The fitted poses (never held-out ones: they judge the result).
    unseen : float
        See above.
    q_start : ndarray, (K, n_q), optional
        The fit's configurations at these poses (``IdentificationResult.configurations``): the assembly starts
        there instead of following the nominal machine from home.

    Returns
    -------
    ndarray, (n_xi, n_xi)
    """
    kin = model.kin
    pred = model.predict(theta, data, q_start=q_start)
    st = kin.evaluate(pred.q, model.defects(theta), jacobians=True)
    k_xi, _ = model.twist_maps(st)
    arm = pred.world - st.output_pose[:, :3, 3]
    dworld = k_xi[:, 3:, :] + np.cross(k_xi[:, :3, :], arm[:, :, None], axis=1)  # (K, 3, n_xi)
    rot, _ = model.tracker_pose(theta)
    jac = np.einsum("ij,kia->kja", rot, dworld).reshape(-1, dworld.shape[2]) * kin.parameter_scale
    resid = pred.position - data.position  # the residual scale per axis, robust to an outlier left in the data
    scale = max(1.4826 * float(np.median(np.abs(resid))), 1e-9 * kin.length_scale)
    return jac.T @ jac / scale ** 2 + np.eye(jac.shape[1]) / unseen ** 2


def _least_in_metric(rows: np.ndarray, rhs: np.ndarray, metric: np.ndarray, rcond: float = 1e-8) -> np.ndarray:
    """The ``d`` of least ``d^T metric d`` with ``rows d = rhs`` in the least-squares sense.

    The rows are first reduced to their range (singular values above ``rcond`` of the largest, the rank
    decision of the least-norm step), then ``d = M^-1 C^T (C M^-1 C^T)^-1 b`` on the reduced system.

    >>> d = _least_in_metric(np.array([[1.0, 1.0]]), np.array([1.0]), np.diag([1.0, 4.0]))
    >>> np.round(d, 6).tolist()
    [0.8, 0.2]
    """
    u, sv, vt = np.linalg.svd(rows, full_matrices=False)
    keep = sv > rcond * max(sv[0] if len(sv) else 0.0, 1e-300)
    c = sv[keep, None] * vt[keep]  # (r, n): the rows' range
    b = u[:, keep].T @ rhs
    chol = np.linalg.cholesky(metric)
    half = np.linalg.solve(chol, c.T)  # L^-1 C^T
    inv_ct = np.linalg.solve(chol.T, half)  # M^-1 C^T
    return inv_ct @ np.linalg.solve(half.T @ half, b)


@dataclass
class VirtualMachine:
    """A simulated machine with known ("true") parameters.

    Attributes
    ----------
    model : MeasurementModel
        Model of the truth: every defect parameter, tracker, target, effects.
    theta : ndarray
        True parameters in ``model``'s layout.
    noise : NoiseModel
        Tracker noise.
    metadata : dict
        How the truth was drawn (seed, tolerances).
    """

    model: MeasurementModel
    theta: np.ndarray
    noise: NoiseModel = field(default_factory=NoiseModel)
    metadata: dict = field(default_factory=dict)

    @classmethod
    def random(
        cls,
        mechanism: Mechanism,
        analysis: StationarityResult,
        seed: int = 0,
        angle_tolerance: float = 2e-4,
        length_tolerance: float = 0.05,
        noise: NoiseModel | None = None,
        tracker: np.ndarray | None = None,
        target: np.ndarray | None = None,
        effects: tuple = (),
        extra_defects: dict | None = None,
        kinematics: Kinematics | None = None,
    ) -> "VirtualMachine":
        """Draw a true machine: every admissible defect uniform within +-tolerance.

        Parameters
        ----------
        mechanism, analysis : Mechanism, StationarityResult
            Nominal model and its analysis (which defects are admissible).
        seed : int
            Random seed.
        angle_tolerance, length_tolerance : float
            Half-widths of the uniform draws (rad, mm).
        noise : NoiseModel, optional
            Tracker noise (default 5 um + 5 um/m per axis).
        tracker : ndarray, (6,), optional
            True tracker pose ``(x, y, z, rx, ry, rz)`` (mm, rad); :func:`default_tracker` if omitted.
        target : ndarray, (3,), optional
            True target offset in the output frame (mm); default ``(12, -8, -25)``.
        effects : tuple
            Unmodelled effects, each carrying its true parameters (``effect.truth``).
        extra_defects : dict, optional
            Defects added on top, by name (rad / mm), e.g. a violated forced defect.
        """
        rng = np.random.default_rng(seed)
        kin = kinematics or Kinematics(mechanism)
        names, matrix = analysis.parameterization(mechanism, influential_only=False)
        units = {p.name: p.unit for p in mechanism.parameters}
        u = np.array([rng.uniform(-1, 1) * (length_tolerance if units[n] == "mm" else angle_tolerance) for n in names])
        xi = matrix @ u if names else np.zeros(len(mechanism.parameters))
        xi = onto_closure(kin, xi, analysis.configurations)
        for name, value in (extra_defects or {}).items():
            xi[mechanism.parameter_index[name]] += value
        model = MeasurementModel(mechanism, analysis, kin, effects, geometry="full")
        theta = model.initial(default_tracker(kin) if tracker is None else np.asarray(tracker, float),
                              np.array([12.0, -8.0, -25.0]) if target is None else np.asarray(target, float))
        theta[model.sl_geometry] = xi
        for eff, sl in zip(model.effects, model._effect_slices):
            theta[sl] = eff.truth
        return cls(model, theta, noise or NoiseModel(),
                   {"seed": seed, "angle_tolerance": angle_tolerance, "length_tolerance": length_tolerance})

    @property
    def defects(self) -> np.ndarray:
        """True defect vector ``xi`` (rad / mm)."""
        return self.theta[self.model.sl_geometry]

    def truth(self) -> dict:
        """True value of every parameter by name (defects, tracker, target, effects)."""
        return dict(zip(self.model.names, self.theta))

    # ------------------------------------------------------------------ poses
    def poses(self, n: int, seed: int = 0, mode: str = "random", margin: float = 0.05) -> np.ndarray:
        """``n`` actuated configurations the true machine reaches (random or grid), shape (n, n_actuated).

        Raises
        ------
        AnalysisError
            If too few configurations can be assembled.
        """
        m = self.model.mechanism
        kin = self.model.kin
        act = m.actuated
        ranges = m.ranges[act]
        lo = ranges[:, 0] + margin * (ranges[:, 1] - ranges[:, 0])
        hi = ranges[:, 1] - margin * (ranges[:, 1] - ranges[:, 0])
        rng = np.random.default_rng(seed)
        kept = []
        for attempt in range(6):
            if mode == "grid" and attempt == 0:
                per = max(2, int(np.ceil(n ** (1.0 / len(act)))))
                axes = [np.linspace(a, b, per) for a, b in zip(lo, hi)]
                cand = np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(act), -1).T
            else:
                cand = lo + rng.random((max(2 * n, 16), len(act))) * (hi - lo)
            res = kin.solve(cand, self.defects)
            full = m.ranges
            ok = res.converged & np.all((res.q >= full[:, 0] - 1e-9) & (res.q <= full[:, 1] + 1e-9), axis=1)
            if np.any(ok):
                good = passive_conditioning(kin, res.q[ok]) > 1e-3
                kept.append(cand[ok][good])
            if sum(len(k) for k in kept) >= n:
                break
        q = np.concatenate(kept)[:n] if kept else np.zeros((0, len(act)))
        if len(q) < n:
            raise AnalysisError(f"only {len(q)} of {n} poses of '{m.name}' could be assembled inside the joint ranges.")
        return q

    # ------------------------------------------------------------------ measurement
    def measure(self, q: np.ndarray, seed: int = 0, metadata: dict | None = None, prefix: str = "P",
                noise: bool = True) -> MeasurementSet:
        """Measurements of the target at actuated values ``q`` (noise drawn with ``seed``).

        The file states what a user would know: the tracker pose and target offset
        rounded to whole millimetres and to 0.01 rad (a rough prior registration).
        """
        m = self.model.mechanism
        k = len(q)
        meta = {key: np.asarray(v, dtype=float) for key, v in (metadata or {}).items()}
        data = MeasurementSet([f"{prefix}{i + 1}" for i in range(k)], [m.joints[i].name for i in m.actuated],
                              np.asarray(q, float), np.zeros((k, 3)), None, meta, self.noise, None, None, m.name)
        pos = self.model.predict(self.theta, data).position
        if noise:
            rng = np.random.default_rng(seed)
            sigma = self.noise.sigma(np.linalg.norm(pos, axis=1))
            pos = pos + rng.normal(size=pos.shape) * sigma[:, None]
        data.position = pos
        trk = self.theta[self.model.sl_tracker]
        data.tracker = np.r_[np.round(trk[3:]), np.round(trk[:3], 2)]
        data.target = np.round(self.theta[self.model.sl_target])
        return data
