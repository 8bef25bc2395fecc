"""Assemble many configurations by continuation from the nearest one already assembled.

Units: joint values in mm (prismatic) and rad (revolute).

A local helper of the tolerance stage, to be replaced by the certified nearest-neighbour
sampler of :mod:`hyperstat.solver.kinematics.sampling` (issue 18) when it lands.

Starting every sample from home (:meth:`Kinematics.solve`, six continuation steps) costs
six Gauss-Newton solves per sample.  Here the first few hundred samples are assembled
that way; every later sample starts from the nearest configuration already assembled
(actuated values scaled to a common length, a k-d tree), moved to first order along the
assembly branch: the passive joints follow ``dq_p = -B_p^+ B_a dq_a`` (implicit function
theorem on the closure, paper 1, eq. 3).  One Gauss-Newton solve of two to four
iterations then closes the loops.  Samples are added in waves that double in size, so
the nearest neighbour is close for almost every sample.

Branch safety (local, not certified): a sample is kept only if the passive joints moved
from the prediction by less than ``jump`` (rad, or ``jump`` times the length scale for
prismatic joints) and stay in the workspace's passive ranges; the others are tried once
more by a four-step continuation from their nearest neighbour, then left out.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from hyperstat.solver.kinematics.closure import Kinematics, batched_lstsq

__all__ = ["assemble_from_nearest", "branch_tangent"]


def branch_tangent(kin: Kinematics, q: np.ndarray) -> np.ndarray:
    """``dq/dq_a`` along the assembly branch at assembled configurations ``q`` (K, n_q, n_a).

    Actuated rows are the identity, passive rows ``-B_p^+ B_a`` with the closure rows
    scaled by the length scale (least squares when over-constrained).
    """
    m = kin.mechanism
    act, pas = m.actuated, m.passive
    st = kin.evaluate(q, None, "joints")
    rows = kin.scaled_rows(st.closure_q)
    t = np.zeros((len(q), kin.n_q, len(act)))
    t[:, act, np.arange(len(act))] = 1.0
    if len(pas) and rows.shape[1]:
        t[:, pas, :] = -batched_lstsq(rows[:, :, pas], rows[:, :, act])
    return t


def assemble_from_nearest(kin: Kinematics, qa: np.ndarray, start: np.ndarray, inside=None, first: int = 256,
                          steps: int = 6, jump: float = 0.5, max_iter: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Assemble configurations at actuated values ``qa`` (K, n_a) (see the module docstring).

    Parameters
    ----------
    kin : Kinematics
    qa : ndarray, (K, n_a)
        Actuated values (mm / rad).
    start : ndarray, (n_q,)
        An assembled configuration on the wanted branch (home).
    inside : callable, optional
        ``inside(q) -> bool (K,)``: the configurations that are in the workspace.
    first : int
        Samples assembled from ``start`` by ``steps``-step continuation before the
        nearest-neighbour waves.

    Returns
    -------
    q : ndarray, (K, n_q)
        Configurations (rows of failed samples hold the last iterate).
    ok : ndarray of bool, (K,)
        Assembled, on the branch, in the workspace.
    """
    m = kin.mechanism
    act, pas = np.asarray(m.actuated), np.asarray(m.passive)
    qa = np.atleast_2d(np.asarray(qa, dtype=float))
    k = len(qa)
    q = np.zeros((k, kin.n_q))
    ok = np.zeros(k, dtype=bool)
    if k == 0:
        return q, ok
    scale = kin.joint_scale[act]
    inside = inside or (lambda qq: np.ones(len(qq), dtype=bool))
    cap = np.where(kin.joint_scale[pas] == 1.0, jump, jump * kin.length_scale)

    def accept(idx, res_q, res_ok, pred):
        good = res_ok & inside(res_q)
        if pred is not None and len(pas):
            good &= np.all(np.abs(res_q[:, pas] - pred[:, pas]) <= cap, axis=1)
        q[idx] = res_q
        ok[idx] = good
        return good

    n0 = min(first, k)
    res = kin.solve(qa[:n0], start=start, steps=steps)
    accept(np.arange(n0), res.q, res.converged, None)
    tangents: dict[int, np.ndarray] = {}
    done = n0
    while done < k:
        have = np.nonzero(ok[:done])[0]
        size = max(len(have), first)
        idx = np.arange(done, min(k, done + size))
        done = idx[-1] + 1
        if len(have) == 0:  # nothing assembled yet: continuation from the start again
            res = kin.solve(qa[idx], start=start, steps=steps)
            accept(idx, res.q, res.converged, None)
            continue
        tree = cKDTree(qa[have] / scale)
        _, nn = tree.query(qa[idx] / scale)
        nn = have[nn]
        need = np.array(sorted(set(nn.tolist()) - tangents.keys()), dtype=int)
        if len(need):
            for i, t in zip(need, branch_tangent(kin, q[need])):
                tangents[int(i)] = t
        t_nn = np.stack([tangents[int(i)] for i in nn])
        pred = q[nn] + np.einsum("kqa,ka->kq", t_nn, qa[idx] - q[nn][:, act])
        pred[:, act] = qa[idx]
        res = kin.assemble(pred.copy(), max_iter=max_iter)
        accept(idx, res.q, res.converged, pred)
    idx, have = np.nonzero(~ok)[0], np.nonzero(ok)[0]
    if len(idx) and len(have):  # one more try: continuation in four steps from the nearest assembled
        _, nn = cKDTree(qa[have] / scale).query(qa[idx] / scale)
        nn = have[nn]
        res = kin.solve(qa[idx], start=q[nn], steps=4)
        good = res.converged & inside(res.q)
        q[idx[good]] = res.q[good]
        ok[idx[good]] = True
    return q, ok
