"""Assemble many configurations by continuation from the nearest one already assembled.

Units: joint values in mm (prismatic) and rad (revolute).

A local helper of the tolerance stage, to be replaced by the certified nearest-neighbour
sampler of :mod:`hyperstat.solver.kinematics.sampling` (issue 18) when it lands.

Starting every sample from home (:meth:`Kinematics.solve`, six continuation steps of up to
12 Gauss-Newton iterations) costs about 80 s for 100,000 Triflex-II samples.  Here the
first 256 samples are assembled that way; every later sample starts from the nearest
configuration already assembled (actuated values scaled to a common length, a k-d tree of
:mod:`scipy.spatial`), moved to first order along the assembly branch: the passive joints
follow ``dq_p = -B_p^+ B_a dq_a`` (implicit function theorem on the closure, paper 1,
eq. 3).  A neighbour farther than ``reach`` is approached in several predictor-corrector
steps.  The corrector is a modified Newton iteration (:func:`_newton`): the Jacobian of the
predicted configuration is kept while the residual falls fast, and its solve also gives
the branch tangent used when this sample becomes someone's neighbour.  Samples are added
in waves that double in size, so the nearest neighbour is close for almost every sample.
Samples outside the reachable set are given up when Newton stalls at a non-zero residual
(a least-squares point); those that failed close to a root get more iterations, then a
four-step continuation from their nearest neighbour (every sample left out gets that
continuation when there are at most ``retry_all`` of them).

Branch safety (local, not certified): a sample is kept only if the passive joints moved
from the prediction by less than ``jump`` (rad, or ``jump`` times the length scale for
prismatic joints; twice the predicted motion near a fold line, where the passive joints
turn fast) and stay in the workspace's passive ranges, which is what selects the branch
when a template declares them.  On the Triflex-II (100,000 draws in the box of the
paper's workspace) no kept sample lies outside the three cylinders and 32 of 68,390
reachable draws (0.05 %) are left out, all within 0.05 l.u. of a folded-leg line.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy.spatial import cKDTree

from hyperstat.solver.kinematics.closure import Kinematics, batched_lstsq

_THREADS = min(os.cpu_count() or 1, 4)
__all__ = ["assemble_from_nearest", "branch_tangent"]


def branch_tangent(kin: Kinematics, q: np.ndarray) -> np.ndarray:
    """``dq_p/dq_a`` along the assembly branch at assembled configurations ``q``: (K, n_p, n_a).

    ``-B_p^+ B_a`` with the closure rows scaled by the length scale (least squares when
    over-constrained); implicit function theorem on the closure (paper 1, eq. 3).
    """
    return _newton(kin, np.array(q, dtype=float), max_iter=1, tol=np.inf)[2]


def _row_weights(kin: Kinematics) -> np.ndarray:
    w = np.ones(6 * len(kin.mechanism.closures))
    for c in range(len(w) // 6):
        w[6 * c : 6 * c + 3] = kin.length_scale
    return w


def _newton(kin: Kinematics, q: np.ndarray, max_iter: int = 8, tol: float | None = None, chunk: int = 4096,
            cap: float = 0.3, stuck: float = 0.7) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Newton on the passive joints of ``q`` (K, n_q), in place, chunk by chunk.

    The same iteration as :meth:`Kinematics.assemble` (scaled closure rows, step capped at
    ``cap`` rad or ``cap`` length scales), organised for many configurations: chunks that
    stay in cache, one solve per iteration for the step *and* the branch tangent
    ``-B_p^-1 B_a`` (the tangent of the last iterate, at the converged configuration, is
    the predictor of the samples that will start from it), a sample leaves the loop as
    soon as its residual is below ``tol`` (mm, default 1e-10 length scales; checked on the
    residual, not on the step, so the check costs no extra evaluation), and a sample whose
    residual stops falling quadratically (less than 4x per iteration from the third on) is
    given up: outside the reachable set, Gauss-Newton converges linearly to a least-squares
    point whose residual is the distance to the set.  A sample given up with a residual
    below 1e-7 length scales counts as assembled (the test of :meth:`Kinematics.assemble`).

    Returns
    -------
    ok : ndarray of bool, (K,)
    residual : ndarray, (K,)
        Scaled residual norm at the last evaluation (mm).
    tangent : ndarray, (K, n_p, n_a)
    """
    m = kin.mechanism
    act, pas = np.asarray(m.actuated), np.asarray(m.passive)
    k = len(q)
    tol = 1e-10 * kin.length_scale if tol is None else tol
    accept = max(tol, 1e-7 * kin.length_scale)  # Kinematics.assemble's convergence test
    ok = np.zeros(k, dtype=bool)
    resid = np.full(k, np.inf)
    tangent = np.zeros((k, len(pas), len(act)))
    if not (len(pas) and len(m.closures)):
        st = kin.evaluate(q, None, False)
        resid[:] = kin.residual_norm(st.residual)
        return resid <= max(tol, 1e-300), resid, tangent
    w = _row_weights(kin)
    step_cap = np.where(kin.joint_scale[pas] == 1.0, cap, cap * kin.length_scale)
    square = len(w) == len(pas)

    def factor(qq: np.ndarray):
        """Residual (scaled), its norm, the solve matrix ``B_p^+`` (scaled) and the tangent at ``qq``."""
        st = kin.evaluate(qq, None, "joints")
        r = st.residual * w
        jac = st.closure_q * w[None, :, None]
        bp = jac[:, :, pas]
        inv = None
        if square:
            try:
                inv = np.linalg.inv(bp)
            except np.linalg.LinAlgError:  # a singular configuration in the chunk: the damped path
                inv = None
        if inv is None:
            inv = batched_lstsq(bp, np.broadcast_to(np.eye(bp.shape[1]), (len(bp), bp.shape[1], bp.shape[1])).copy())
        return r, np.sqrt(np.einsum("ij,ij->i", r, r)), inv, -inv @ jac[:, :, act]

    def work(s: int) -> None:
        # modified Newton: the Jacobian of the start is kept while the residual falls at least 4x per
        # iteration, refreshed (a full Newton step) when it does not, given up when a fresh one does not help
        idx = np.arange(s, min(k, s + chunk))
        r, rn, inv, tangent[idx] = factor(q[idx])
        fresh = np.ones(len(idx), dtype=bool)
        capped = np.zeros(len(idx), dtype=bool)
        prev = np.full(len(idx), np.inf)
        for it in range(max_iter + 1):
            resid[idx] = rn
            done = rn <= tol
            ok[idx[done]] = True
            slow = rn > 0.25 * prev
            # a fresh Jacobian, a full (uncapped) step and still no progress: a least-squares point, not a root
            flat = (rn > stuck * prev) & fresh & (~capped | (it >= 4)) & (it >= 2)
            keep = ~done & ~flat & (it < max_iter)
            ok[idx[~keep & (rn <= accept)]] = True  # stopped at a round-off floor, within assemble's tolerance
            idx, r, rn, inv, slow, capped = idx[keep], r[keep], rn[keep], inv[keep], slow[keep], capped[keep]
            if not len(idx):
                break
            renew = np.nonzero(slow)[0]
            fresh = np.zeros(len(idx), dtype=bool)
            if len(renew):
                r[renew], rn[renew], inv[renew], tangent[idx[renew]] = factor(q[idx[renew]])
                fresh[renew] = True
            dq = np.einsum("kij,kj->ki", inv, r)
            ratio = np.max(np.abs(dq) / step_cap, axis=1, keepdims=True)
            q[np.ix_(idx, pas)] -= dq / np.maximum(ratio, 1.0)
            capped = ratio[:, 0] > 1.0
            prev = rn
            st = kin.evaluate(q[idx], None, False)
            r = st.residual * w
            rn = np.sqrt(np.einsum("ij,ij->i", r, r))

    starts = range(0, k, chunk)
    threads = min(_THREADS, len(starts))
    if threads > 1:  # numpy releases the GIL in its loops and LAPACK calls; each chunk writes its own rows
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(work, starts))
    else:
        for s in starts:
            work(s)
    return ok, resid, tangent


