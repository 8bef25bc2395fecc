"""Branch-safe assembly: predictor-corrector continuation with a certificate per configuration.

Units: joint values in rad (revolute) and mm (prismatic); distances along a path are
dimensionless (rad, and mm divided by the length scale of the mechanism).

A closed loop ``F(q_a, q_p) = 0`` (paper 1, eqs. 7 and 9) has several assembly branches
at the same actuated values ``q_a``.  The passive joints ``q_p`` of a configuration must
come from the branch of the configuration one starts from (home, or a configuration
already assembled).  The actuated joints move along the straight segment
``q_a(s) = q_a0 + s (q_a1 - q_a0)``, ``s`` from 0 to 1, and the passive joints follow:

* **predictor**: the tangent of the branch, from the implicit function theorem applied to
  the stationarity of the closure (paper 1, eq. 3 with ``dxi = 0``):
  ``dq_p = -B_p^+ B_a dq_a``, ``B = dF/dq`` (the matrix ``B_s`` of the paper split into
  passive and actuated columns);
* **corrector**: Newton (Gauss-Newton in the least-squares sense for an over-constrained
  loop) at fixed ``q_a``;
* **step control**: a step is rejected and halved when the corrector needs more than a
  few iterations, when its contraction ``|dq_1| / |dq_0|`` exceeds ``theta_max``, or when
  the step is not short against the distance to any other solution (below); it is doubled
  after easy steps.

The guarantee (stated in :func:`continue_path`) rests on two estimates made at every
accepted step.  If ``x`` and ``y`` both solve ``F = 0`` at the same ``q_a``, then
``0 = F(y) - F(x) = B_p(x)(y - x) + R`` with ``|R| <= gamma/2 |y - x|^2`` (``gamma`` a
Lipschitz constant of ``B_p``), so ``|y - x| >= 2 sigma_min(B_p(x)) / gamma``: another
branch is never closer than ``2 sigma_min / gamma``.  A step whose length (both end points
and the tangent's reach) stays below ``sigma_min / (2 gamma)`` therefore cannot have
landed on another branch.  ``gamma`` is estimated from the change of ``B_p`` along the
accepted steps (the largest chord estimate met on the path, never decreasing), and the
Newton contraction bounds the affine-covariant Lipschitz constant of the corrector
(Deuflhard, *Newton Methods for Nonlinear Problems*, 2004, sec. 5.1): these are estimates
from the computed path, not interval bounds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["BranchCertificate", "ContinuationOptions", "batched_lstsq", "continue_nearest", "continue_path"]


def batched_lstsq(a: np.ndarray, rhs: np.ndarray, damping: float = 1e-12) -> np.ndarray:
    """Least-squares solutions of a stack of small systems ``a[k] x = rhs[k]``.

    Normal equations with a tiny Levenberg damping ``damping * max(diag(a^T a))``, five
    times faster than a batched pseudo-inverse on the (K, 12, 10) systems of assembly
    and still defined at singular configurations (minimum-norm-like step).

    Parameters
    ----------
    a : ndarray, (K, m, n)
    rhs : ndarray, (K, m, p)

    Returns
    -------
    ndarray, (K, n, p)

    Examples
    --------
    >>> import numpy as np
    >>> a = np.array([[[2.0, 0.0], [0.0, 4.0], [0.0, 0.0]]])
    >>> np.round(batched_lstsq(a, np.array([[[2.0], [4.0], [0.0]]]))[0, :, 0], 9).tolist()
    [1.0, 1.0]
    """
    at = np.ascontiguousarray(np.swapaxes(a, 1, 2))  # contiguous: the stacked product is 3x faster
    ata = at @ a
    atb = at @ rhs
    diag = np.einsum("kii->ki", ata)
    lam = damping * np.maximum(diag.max(axis=1), 1e-300)
    idx = np.arange(ata.shape[1])
    ata[:, idx, idx] += lam[:, None]
    return np.linalg.solve(ata, atb)


@dataclass
class ContinuationOptions:
    """Step control of :func:`continue_path` (dimensionless lengths: rad, mm / length scale).

    Attributes
    ----------
    initial_steps : int
        The first step is ``1 / initial_steps`` of the path (at most ``max_step`` long);
        later steps adapt.
    max_step : float
        Longest actuated move of one step (rad).
    min_step : float
        A configuration whose step falls below this length is given up ("stalled").
    theta_max : float
        Largest accepted Newton contraction ``|dq_{k+1}| / |dq_k|``.
    max_newton : int
        Corrector iterations before a step is rejected.
    max_rejections : int
        Consecutive rejected steps (the step shrunk 4096-fold) before a configuration is
        given up ("stalled"): the target is beyond a fold of the workspace, or the corrector
        cannot follow.
    tol : float
        Corrector convergence on the passive update at the end point (rad).
    path_tol : float
        The same at intermediate points of the path (rad).
    cond_tol : float
        Smallest accepted inverse condition number ``sigma_r / sigma_1`` of the
        dimensionless passive Jacobian ``B_p`` at every accepted point.
    branch_fraction : float
        The corrector's move and the predictor's estimated error of an accepted step are at
        most this fraction of the estimated distance ``2 / omega`` to another solution.
    """

    initial_steps: int = 6
    max_step: float = 0.5
    min_step: float = 1e-6
    theta_max: float = 0.25
    max_newton: int = 6
    max_rejections: int = 12
    tol: float = 1e-12
    path_tol: float = 1e-8
    cond_tol: float = 1e-6
    branch_fraction: float = 0.25


@dataclass
class BranchCertificate:
    """Evidence that each configuration lies on the branch of its start configuration.

    Attributes
    ----------
    certified : ndarray of bool, (K,)
        Whether the whole path was followed under the rules of :func:`continue_path`.
    reason : list of str, (K,)
        Empty when certified; otherwise why not (a sentence fragment).
    min_condition : ndarray, (K,)
        Smallest inverse condition number ``sigma_r / sigma_1`` of ``B_p`` along the path.
    min_sigma : ndarray, (K,)
        Smallest ``sigma_r`` of the dimensionless ``B_p`` along the path.
    max_contraction : ndarray, (K,)
        Largest Newton contraction of an accepted step.
    max_branch_ratio : ndarray, (K,)
        Largest ratio of an accepted step length to the estimated distance to another
        solution ``2 sigma_min / gamma`` (below ``branch_fraction`` when certified).
    steps, rejected : ndarray of int, (K,)
        Accepted and rejected steps.
    path_length : ndarray, (K,)
        Actuated distance followed (dimensionless).
    end_condition : ndarray, (K,)
        Inverse condition number of ``B_p`` at the end point.
    """

    certified: np.ndarray
    reason: list
    min_condition: np.ndarray
    min_sigma: np.ndarray
    max_contraction: np.ndarray
    max_branch_ratio: np.ndarray
    steps: np.ndarray
    rejected: np.ndarray
    path_length: np.ndarray
    end_condition: np.ndarray | None = None
    options: ContinuationOptions = field(default_factory=ContinuationOptions)

    def summary(self) -> str:
        """One sentence: how many configurations were certified, and why the others were not."""
        n = len(self.certified)
        bad = [r for r, c in zip(self.reason, self.certified) if not c]
        if not bad:
            return (f"all {n} configuration(s) certified on the start branch (smallest inverse condition of B_p "
                    f"{float(np.min(self.min_condition)) if n else 1.0:.2g}, steps at most "
                    f"{float(np.max(self.max_branch_ratio)) if n else 0.0:.2g} of the distance to another solution).")
        counts: dict[str, int] = {}
        for r in bad:
            counts[r] = counts.get(r, 0) + 1
        why = "; ".join(f"{c} {r}" for r, c in sorted(counts.items(), key=lambda t: -t[1]))
        return f"{len(bad)} of {n} configuration(s) could not be certified on the start branch ({why})."

    def take(self, mask: np.ndarray) -> "BranchCertificate":
        """The certificate of a subset of the configurations."""
        idx = np.nonzero(mask)[0] if np.asarray(mask).dtype == bool else np.asarray(mask)
        return BranchCertificate(self.certified[idx], [self.reason[i] for i in idx], self.min_condition[idx],
                                 self.min_sigma[idx], self.max_contraction[idx], self.max_branch_ratio[idx],
                                 self.steps[idx], self.rejected[idx], self.path_length[idx],
                                 self.end_condition[idx], self.options)

    @staticmethod
    def concatenate(parts: list) -> "BranchCertificate":
        """Certificates of several batches, in order."""
        if not parts:
            z = np.zeros(0)
            return BranchCertificate(z.astype(bool), [], z, z, z, z, z.astype(int), z.astype(int), z, z)
        cat = np.concatenate
        return BranchCertificate(cat([p.certified for p in parts]), sum((p.reason for p in parts), []),
                                 cat([p.min_condition for p in parts]), cat([p.min_sigma for p in parts]),
                                 cat([p.max_contraction for p in parts]), cat([p.max_branch_ratio for p in parts]),
                                 cat([p.steps for p in parts]), cat([p.rejected for p in parts]),
                                 cat([p.path_length for p in parts]), cat([p.end_condition for p in parts]),
                                 parts[0].options)


def _dimensionless_state(kin, q: np.ndarray, xi) -> tuple[np.ndarray, np.ndarray]:
    """Residual (rad, mm / L) and ``dF/dq`` with dimensionless rows and columns at ``q``."""
    st = kin.evaluate(q, xi, "joints")
    lc = kin.length_scale
    r = st.residual.copy()
    for c in range(r.shape[1] // 6):
        r[:, 6 * c + 3: 6 * c + 6] /= lc
    return r, kin.dimensionless(st.closure_q, kin.joint_scale)


def _svd_parts(bp: np.ndarray, rank: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``sigma_r``, ``sigma_r / sigma_1`` and the rank-``r`` pseudo-inverse of a stack of matrices."""
    k, _, n = bp.shape
    if rank == 0:
        return np.full(k, np.inf), np.ones(k), np.zeros((k, n, bp.shape[1]))
    u, s, vt = np.linalg.svd(bp, full_matrices=False)
    s1 = np.maximum(s[:, 0], np.finfo(float).tiny)
    sr = s[:, rank - 1]
    inv = np.where(np.arange(s.shape[1])[None, :] < rank, 1.0 / np.maximum(s, np.finfo(float).tiny), 0.0)
    pinv = np.einsum("kji,kj,klj->kil", vt, inv, u)  # V diag(1/s) U^T
    return sr, sr / s1, pinv


