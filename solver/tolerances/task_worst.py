"""Worst cases of the task-restricted accuracy coefficients over the workspace: sampled, then refined.

Units: joint values in mm and rad; coefficients in their own units (rad/rad, mm/rad, rad/mm, mm/mm).

The allocation of the tolerance values (paper 2, eqs. 19, 30-31;
:mod:`hyperstat.solver.tolerances.values`) divides the spec by the largest value over the
workspace of each *task-restricted* coefficient: the largest singular value of the task
rows (:func:`hyperstat.solver.tolerances.declaration.task_rows`) of the output twist per
unit of the tolerances of one kind (``gP`` lengths, ``gR`` angles), eq. 18 restricted to
what the task uses.  A sampled maximum is low, which makes the values loose (the unsafe
direction), so the best samples are refined here by a batched projected-gradient ascent
over the actuated variables:

* the variables are the actuated joints, normalised to ``[0, 1]`` on the workspace's
  actuated box (its bounds are the projection's bounds); the passive joints follow on
  the sample's assembly branch: each step is predicted to first order
  (``dq_p = -B_p^+ B_a dq_a``, paper 1, eq. 3) and corrected by Gauss-Newton; a step
  whose correction is not small against the prediction, that does not converge, or
  that leaves the declared passive ranges (another branch) or where the passive
  Jacobian's relative conditioning falls below :data:`CONDITIONING_FLOOR` times its
  median over the sample (a singular edge, where a coefficient can grow without bound)
  is refused and shortened;
* the gradient is taken by forward differences (step 1e-6 of the box) on the
  first-order passive motion, for all paths in one batched evaluation;
* the step doubles after an accepted ascent and is quartered after a refusal; a path
  stops when its step falls below ``1e-7`` of the box or an accepted step gains less
  than ``1e-12`` of the value (``converged``), or after ``iterations``.

This is a local method: it finds the global maximum only if one of its starts lies in
the right basin; several separate starts are used and how many agree is reported.  The
refined value is never below the sampled one.  The stated tolerance is the last accepted
increase of the path that gave the value (the ascent's remaining improvement is smaller
when it converges linearly with a ratio below 1/2); a path stopped at the iteration limit
says so in its evidence.  :func:`hyperstat.solver.tolerances.worst_case.refine_extremes` (SLSQP over all
joints) finds the same maxima on the Triflex-II (``tests/solver/tolerances/test_values.py``)
at a cost that the report cannot afford on the Tripteor (about 10 s of CPU time against
about 0.5 s here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.tolerances.accuracy import output_twist_maps
from hyperstat.solver.tolerances.declaration import n_rotation_rows, task_rows
from hyperstat.solver.tolerances.workspace import Workspace, workspace_of
from hyperstat.solver.tolerances.worst_case import Extreme, branch_conditioning

__all__ = ["TaskExtreme", "TaskCoefficients", "task_worst_cases", "TASK_COEFFICIENTS"]

#: the task-restricted coefficients the allocation divides by (paper 2, eq. 18, task rows only)
TASK_COEFFICIENTS = ("delta_gP", "delta_gR", "epsilon_gP", "epsilon_gR")


@dataclass
class TaskExtreme(Extreme):
    """The worst case (maximum) of one task-restricted coefficient over the workspace.

    The fields of :class:`~hyperstat.solver.tolerances.worst_case.Extreme` (``kind`` is
    ``"max"``; ``location`` is ``interior``, ``boundary`` when an actuated bound is active, or
    ``constant``; ``tolerance`` is NaN when the ascent was interrupted), and:

    Attributes
    ----------
    iterations : int
        Iterations of the ascent path that gave ``value``.
    """

    iterations: int = 0

    def as_dict(self) -> dict:
        """JSON-ready (lengths in mm, angles in rad)."""
        return {"max": self.value, "sampled_max": self.sampled, "optimiser_tolerance": self.tolerance,
                "location": self.location, "where": self.where(), "bounds": list(self.bounds),
                "actuated": dict(self.actuated), "position_mm": list(self.position),
                "configuration": self.q.tolist(), "starts": self.starts, "agreeing_starts": self.agreeing,
                "iterations": self.iterations, "evidence": self.evidence}


class TaskCoefficients:
    """The four task-restricted coefficients as functions of assembled configurations.

    Parameters
    ----------
    kin : Kinematics
    task : tuple of str
        Task components (:data:`hyperstat.solver.tolerances.declaration.TASK_COMPONENTS`).
    directions : ndarray, (n_xi, n)
        Defect vector per unit of each tolerance (rad / mm).
    is_length : ndarray of bool, (n,)
        Which tolerances are lengths (class ``gP``); the others are angles (``gR``).
    """

    def __init__(self, kin: Kinematics, task: tuple, directions: np.ndarray, is_length: np.ndarray) -> None:
        self.kin, self.task, self.directions = kin, tuple(task), directions
        self.is_length = np.asarray(is_length, dtype=bool)
        self.n_rot = n_rotation_rows(self.task)

    def __call__(self, q: np.ndarray) -> dict:
        """Coefficient name -> (K,) values at configurations ``q`` (K, n_q)."""
        st = self.kin.evaluate(np.atleast_2d(q), None, jacobians=True)
        k_xi, _ = output_twist_maps(self.kin, st)
        t = task_rows(self.task, st.output_pose) @ k_xi @ self.directions
        out = {}
        for kind, cols in (("P", self.is_length), ("R", ~self.is_length)):
            for name, rows in (("delta", t[:, :self.n_rot]), ("epsilon", t[:, self.n_rot:])):
                block = rows[:, :, cols]
                out[f"{name}_g{kind}"] = (np.zeros(len(t)) if block.shape[1] == 0 or block.shape[2] == 0
                                          else np.linalg.svd(block, compute_uv=False)[:, 0])
        return out


#: a step is refused where the relative smallest singular value of the scaled passive Jacobian falls below this
#: fraction of its median over the sample: at a singular edge of the workspace a coefficient can grow without bound
CONDITIONING_FLOOR = 1e-2


def _passive_motion(kin: Kinematics, q: np.ndarray) -> np.ndarray:
    """First-order passive motion per unit actuated motion, ``-B_p^+ B_a`` (K, n_p, n_a), mm and rad."""
    m = kin.mechanism
    b = kin.scaled_rows(kin.evaluate(q, None, "joints").closure_q)
    return -np.linalg.pinv(b[:, :, m.passive], rcond=1e-10) @ b[:, :, m.actuated]


def task_worst_cases(mechanism: Mechanism, kin: Kinematics, sample: np.ndarray, coefficients: TaskCoefficients,
                     workspace: Workspace | None = None, starts: int = 2, iterations: int = 30,
                     sampled: dict | None = None) -> dict:
    """Refined maxima of the task-restricted coefficients (see the module docstring).

    Parameters
    ----------
    sample : ndarray, (K, n_q)
        Assembled configurations of the workspace (the starts are its best ones).
    coefficients : TaskCoefficients
    workspace : Workspace, optional
        Bounds (default: the mechanism's declared workspace).
    starts : int
        Paths per coefficient, from the best samples at least 5 % of the box apart.
    iterations : int
        Largest number of ascent iterations.
    sampled : dict, optional
        The coefficients at ``sample`` if already computed.

    Returns
    -------
    dict
        Coefficient name -> :class:`TaskExtreme` (zero coefficients are left out).
    """
    m = mechanism
    ws = workspace or workspace_of(m)
    act, pas = np.asarray(m.actuated), np.asarray(m.passive)
    sample = np.atleast_2d(sample)
    values = sampled if sampled is not None else coefficients(sample)
    lo, hi = ws.actuated_box(m)
    width = hi - lo
    free = width > 0
    box = np.where(free, width, 1.0)
    out: dict = {}
    paths, owner = [], []
    for name in TASK_COEFFICIENTS:
        v = values.get(name)
        if v is None or len(v) == 0 or float(np.max(v)) <= 0:
            continue
        best = int(np.argmax(v))
        spread = float(v.max() - v.min())
        if spread <= 1e-9 * max(1.0, float(v.max())):
            out[name] = _describe(m, kin, ws, name, float(v[best]), float(v[best]), sample[best], 0.0, 0, 0, 0,
                                  f"varies by {spread:.2g} over {len(v)} samples", location="constant")
            continue
        chosen: list = []
        for i in np.argsort(-v):
            z = (sample[i, act] - lo) / box
            if all(np.linalg.norm(z - (sample[j, act] - lo) / box) > 0.05 for j in chosen):
                chosen.append(int(i))
            if len(chosen) == starts:
                break
        for i in chosen:
            paths.append(sample[i].copy())
            owner.append(name)
    if not paths:
        return out
    q = np.array(paths)
    p = len(q)
    names = list(owner)

    def f(qq: np.ndarray, who: list) -> np.ndarray:
        c = coefficients(qq)
        return np.array([c[n][k] for k, n in enumerate(who)])

    val = f(q, names)
    floor_at = CONDITIONING_FLOOR * float(np.median(branch_conditioning(kin, sample)))
    step = np.full(p, 0.05)
    gain = np.full(p, np.nan)  # last accepted increase
    active = np.ones(p, dtype=bool)
    done = np.zeros(p, dtype=bool)
    iters = np.zeros(p, dtype=int)
    floor = np.zeros(p, dtype=bool)  # a step was refused at the conditioning floor (a singular edge)
    h = 1e-6
    n_a = len(act)
    for _ in range(iterations):
        idx = np.nonzero(active)[0]
        if not len(idx):
            break
        qa = q[idx]
        g_p = _passive_motion(kin, qa)  # (P, n_p, n_a) per unit of scaled actuated motion
        # forward differences in the normalised actuated variables, passive joints to first order
        pert = np.repeat(qa, n_a, axis=0).reshape(len(idx), n_a, -1)
        for j in range(n_a):
            da = np.zeros(n_a)
            da[j] = h * box[j] if free[j] else 0.0
            pert[:, j, act] += da
            pert[:, j, pas] += g_p @ da
        fp = f(pert.reshape(len(idx) * n_a, -1), [names[k] for k in idx for _ in range(n_a)]).reshape(len(idx), n_a)
        grad = (fp - val[idx, None]) / h
        z = (qa[:, act] - lo) / box
        grad[:, ~free] = 0.0
        grad[(z <= 1e-12) & (grad < 0)] = 0.0
        grad[(z >= 1 - 1e-12) & (grad > 0)] = 0.0
        norm = np.linalg.norm(grad, axis=1)
        flat = norm <= 1e-14 * np.maximum(np.abs(val[idx]), 1e-300)
        for k in idx[flat]:
            active[k], done[k] = False, True
            gain[k] = 0.0 if np.isnan(gain[k]) else gain[k]
        keep = ~flat
        if not keep.any():
            continue
        idx, qa, g_p, grad, z, norm = idx[keep], qa[keep], g_p[keep], grad[keep], z[keep], norm[keep]
        z_new = np.clip(z + step[idx, None] * grad / norm[:, None], 0.0, 1.0)
        da = (z_new - z) * box
        q_pred = qa.copy()
        q_pred[:, act] += da
        dq_p = np.einsum("kpa,ka->kp", g_p, da)
        q_pred[:, pas] += dq_p
        res = kin.assemble(q_pred)
        q_new = ws.wrapped(res.q)
        corr = np.linalg.norm((res.q[:, pas] - q_pred[:, pas]) / kin.joint_scale[pas], axis=1)
        pred = np.linalg.norm(dq_p / kin.joint_scale[pas], axis=1)
        ok = res.converged & ws.inside(q_new) & (corr <= 0.1 * pred + 1e-9)
        if ok.any():
            cond = np.ones(len(idx))
            cond[ok] = branch_conditioning(kin, q_new[ok])
            edge = ok & (cond < floor_at)
            floor[idx[edge]] = True
            ok &= ~edge
        v_new = np.full(len(idx), -np.inf)
        if ok.any():
            v_new[ok] = f(q_new[ok], [names[k] for k in idx[ok]])
        better = ok & (v_new > val[idx])
        for n_k, k in enumerate(idx):
            iters[k] += 1
            if better[n_k]:
                gain[k] = v_new[n_k] - val[k]
                q[k], val[k] = q_new[n_k], v_new[n_k]
                step[k] = min(2.0 * step[k], 0.25)
                if gain[k] <= 1e-12 * abs(val[k]):  # improvements at round-off: converged
                    active[k], done[k] = False, True
            else:
                step[k] *= 0.25
            if step[k] < 1e-7:
                active[k], done[k] = False, True
    for name in dict.fromkeys(names):
        ks = [k for k, n in enumerate(names) if n == name]
        v = values[name]
        best_s = int(np.argmax(v))
        top = max(ks, key=lambda k: val[k])
        tol = float(gain[top]) if np.isfinite(gain[top]) else (0.0 if done[top] else float("nan"))
        agree = sum(1 for k in ks if abs(val[k] - val[top]) <= max(tol if math.isfinite(tol) else 0.0,
                                                                    1e-7 * abs(val[top])))
        if val[top] < float(v[best_s]):  # never below the sample
            out[name] = _describe(m, kin, ws, name, float(v[best_s]), float(v[best_s]), sample[best_s],
                                  float("nan"), len(ks), 0, 0, "the ascent did not improve on the sampled value")
            continue
        evidence = (f"projected-gradient ascent over the actuated variables from {len(ks)} of the best samples, "
                    f"passive joints on the sample's branch; {agree} of {len(ks)} starts agree")
        if floor[top]:
            evidence += (f"; bounded by the singular edge of the workspace: steps where the passive Jacobian's relative "
                         f"conditioning falls below {CONDITIONING_FLOOR:g} of its median over the sample were refused "
                         "(the coefficient grows without bound there; the value holds on the well-conditioned part of "
                         "the workspace)")
        if not done[top]:
            evidence += (f"; stopped at the iteration limit ({iterations}) with a last accepted gain of {tol:.2g} "
                         "(the stated tolerance): a value reached, not a certified maximum")
        out[name] = _describe(m, kin, ws, name, float(val[top]), float(v[best_s]), q[top], tol, len(ks), agree,
                              int(iters[top]), evidence)
    return {n: out[n] for n in TASK_COEFFICIENTS if n in out}


def _describe(m: Mechanism, kin: Kinematics, ws: Workspace, name: str, value: float, sampled: float, q: np.ndarray,
              tol: float, starts: int, agreeing: int, iterations: int, evidence: str,
              location: str | None = None) -> TaskExtreme:
    bounds = []
    for i in m.actuated:
        j = m.joints[i]
        unit = "rad" if j.type == "R" else "mm"
        width = ws.upper[i] - ws.lower[i]
        for side, edge in (("lower", ws.lower[i]), ("upper", ws.upper[i])):
            if abs(q[i] - edge) <= 1e-9 * max(width, 1e-300) and not (j.type == "R" and width >= 2 * math.pi - 1e-9):
                bounds.append(f"actuated joint {j.name} at its {side} workspace bound ({edge:.6g} {unit})")
    st = kin.evaluate(q[None], None, False)
    return TaskExtreme(name, "max", value, sampled, np.asarray(q, float),
                       actuated={m.joints[i].name: float(q[i]) for i in m.actuated},
                       position=[float(v) for v in st.output_pose[0, :3, 3]],
                       location=location or ("boundary" if bounds else "interior"), bounds=bounds, tolerance=tol,
                       starts=starts, agreeing=agreeing, evidence=evidence, iterations=iterations)