def assemble_from_nearest(kin: Kinematics, qa: np.ndarray, start: np.ndarray, inside=None, first: int = 256,
                          steps: int = 6, jump: float = 0.5, max_iter: int = 8,
                          reach: float = 0.1, retry_all: int = 2048) -> tuple[np.ndarray, np.ndarray]:
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
    reach : float
        Longest continuation step from a neighbour, in actuated values scaled by the
        length scale (prismatic) or 1 (revolute); a sample farther from its neighbour
        is reached in several predictor-corrector steps.
    retry_all : int
        When at most this many samples are left out after the waves, all of them get a
        last four-step continuation from their nearest neighbour; otherwise only those
        that failed close to a root (the others are mostly outside the reachable set).

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
    tangent = np.zeros((k, len(pas), len(act)))
    near = np.zeros(k, dtype=bool)  # failed close to the reachable set: worth a second try
    dist = np.full(k, np.inf)  # distance to the neighbour a sample started from (scaled actuated values)

    def from_nearest(idx: np.ndarray, have: np.ndarray) -> None:
        """Predictor-corrector from the nearest assembled configuration, in steps of at most ``reach``."""
        d, nn = cKDTree(qa[have] / scale).query(qa[idx] / scale)
        nn = have[nn]
        n_steps = np.maximum(np.ceil(d / reach), 1).astype(int)
        qi = q[nn].copy()
        t_i = tangent[nn].copy()
        a0 = q[nn][:, act].copy()
        alive = np.ones(len(idx), dtype=bool)
        resid = np.zeros(len(idx))
        for step in range(1, int(n_steps.max()) + 1):
            sel = np.nonzero(alive & (n_steps >= step))[0]
            if not len(sel):
                break
            target = a0[sel] + (qa[idx[sel]] - a0[sel]) * (step / n_steps[sel])[:, None]
            pred = qi[sel].copy()
            pred[:, pas] += np.einsum("kpa,ka->kp", t_i[sel], target - pred[:, act])
            pred[:, act] = target
            qs = pred.copy()
            good, resid[sel], t_i[sel] = _newton(kin, qs, max_iter=max_iter)
            moved = np.abs(pred[:, pas] - qi[sel][:, pas])  # the predicted motion: large near a fold line
            good &= np.all(np.abs(qs[:, pas] - pred[:, pas]) <= np.maximum(cap, 2 * moved), axis=1)
            qi[sel] = qs
            alive[sel] = good
        good = alive & inside(qi)
        qi[:, act] = qa[idx]  # a sample that failed at an intermediate step holds the target, not the step
        q[idx] = qi
        tangent[idx] = t_i
        ok[idx] = good
        near[idx] = ~good & (resid < 1e-3 * kin.length_scale) & (n_steps == 1)
        dist[idx] = d

    n0 = min(first, k)
    res = kin.solve(qa[:n0], start=start, steps=steps)
    q[:n0] = res.q
    ok[:n0] = res.converged & inside(res.q)
    near[:n0] = ~ok[:n0]
    if ok[:n0].any():
        tangent[:n0] = branch_tangent(kin, q[:n0])
    done = n0
    while done < k:
        have = np.nonzero(ok[:done])[0]
        idx = np.arange(done, min(k, done + max(len(have), first)))
        done = idx[-1] + 1
        if len(have) == 0:  # nothing assembled yet: continuation from the start again
            res = kin.solve(qa[idx], start=start, steps=steps)
            q[idx] = res.q
            ok[idx] = res.converged & inside(res.q)
            near[idx] = ~ok[idx]
            tangent[idx] = branch_tangent(kin, q[idx])
            continue
        from_nearest(idx, have)
    # second try for the failures that now have a neighbour at least twice as close (the early waves'),
    # and for those that failed close to the reachable set
    failed, have = np.nonzero(~ok)[0], np.nonzero(ok)[0]
    if len(failed) and len(have):
        d_new, _ = cKDTree(qa[have] / scale).query(qa[failed] / scale)
        again = failed[(d_new < 0.5 * dist[failed]) & ~near[failed]]
        if len(again):
            from_nearest(again, have)
    idx = np.nonzero(~ok & near)[0]
    if len(idx):  # close to a root: near a singular edge Newton converges linearly; give it time
        qi = q[idx].copy()
        qi[:, act] = qa[idx]
        good, _, tangent[idx] = _newton(kin, qi, max_iter=40, stuck=0.9)
        good &= inside(qi)
        q[idx[good]] = qi[good]
        ok[idx[good]] = True
    idx, have = np.nonzero(~ok)[0], np.nonzero(ok)[0]
    if len(idx) > retry_all:  # too many to retry them all (most are outside the reachable set)
        idx = idx[near[idx]]
    if len(idx) and len(have):  # last try: continuation in four steps from the nearest
        _, nn = cKDTree(qa[have] / scale).query(qa[idx] / scale)
        nn = have[nn]
        res = kin.solve(qa[idx], start=q[nn], steps=4)
        good = res.converged & inside(res.q)
        q[idx[good]] = res.q[good]
        ok[idx[good]] = True
    # every kept sample holds its actuated values (continuation targets a0 + (qa - a0) * 1 round to qa)
    assert np.allclose(q[ok][:, act], qa[ok], rtol=0, atol=1e-12 * kin.length_scale)
    return q, ok