def continue_path(
    kin,
    q_start: np.ndarray,
    qa_target: np.ndarray,
    xi: np.ndarray | None = None,
    options: ContinuationOptions | None = None,
) -> tuple[np.ndarray, BranchCertificate]:
    """Follow the assembly branch of ``q_start`` while the actuators move to ``qa_target``.

    Batched over configurations: every configuration has its own path, step length and
    certificate; each corrector iteration evaluates all unfinished configurations at once.

    **Guarantee.** For a configuration reported ``certified``: the start was corrected
    onto ``F = 0`` and every accepted step (i) converged by Newton with contraction at
    most ``theta_max`` within ``max_newton`` iterations, (ii) kept the inverse condition
    number of ``B_p`` above ``cond_tol`` at its end point, and (iii) moved the joints by
    at most ``branch_fraction`` of ``2 sigma_min(B_p) / gamma``, the distance below which
    no other solution with the same actuated values can lie (module docstring).  Under
    the estimated ``gamma`` (the Lipschitz constant of ``B_p``, estimated from the change
    of ``B_p`` along the accepted steps) no step can reach another solution, so the end
    point is on the branch of the start.  A configuration that cannot meet these rules
    (the path passes a singularity of the passive joints, or the corrector stalls) is
    reported uncertified with the reason, never silently returned as certified.

    Parameters
    ----------
    kin : Kinematics
        Forward model (:class:`hyperstat.solver.kinematics.closure.Kinematics`).
    q_start : ndarray, (n_q,) or (K, n_q)
        Start configurations, assembled at ``xi`` or close to it (e.g. the nominal home
        with small defects: the first correction is certified like a step).
    qa_target : ndarray, (K, n_actuated)
        Actuated values to reach (rad / mm).
    xi : ndarray, (n_xi,) or (K, n_xi), optional
        Defects (rad / mm).
    options : ContinuationOptions, optional

    Returns
    -------
    q : ndarray, (K, n_q)
        End configurations; for an uncertified configuration, the last certified point
        (its actuated values then differ from the target).
    certificate : BranchCertificate

    Examples
    --------
    Not run here: see ``tests/solver/kinematics/test_continuation.py`` and
    ``docs/assembly-branches.md``.
    """
    opt = options or ContinuationOptions()
    m = kin.mechanism
    act, pas = m.actuated, m.passive
    qa1 = np.atleast_2d(np.asarray(qa_target, dtype=float))
    k = qa1.shape[0]
    q = np.array(np.broadcast_to(np.asarray(q_start, dtype=float), (k, kin.n_q)), dtype=float)
    xi_rows = None if xi is None else np.asarray(xi, dtype=float)
    per_row = xi_rows is not None and xi_rows.ndim == 2 and xi_rows.shape[0] == k and k > 1

    def xi_of(idx):
        if xi_rows is None:
            return None
        return xi_rows[idx] if per_row else xi_rows

    jscale = kin.joint_scale
    qa0 = q[:, act].copy()
    delta = (qa1 - qa0) / jscale[act]  # dimensionless actuated move per unit s
    length = np.linalg.norm(delta, axis=1)
    z = np.zeros(k)
    cert = BranchCertificate(np.ones(k, bool), [""] * k, np.ones(k), np.full(k, np.inf), z.copy(), z.copy(),
                             np.zeros(k, int), np.zeros(k, int), length.copy(), np.ones(k), opt)
    if len(m.closures) == 0 or len(pas) == 0:
        q[:, act] = qa1
        return q, cert

    # generic rank of B_p at the start (a passive self-motion keeps sigma_n at zero everywhere)
    # (decided from the first corrector evaluation, at the start configurations)
    rank = -1
    bshape = (6 * len(m.closures), kin.n_q)
    jp, ja = jscale[pas], jscale[act]

    s = np.zeros(k)
    step_len = np.minimum(length / max(opt.initial_steps, 1), opt.max_step)
    h = np.where(length > 0, step_len / np.maximum(length, 1e-300), 1.0)
    omega = np.zeros(k)  # estimated affine-covariant Lipschitz constant of B_p (last accepted step)
    bcur = np.zeros((k,) + bshape)  # B at the current accepted point (dimensionless, all joints)
    todo = np.ones(k, bool)
    streak = np.zeros(k, int)  # consecutive rejections
    first = True  # step 0: correct the start onto F = 0 (h = 0), checked like any other step
    while np.any(todo):
        idx = np.nonzero(todo)[0]
        ni = len(idx)
        hs = np.zeros(ni) if first else np.minimum(h[idx], 1.0 - s[idx])
        qn = q[idx].copy()
        qn[:, act] = qa0[idx] + (s[idx] + hs)[:, None] * delta[idx] * ja
        reach = np.zeros(ni)
        if not first:
            bc = bcur[idx]
            tangent = -batched_lstsq(bc[:, :, pas], bc[:, :, act] @ delta[idx][:, :, None])[..., 0]  # dq_p/ds
            qn[:, pas] += hs[:, None] * tangent * jp
            reach = hs * np.sqrt(np.sum(tangent ** 2, axis=1) + length[idx] ** 2)
        qpred = qn.copy()
        final = s[idx] + hs >= 1.0 - 1e-12
        tol_here = np.where(final | first, opt.tol, opt.path_tol)  # intermediate points need less
        # corrector: Newton (Gauss-Newton) at fixed actuated values
        prev = np.full(ni, np.inf)
        iters = np.zeros(ni, int)
        live = np.ones(ni, bool)
        conv = np.zeros(ni, bool)
        theta = np.zeros(ni)
        blast = np.zeros((ni,) + bshape)
        for it in range(opt.max_newton):
            li = np.nonzero(live)[0]
            if li.size == 0:
                break
            r, b = _dimensionless_state(kin, qn[li], xi_of(idx[li]))
            blast[li] = b
            dq = -batched_lstsq(b[:, :, pas], r[..., None])[..., 0]
            n = np.linalg.norm(dq, axis=1)
            qn[np.ix_(li, pas)] += dq * jp
            iters[li] += 1
            th = np.where(prev[li] > 1e-9, n / np.minimum(prev[li], 1e300), 0.0)
            theta[li] = np.maximum(theta[li], th)
            diverging = th > opt.theta_max
            # converged when this update, or the next one the contraction predicts, is below tol
            tl = tol_here[li]
            done = (n < tl) | ((n * np.where(np.isfinite(prev[li]), th, 1.0) < tl) & (n < 1e-6))
            if it == 0 and not first:
                # Newton-Kantorovich estimate with the omega of the last step: the next update would be
                # about omega/2 |dq|^2 and the contraction omega/2 |dq| (Deuflhard 2004, sec. 5.1)
                w_prev = omega[idx[li]]
                quick = (w_prev > 0) & (0.5 * w_prev * n * n < tl) & (0.5 * w_prev * n < opt.theta_max / 4)
                theta[li] = np.where(quick, 0.5 * w_prev * n, theta[li])
                done |= quick
            conv[li[done & ~diverging]] = True
            prev[li] = n
            live[li[done | diverging]] = False
        ok = conv & (theta <= opt.theta_max)
        if rank < 0:
            s_all = np.linalg.svd(blast[:, :, pas], compute_uv=False)
            rank = int(np.max(np.sum(s_all > 1e-8 * np.maximum(s_all[:, :1], 1e-300), axis=1)))
        # conditioning and the distance to another solution at the end point
        sig, cond, pinv = _svd_parts(blast[:, :, pas], rank)
        moved = np.linalg.norm((qn - q[idx]) / jscale, axis=1)
        if first:
            w = np.zeros(ni)
        else:
            change = np.einsum("kij,kjl->kil", pinv, bcur[idx][:, :, pas] - blast[:, :, pas])
            w_step = np.linalg.norm(change, ord=2, axis=(1, 2)) / np.maximum(moved, 1e-300)
            w = np.maximum(np.where(moved > 1e-12, w_step, 0.0), omega[idx])
        # another solution is at least 2/omega away from the end point; the end point is within
        # corr (the corrector's move) + the predictor error (about omega/2 reach^2) of the branch point
        corr = np.linalg.norm((qn - qpred) / jscale, axis=1)
        ratio = 0.5 * w * np.maximum(corr, 0.5 * w * reach ** 2)
        singular = ok & (cond < opt.cond_tol)
        too_long = ok & ~singular & (ratio > opt.branch_fraction)
        accept = ok & ~singular & ~too_long
        # bookkeeping of accepted steps
        ia = idx[accept]
        q[ia] = qn[accept]
        s[ia] += hs[accept]
        omega[ia] = np.where(first, omega[ia], np.where(moved[accept] > 1e-12, w[accept], omega[ia]))
        if not first:
            cert.steps[ia] += 1
        cert.min_condition[ia] = np.minimum(cert.min_condition[ia], cond[accept])
        cert.min_sigma[ia] = np.minimum(cert.min_sigma[ia], sig[accept])
        cert.max_contraction[ia] = np.maximum(cert.max_contraction[ia], theta[accept])
        cert.max_branch_ratio[ia] = np.maximum(cert.max_branch_ratio[ia], ratio[accept])
        cert.end_condition[ia] = cond[accept]
        bcur[ia] = blast[accept]
        # next step: the branch ratio grows with the square of the step, so aim at 70 % of the bound;
        # double at most, and only after an easy corrector (few iterations, strong contraction)
        aim = np.where(ratio > 0, np.sqrt(0.7 * opt.branch_fraction / np.maximum(ratio, 1e-300)), 2.0)
        easy = (theta < opt.theta_max / 4) & (iters <= 2)
        factor = np.clip(np.where(easy, np.minimum(aim, 2.0), np.minimum(aim, 1.0)), 0.5, 2.0)
        h[ia] = np.minimum(h[ia] * factor[accept], opt.max_step / np.maximum(length[ia], 1e-300))
        for j in np.nonzero(singular)[0]:
            i = idx[j]
            cert.certified[i] = False
            cert.reason[i] = "the path passes near a singularity of the passive joints"
            cert.min_condition[i] = min(cert.min_condition[i], cond[j])
            todo[i] = False
        rej = ~accept & ~singular
        h[idx[rej]] *= np.where(too_long[rej], np.clip(aim[rej], 0.1, 0.5), 0.5)
        cert.rejected[idx[rej]] += 1
        streak[idx[rej]] += 1
        streak[idx[accept]] = 0
        stalled = rej & ((h[idx] * length[idx] < opt.min_step) | (streak[idx] >= opt.max_rejections) | first)
        for j in np.nonzero(stalled)[0]:
            i = idx[j]
            cert.certified[i] = False
            cert.reason[i] = ("the start configuration could not be corrected onto the closure" if first
                              else "the corrector stalled (step below the minimum)")
            todo[i] = False
        finished = accept & ((s[idx] >= 1.0 - 1e-12) | (length[idx] == 0))
        todo[idx[finished]] = False
        first = False
    return q, cert


