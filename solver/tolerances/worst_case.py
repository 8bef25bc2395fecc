"""Extremes of the accuracy coefficients over the workspace: sampled, then refined by optimisation.

Units: joint values in mm and rad; coefficients in their own units (rad/rad, mm/rad, ...).

The allocation of paper 2 (eqs. 19, 30-31) divides the required accuracy by the largest
value of each accuracy coefficient (eq. 18) over the workspace.  A sampled maximum is
low by construction, which makes the tolerances too loose: the unsafe direction.  Here
the best samples are refined by bounded local optimisation (SLSQP, :mod:`scipy.optimize`)
over the configuration ``q`` of all joints with

* the loop closures as equality constraints (their independent rows, picked by a pivoted
  QR of the closure Jacobian at the start), so every iterate may leave the closure
  surface but the solution lies on it: the actuated variables are the free ones, the
  passive joints follow; the reachable set is the closure surface itself;
* the workspace's joint ranges as bounds: the actuated box and the passive ranges that
  pick the assembly branch (:mod:`hyperstat.solver.tolerances.workspace`), the passive
  ones moved inwards by ``margin`` (1e-4 rad) because the edge of a branch is where the
  passive Jacobian is singular and the coefficients are not evaluated reliably there.

Each refined configuration is re-assembled at its actuated values (Gauss-Newton), checked
to lie in the workspace, and checked to be on the sample's branch (a continuation back
to the sample from it must land on the sample).  Where each extreme is reached is
reported: the configuration, ``interior`` or ``boundary`` (which bound is active), and
whether the passive Jacobian is singular there; an extreme at a singular edge of the
branch is a *supremum on the boundary*: the value is approached, not attained, and is
reported at margins 1e-2, 1e-3, 1e-4 rad from the edge with the remaining gap estimated
from that sequence.  The refined extreme is never below the sampled one (it is the
largest of both).  A local optimiser finds the global extreme only if one of its starts
lies in the right basin: several separate starts are used, and how many of them agree
is reported.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.kinematics.continuation import ContinuationOptions, continue_path
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.tolerances.accuracy import (COEFFICIENT_NAMES, AccuracyMaps, geometric_parameters,
                                                  largest_singular_value, output_twist_maps)
from hyperstat.solver.tolerances.workspace import Workspace, workspace_of

__all__ = ["Extreme", "refine_extremes", "coefficient_at", "branch_conditioning"]

#: passive bounds are moved inwards by this much (rad; times the length scale for mm)
MARGIN = 1e-4
#: SLSQP iterations for a maximum (half for a minimum: a largest singular value is not smooth where it is
#: smallest, two singular values meet there, and the minima do not enter the allocation)
MAXITER = 80
#: SLSQP's stopping tolerance on the change of the objective, relative to the coefficient's value at the start
FTOL = 1e-12
#: relative smallest singular value of the scaled passive Jacobian below which a configuration is singular
SINGULAR = 1e-2


@dataclass
class Extreme:
    """An extreme (largest or smallest value) of one accuracy coefficient over the workspace.

    Attributes
    ----------
    coefficient, kind : str
        Paper name (eq. 18) and ``"max"`` or ``"min"``.
    value : float
        The refined extreme (never less extreme than ``sampled``).
    sampled : float
        The extreme over the sampled configurations.
    q : ndarray, (n_q,)
        Where it is reached (all joints, mm / rad).
    location : str
        ``"interior"``, ``"boundary"`` or ``"constant"`` (the coefficient does not vary).
    bounds : list of str
        Active workspace bounds there, in words.
    singular : bool
        The passive Jacobian is (nearly) singular there (edge of the assembly branch).
    supremum : bool
        The value is approached at a singular boundary, not attained.
    tolerance : float
        Estimated distance of ``value`` from the true (local) extreme, in the coefficient's unit.
    starts, agreeing : int
        Local optimisations run, and how many reached ``value`` within the tolerance.
    evidence : str
        What supports the value, in words.
    """

    coefficient: str
    kind: str
    value: float
    sampled: float
    q: np.ndarray
    actuated: dict = field(default_factory=dict)
    position: list = field(default_factory=list)
    location: str = "interior"
    bounds: list = field(default_factory=list)
    singular: bool = False
    supremum: bool = False
    tolerance: float = 0.0
    starts: int = 0
    agreeing: int = 0
    evidence: str = ""

    def as_dict(self) -> dict:
        """JSON-ready (lengths in mm, angles in rad)."""
        return {"value": self.value, "sampled": self.sampled, "location": self.location, "bounds": self.bounds,
                "singular": self.singular, "supremum_on_boundary": self.supremum, "tolerance": self.tolerance,
                "actuated": self.actuated, "position_mm": self.position, "configuration": self.q.tolist(),
                "starts": self.starts, "agreeing_starts": self.agreeing, "evidence": self.evidence}

    def where(self) -> str:
        """One line saying where the extreme is reached."""
        at = ", ".join(f"{k}={v:.6g}" for k, v in self.actuated.items())
        if self.location == "constant":
            return "constant over the workspace"
        text = f"{self.location} at {at} (O_p = {', '.join(f'{v:.4g}' for v in self.position)} mm)"
        if self.bounds:
            text += "; " + "; ".join(self.bounds)
        if self.supremum:
            text += "; a supremum on the boundary (approached, not attained: the passive Jacobian is singular there)"
        return text


class _Coefficient:
    """One accuracy coefficient as a function of configurations (the columns of accuracy_maps)."""

    def __init__(self, kin: Kinematics, analysis, name: str) -> None:
        m = kin.mechanism
        self.kin = kin
        names, self.matrix = geometric_parameters(m, analysis)
        units = {p.name: p.unit for p in m.parameters}
        label, kind = name.split("_")[1][0], name.split("_")[1][1]
        self.rows = slice(0, 3) if name.startswith("delta") else slice(3, 6)
        if label == "f":
            self.cols = [a for a, i in enumerate(m.actuated) if (m.joints[i].type == "P") == (kind == "P")]
        else:
            self.cols = [j for j, n in enumerate(names) if (units[n] == "mm") == (kind == "P")]
        self.label = label

    def __call__(self, q: np.ndarray) -> np.ndarray:
        st = self.kin.evaluate(q, None, jacobians=True)
        k_xi, k_a = output_twist_maps(self.kin, st)
        src = k_a if self.label == "f" else k_xi @ self.matrix
        return largest_singular_value(src[:, self.rows][:, :, self.cols])


def coefficient_at(mechanism: Mechanism, q: np.ndarray, name: str, analysis=None,
                   kinematics: Kinematics | None = None) -> np.ndarray:
    """One accuracy coefficient (eq. 18, :data:`COEFFICIENT_NAMES`) at assembled configurations ``q`` (K, n_q)."""
    if name not in COEFFICIENT_NAMES:
        raise ValueError(f"unknown accuracy coefficient '{name}' (one of {', '.join(COEFFICIENT_NAMES)}).")
    return _Coefficient(kinematics or Kinematics(mechanism), analysis, name)(np.atleast_2d(q))


def branch_conditioning(kin: Kinematics, q: np.ndarray) -> np.ndarray:
    """Relative smallest singular value of the scaled passive closure Jacobian at configurations ``q`` (K,).

    1 where there is no passive joint or no loop; 0 where the Jacobian vanishes.  Below
    :data:`SINGULAR` a configuration is at the singular edge of its assembly branch.  The
    smallest singular value is the one of full column rank, so an exactly singular point reads
    0; :func:`hyperstat.solver.kinematics.sampling.passive_conditioning`, which screens samples,
    counts the generic rank of the batch instead (a passive self-motion does not read singular).
    """
    q = np.atleast_2d(q)
    m = kin.mechanism
    if not (len(m.passive) and len(m.closures)):
        return np.ones(len(q))
    b = kin.scaled_rows(kin.evaluate(q, None, "joints").closure_q)[:, :, m.passive]
    s = np.linalg.svd(b, compute_uv=False)
    return s[:, min(b.shape[1:]) - 1] / np.maximum(s[:, 0], 1e-300)


def _passive_conditioning(kin: Kinematics, q: np.ndarray) -> float:
    return float(branch_conditioning(kin, q[None])[0])


def _optimise(f: _Coefficient, kin: Kinematics, q0: np.ndarray, lb: np.ndarray, ub: np.ndarray, sign: float,
              h: float = 1e-7, maxiter: int | None = None):
    """SLSQP over all joints: extremise ``f`` subject to the closure (independent rows) and the bounds."""
    from scipy.linalg import qr  # here, not at import: the report imports this module for Extreme only
    from scipy.optimize import minimize

    n = kin.n_q
    jac0 = kin.scaled_rows(kin.evaluate(q0[None], None, "joints").closure_q)[0]
    if jac0.shape[0]:
        s = np.linalg.svd(jac0, compute_uv=False)
        rank = int(np.sum(s > s[0] * 1e-9))
        rows = np.sort(qr(jac0.T, pivoting=True)[2][:rank])
    else:
        rows = np.zeros(0, dtype=int)
    cache: dict = {}
    eye = np.eye(n)
    # the objective is divided by its size at the start, so that FTOL is relative: an absolute 1e-13 is
    # out of reach of a forward-difference gradient and left every run at the iteration limit
    size = max(abs(float(f(q0[None])[0])), 1e-300)

    def fg(x):
        key = x.tobytes()
        if key not in cache:
            v = f(np.vstack([x, x + h * eye])) / size  # forward differences: the gradient's O(h) error moves
            cache.clear()                                 # the extreme by O(h), its value by O(h^2)
            cache[key] = (-sign * v[0], -sign * (v[1:] - v[0]) / h)
        return cache[key]

    constraints = []
    if len(rows):
        constraints = [{"type": "eq",
                        "fun": lambda x: kin.scaled(kin.evaluate(x[None], None, False).residual)[0, rows],
                        "jac": lambda x: kin.scaled_rows(kin.evaluate(x[None], None, "joints").closure_q)[0][rows]}]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = minimize(lambda x: fg(x)[0], np.clip(q0, lb, ub), jac=lambda x: fg(x)[1], method="SLSQP",
                       bounds=list(zip(lb, ub)), constraints=constraints,
                       options={"ftol": FTOL, "maxiter": maxiter or (MAXITER if sign > 0 else MAXITER // 2)})
    return res


def refine_extremes(mechanism: Mechanism, maps: AccuracyMaps, analysis=None, kinematics: Kinematics | None = None,
                    workspace: Workspace | None = None, kinds: tuple = ("max", "min"), starts: int = 3,
                    margin: float = MARGIN, names: tuple | None = None) -> dict:
    """Refine the sampled extremes of the accuracy coefficients (see the module docstring).

    Parameters
    ----------
    maps : AccuracyMaps
        Coefficients at sampled, assembled configurations of the workspace.
    analysis : StationarityResult, optional
        As for :func:`hyperstat.solver.tolerances.accuracy.accuracy_maps`.
    workspace : Workspace, optional
        Bounds (default: :func:`workspace_of` the mechanism).
    kinds : tuple
        ``"max"`` and/or ``"min"``.
    starts : int
        Local optimisations per extreme, from the best separate samples.
    margin : float
        Passive bounds are moved inwards by this much (rad, or times the length scale in mm).

    Returns
    -------
    dict
        ``(coefficient, kind)`` -> :class:`Extreme`.
    """
    kin = kinematics or Kinematics(mechanism)
    ws = workspace or workspace_of(mechanism)
    m = mechanism
    act, pas = np.asarray(m.actuated), np.asarray(m.passive)
    joint_names = [j.name for j in m.joints]
    lb0, ub0 = ws.lower.copy(), ws.upper.copy()
    scale = kin.joint_scale
    q_all = maps.q
    box = (ub0 - lb0)[act] / scale[act]
    out = {}
    for name in names or COEFFICIENT_NAMES:
        values = maps.coefficients[name]
        if len(values) == 0:
            continue
        spread = float(values.max() - values.min())
        f = None
        for kind in kinds:
            sign = 1.0 if kind == "max" else -1.0
            best = int(np.argmax(sign * values))
            sampled = float(values[best])
            if spread <= 1e-7 * max(1.0, abs(sampled)):
                out[(name, kind)] = _describe(m, kin, q_all[best], name, kind, sampled, sampled, ws, lb0, ub0,
                                              location="constant", tolerance=spread, starts=0, agreeing=0, singular=False,
                                              evidence=f"varies by {spread:.2g} over {len(values)} samples")
                continue
            f = f or _Coefficient(kin, analysis, name)
            order = np.argsort(-sign * values)
            chosen: list[int] = []
            n_starts = starts
            for i in order:  # the best samples, at least 5 % of the box apart in actuated values
                if all(np.linalg.norm((q_all[i, act] - q_all[j, act]) / scale[act] / box) > 0.05 for j in chosen):
                    chosen.append(int(i))
                if len(chosen) == n_starts:
                    break
            results = [r for r in _refine_many(f, kin, ws, q_all[chosen], lb0, ub0, sign, margin) if r is not None]
            out[(name, kind)] = _conclude(m, kin, f, ws, lb0, ub0, name, kind, sampled, q_all[best], results,
                                          len(chosen), sign, margin)
    return out


def _refine_one(f, kin, ws, q_start, lb0, ub0, sign, margin):
    """One local optimisation from a sample: (value, q, lb, ub, converged) or None if it left the branch."""
    return _refine_many(f, kin, ws, np.asarray(q_start)[None], lb0, ub0, sign, margin)[0]


def _refine_many(f, kin, ws, q_starts, lb0, ub0, sign, margin):
    """Local optimisations from several samples, their branch checks batched: a list of results or None."""
    m = kin.mechanism
    pas = np.asarray(m.passive)
    lb, ub = lb0.copy(), ub0.copy()
    step = np.where(kin.joint_scale[pas] == 1.0, margin, margin * kin.length_scale)
    lb[pas] += step
    ub[pas] -= step
    q0 = ws.wrapped(np.atleast_2d(q_starts))
    res = [_optimise(f, kin, q, lb, ub, sign) for q in q0]
    settled = _settle(f, kin, ws, q0, np.array([r.x for r in res]), lb, ub)
    return [None if s_ is None else (*s_, bool(r.success)) for s_, r in zip(settled, res)]


def _settle(f, kin, ws, q_starts, xs, lb, ub):
    """Re-assemble the optimiser's points at their actuated values; keep those on their start's branch.

    The branch checks of all points are one batched continuation (one path per point).
    """
    m = kin.mechanism
    act = np.asarray(m.actuated)
    a = kin.assemble(np.clip(xs, lb, ub).copy())
    q = ws.wrapped(a.q)
    good = np.nonzero(a.converged & ws.inside(q))[0]
    out: list = [None] * len(xs)
    if good.size == 0:
        return out
    # the branch check: back to the sample by certified continuation; the optimiser's point may lie
    # a margin from the singular edge of the branch, so the conditioning floor is lowered for this path
    # only (the steps stay bounded by the distance to another solution, see ContinuationOptions)
    opt = ContinuationOptions(initial_steps=4, cond_tol=1e-12)
    back, cert = continue_path(kin, q[good], q_starts[good][:, act], None, opt)
    lost = ~cert.certified
    if np.any(lost):  # as Kinematics.solve: a least-squares assembly at the target from the last certified point
        qq = back[lost].copy()
        qq[:, act] = q_starts[good][lost][:, act]
        back[lost] = kin.assemble(qq).q
    # evidence: the path, taken in steps bounded by the distance to another solution, ends on the sample.
    # Its certificate may still fail at the very start (a fold a margin away: the corrector cannot shrink
    # its steps below the minimum there), which is why the end point, not the flag, decides.
    values = f(q[good])
    for j, i in enumerate(good):
        if np.max(np.abs(ws.wrapped(back[j]) - q_starts[i]) / kin.joint_scale) <= 1e-6:
            out[i] = (float(values[j]), q[i], lb, ub)
    return out


def _active(q, lb, ub, scale, tol=1e-7):
    return (np.abs(q - lb) <= tol * scale), (np.abs(ub - q) <= tol * scale)


def _conclude(m, kin, f, ws, lb0, ub0, name, kind, sampled, q_sampled, results, n_starts, sign, margin):
    if not results:
        return _describe(m, kin, q_sampled, name, kind, sampled, sampled, ws, lb0, ub0, starts=n_starts, agreeing=0,
                         tolerance=float("nan"),
                         evidence="no local optimisation stayed on the assembly branch: the sampled value is reported")
    values = np.array([r[0] for r in results])
    top = int(np.argmax(sign * values))
    value, q, lb, ub, converged = results[top]
    scale = kin.joint_scale
    pas = np.asarray(m.passive)
    low, high = _active(q, lb, ub, scale)
    passive_active = bool(np.any(low[pas] | high[pas]))
    cond = _passive_conditioning(kin, q)
    singular = cond < SINGULAR
    tol = max(1e-9 * max(1.0, abs(value)), 0.0)
    evidence = ""
    supremum = False
    if passive_active and singular:
        # a supremum at the singular edge of the branch: the value at margins 1e-2, 1e-3, 1e-4 from it
        seq = []
        for mg in (100 * margin, 10 * margin):
            r = _refine_one(f, kin, ws, q, lb0, ub0, sign, mg)
            seq.append(r[0] if r is not None else float("nan"))
        seq.append(value)
        gaps = np.abs(np.diff(seq))
        supremum = True
        tol = max(tol, float(gaps[-1]) / 9.0) if np.all(np.isfinite(gaps)) else float("nan")
        evidence = (f"values {', '.join(f'{v:.10g}' for v in seq)} at {100 * margin:g}, {10 * margin:g}, {margin:g} "
                    f"from the singular edge (steps {', '.join(f'{g:.2g}' for g in gaps)}); remaining gap estimated "
                    f"at {tol:.2g} assuming at least linear convergence")
    elif passive_active:
        # a regular passive bound: the extreme is attained on it; optimise again with the exact bound
        r = _refine_one(f, kin, ws, q, lb0, ub0, sign, 0.0)
        if r is not None and sign * r[0] >= sign * value:
            value, q, lb, ub, converged = r
        evidence = "attained on a passive joint's workspace bound (regular configuration)"
    agreeing = int(np.sum(np.abs(values - value) <= max(tol, 1e-7 * max(1.0, abs(value)))))
    if not evidence:
        evidence = f"local extreme (SLSQP, relative ftol {FTOL:g}, forward-difference gradient, step 1e-7)"
    if not converged:
        evidence += "; the optimiser stopped at its iteration limit (the value is a bound reached, not a converged extreme)"
        tol = float("nan")
    evidence += f"; {agreeing} of {n_starts} starts agree"
    if sign * sampled > sign * value:  # never report less than what was sampled
        return _describe(m, kin, q_sampled, name, kind, sampled, sampled, ws, lb0, ub0, starts=n_starts, agreeing=0,
                         tolerance=float("nan"), evidence="the optimiser did not improve on the sampled value")
    return _describe(m, kin, q, name, kind, value, sampled, ws, lb0, ub0, tolerance=tol, starts=n_starts,
                     agreeing=agreeing, evidence=evidence, supremum=supremum, singular=singular, margin=margin)


def _describe(m, kin, q, name, kind, value, sampled, ws, lb, ub, location=None, tolerance=0.0, starts=0, agreeing=0,
              evidence="", supremum=False, singular=None, margin=0.0):
    scale = kin.joint_scale
    pas = set(int(i) for i in m.passive)
    tol = np.where(np.isin(np.arange(len(q)), list(pas)), margin * scale + 1e-7 * scale, 1e-7 * scale)
    bounds = []
    for i, j in enumerate(m.joints):
        unit = "rad" if j.type == "R" else "mm"
        for side, edge in (("lower", lb[i]), ("upper", ub[i])):
            if abs(q[i] - edge) <= tol[i] and not (j.type == "R" and ub[i] - lb[i] >= 4 * math.pi - 1e-9):
                what = "passive" if i in pas else "actuated"
                bounds.append(f"{what} joint {j.name} at its {side} workspace bound ({edge:.6g} {unit})")
    if singular is None:
        singular = _passive_conditioning(kin, q) < SINGULAR
    if location is None:
        location = "boundary" if bounds else "interior"
    st = kin.evaluate(q[None], None, False)
    act = {m.joints[i].name: float(q[i]) for i in m.actuated}
    return Extreme(name, kind, float(value), float(sampled), np.asarray(q, float), act,
                   [float(v) for v in st.output_pose[0, :3, 3]], location, bounds, bool(singular), bool(supremum),
                   float(tolerance), int(starts), int(agreeing), evidence)