def continue_nearest(
    kin,
    qa_targets: np.ndarray,
    xi: np.ndarray | None = None,
    start: np.ndarray | None = None,
    options: ContinuationOptions | None = None,
    pool: np.ndarray | None = None,
) -> tuple[np.ndarray, BranchCertificate]:
    """Certified configurations at many actuated values, each continued from the nearest one assembled.

    The implementation of :func:`hyperstat.solver.kinematics.sampling.assemble_nearest`
    (see there); also what :meth:`Kinematics.solve` uses for large batches from one start.
    """
    m = kin.mechanism
    act = m.actuated
    qa = np.atleast_2d(np.asarray(qa_targets, dtype=float))
    k = len(qa)
    q_home = np.asarray(m.home if start is None else start, dtype=float)
    if xi is not None and np.ndim(xi) != 1:
        raise ValueError("assemble_nearest takes one defect vector (n_xi,) for every target.")
    scale = kin.joint_scale[act]
    options = options or ContinuationOptions(initial_steps=1)
    q = np.zeros((k, kin.n_q))
    parts: list = [None] * k
    q0 = q_home[None, :]  # every path corrects its start first (step 0 of continue_path)
    pool_q = [q0[0]] + ([] if pool is None else list(np.atleast_2d(np.asarray(pool, dtype=float))))
    pool_a = [p[act] / scale for p in pool_q]
    order = np.argsort(np.min(np.linalg.norm((qa / scale)[:, None, :] - np.array(pool_a)[None], axis=2), axis=1),
                       kind="stable")
    pos, size = 0, 4 * len(pool_q)
    while pos < k:
        batch = order[pos: pos + size]
        pos += size
        size *= 4
        pa = np.array(pool_a)
        dist = np.linalg.norm((qa[batch] / scale)[:, None, :] - pa[None, :, :], axis=2)
        near = np.argmin(dist, axis=1)
        starts = np.array(pool_q)[near]
        # screen: a target where Gauss-Newton in six equal steps from its neighbour finds no closure (gap above 1 % of
        # the length scale) is beyond the workspace; following a path to it would crawl to a fold
        # (it finds a closure, on some branch, wherever one is near; the certified path then decides the branch)
        trial = starts.copy()
        trial[:, act] = qa[batch]
        closes = kin.assemble(trial, xi).residual <= 1e-2 * kin.length_scale  # one jump first (short paths)
        if not np.all(closes):
            far = np.nonzero(~closes)[0]
            trial = starts[far].copy()
            for step in range(1, 7):
                trial[:, act] = starts[far][:, act] + (qa[batch][far] - starts[far][:, act]) * (step / 6)
                gn = kin.assemble(trial, xi, max_iter=40 if step == 6 else 12)
                trial = gn.q
            closes[far] = gn.residual <= 1e-2 * kin.length_scale
        qb = starts.copy()
        nb = len(batch)
        z = np.zeros(nb)
        cb = BranchCertificate(np.zeros(nb, bool),
                               ["no closure near the nearest assembled configuration (outside the workspace?)"] * nb,
                               z.copy(), z.copy(), z.copy(), z.copy(), np.zeros(nb, int), np.zeros(nb, int), z.copy(),
                               z.copy(), options)
        if np.any(closes):
            qc, cc = continue_path(kin, starts[closes], qa[batch][closes], xi, options)
            qb[closes] = qc
            for j, i in enumerate(np.nonzero(closes)[0]):
                one = cc.take([j])
                for attr in ("certified", "min_condition", "min_sigma", "max_contraction", "max_branch_ratio",
                             "steps", "rejected", "path_length", "end_condition"):
                    getattr(cb, attr)[i] = getattr(one, attr)[0]
                cb.reason[i] = one.reason[0]
        lost = ~cb.certified & closes
        if np.any(lost) and np.any(near[lost] != 0):  # once more from the start
            retry = lost & (near != 0)
            qr, cr = continue_path(kin, q0[0], qa[batch][retry], xi, options)
            qb[retry] = qr
            ridx = np.nonzero(retry)[0]
            for j, i in enumerate(ridx):
                cb_one = cr.take([j])
                for attr in ("certified", "min_condition", "min_sigma", "max_contraction", "max_branch_ratio",
                             "steps", "rejected", "path_length", "end_condition"):
                    getattr(cb, attr)[i] = getattr(cb_one, attr)[0]
                cb.reason[i] = cb_one.reason[0]
        for j, i in enumerate(batch):
            q[i] = qb[j]
            parts[i] = cb.take([j])
            if cb.certified[j]:
                pool_q.append(qb[j])
                pool_a.append(qb[j][act] / scale)
    return q, BranchCertificate.concatenate(parts)
