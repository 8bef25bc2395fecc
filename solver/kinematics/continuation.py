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

Workspace sampling (:func:`continue_nearest`) certifies most configurations in one step from
the nearest configuration already certified, with one Jacobian each (:func:`one_step`): the
Kantorovich theorem for the simplified Newton method at that Jacobian gives a solution and a
ball in which it is the only one, and the branch of the start is required to reach the
target inside that ball (``docs/assembly-branches.md``).
"""

from __future__ import annotations

import dataclasses
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

__all__ = ["BranchCertificate", "ContinuationOptions", "OneStep", "batched_lstsq", "continue_nearest",
           "continue_path", "one_step"]


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
    reach : float
        :func:`continue_nearest`: longest first try of a step from a neighbour
        (dimensionless actuated distance: rad, mm / length scale).
    retries : int
        :func:`continue_nearest`: further tries of a failed path, each with twice as many
        steps.
    one_step : bool
        :func:`continue_nearest`: every step with the chord corrector of :func:`one_step`
        (residual evaluations around one Jacobian), the targets within ``reach`` first tried
        in one step all at once.  ``False`` (default): the Newton corrector of
        :func:`_correct` (one chord step, then Newton; in most steps one Jacobian too, the
        last update applied without another), which costs about 15 % less CPU on the
        Triflex-II; both end with the same Kantorovich test.  ``True`` leaves out fewer
        reachable draws where the passive joints turn fast (0.14-0.27 % of the reachable
        draws of the Triflex-II's box instead of 0.44-0.48 %).
    block : int
        :func:`continue_nearest`: largest number of targets taken in one wave (memory).
    node_memory : float
        :func:`continue_nearest`: MiB held for the certified configurations that later
        targets start from (their ``B_p``, its inverse and the branch tangent); once full,
        further certified configurations are returned but not used as starts.
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
    reach: float = 0.1
    retries: int = 1
    one_step: bool = False
    block: int = 8192
    node_memory: float = 32.0


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

    def summary(self, total: int | None = None) -> str:
        """One sentence: how many configurations were certified, and why the others were not.

        ``total``: the number of configurations when this certificate holds only some of them
        (e.g. the uncertified ones).
        """
        n = len(self.certified) if total is None else int(total)
        bad = [r for r, c in zip(self.reason, self.certified) if not c]
        if not bad:
            return (f"all {n} configuration(s) certified on the start branch (smallest inverse condition of B_p "
                    f"{float(np.min(self.min_condition)) if len(self.certified) else 1.0:.2g}, steps at most "
                    f"{float(np.max(self.max_branch_ratio)) if len(self.certified) else 0.0:.2g} of the distance to "
                    "another solution).")
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
    r, b = st.residual, st.closure_q  # fresh arrays of this evaluation: scaled in place
    if lc != 1.0:
        r = r.copy()
        for c in range(r.shape[1] // 6):
            r[:, 6 * c + 3: 6 * c + 6] /= lc
            b[:, 6 * c + 3: 6 * c + 6, :] /= lc
        b *= kin.joint_scale
    return r, b


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


# ---------------------------------------------------------------------------- nearest-neighbour sampling
def _inverse_parts(bp: np.ndarray, rank: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Pseudo-)inverse of a stack of dimensionless ``B_p`` with lower bounds of ``sigma_r`` and ``sigma_r / sigma_1``.

    Full column rank (``rank == n``): ``B_p^-1`` when square, else ``(B_p^T B_p)^-1 B_p^T``
    (damped by 1e-14 of the largest diagonal entry); the bounds come from Frobenius norms,
    ``sigma_n >= 1 / ||B_p^-1||_F`` (or ``sqrt(1 / ||(B_p^T B_p)^-1||_F - damping)``) and
    ``sigma_1 <= ||B_p||_F``, so they never overstate the conditioning and cost no SVD
    (where rounding could spoil them, below an inverse condition of 1e-9, or 1e-5 through the
    normal equations, the exact values of the SVD are used instead).
    A passive self-motion (generic rank below ``n``): the rank-``r`` pseudo-inverse and the
    exact ``sigma_r`` from a batched SVD (:func:`_svd_parts`).

    Returns
    -------
    pinv : ndarray, (K, n, m)
    sigma : ndarray, (K,)
        Lower bound of ``sigma_r`` (exact when ``rank < n``).
    cond : ndarray, (K,)
        Lower bound of ``sigma_r / sigma_1`` (exact when ``rank < n``).
    """
    k, rows, n = bp.shape
    if rank < n:
        sig, cond, pinv = _svd_parts(bp, rank)
        return pinv, sig, cond
    fro_b = np.sqrt(np.einsum("kij,kij->k", bp, bp))
    out = None
    if rows == n:
        try:
            inv = np.linalg.inv(bp)
        except np.linalg.LinAlgError:  # an exactly singular matrix in the stack: the damped path below
            inv = None
        if inv is not None and np.all(np.isfinite(inv)):
            sig = 1.0 / np.sqrt(np.einsum("kij,kij->k", inv, inv))
            out, floor = (inv, sig, sig / np.maximum(fro_b, 1e-300)), 1e-9
    if out is None:
        bt = np.ascontiguousarray(np.swapaxes(bp, 1, 2))
        normal = bt @ bp
        lam = 1e-14 * np.maximum(np.einsum("kii->ki", normal).max(axis=1), 1e-300)
        idx = np.arange(n)
        normal[:, idx, idx] += lam[:, None]
        ninv = np.linalg.inv(normal)
        sig = np.sqrt(np.maximum(1.0 / np.sqrt(np.einsum("kij,kij->k", ninv, ninv)) - lam, 0.0))
        out, floor = (ninv @ bt, sig, sig / np.maximum(fro_b, 1e-300)), 1e-5
    # rounding: the inverse carries a relative error of about eps / cond (the normal equations eps / cond^2);
    # near a singularity the bounds are taken from the SVD instead
    bad = np.nonzero(out[2] < floor)[0]
    if bad.size:
        s_, c_, p_ = _svd_parts(bp[bad], rank)
        out[0][bad], out[1][bad], out[2][bad] = p_, s_, c_
    return out


@dataclass
class _Corrected:
    """What a corrector leaves per configuration: dimensionless ``B_p`` and tangent at ``q_b``, bounds, contraction."""

    ok: np.ndarray
    theta: np.ndarray
    bp: np.ndarray
    tangent: np.ndarray
    sigma: np.ndarray
    cond: np.ndarray
    pinv: np.ndarray
    residual: np.ndarray
    q_b: np.ndarray | None = None
    last: np.ndarray | None = None
    first: np.ndarray | None = None


def _empty(k: int, rows: int, n_p: int, n_a: int, n_q: int) -> _Corrected:
    return _Corrected(np.zeros(k, bool), np.zeros(k), np.zeros((k, rows, n_p)), np.zeros((k, n_p, n_a)),
                      np.zeros(k), np.zeros(k), np.zeros((k, n_p, rows)), np.full(k, np.inf), np.zeros((k, n_q)),
                      np.zeros(k))


def _residual(kin, q: np.ndarray, xi) -> np.ndarray:
    """Closure residual (rad, mm / length scale) at ``q``, no Jacobian."""
    r = kin.evaluate(q, xi, False).residual
    if kin.length_scale != 1.0:
        r = r.copy()
        for c in range(r.shape[1] // 6):
            r[:, 6 * c + 3: 6 * c + 6] /= kin.length_scale
    return r


def _correct(kin, q: np.ndarray, xi, rank: int, opt: ContinuationOptions, tol: float = 1e-10,
             pinv0: np.ndarray | None = None) -> _Corrected:
    """Newton on the passive joints of ``q`` (K, n_q) at fixed actuated values, in place, all rows at once.

    With ``pinv0`` (the start's ``B_p^+``, (K, n_p, m)) the first update is a chord step
    from the predicted point (one residual evaluation, no Jacobian).  Every Newton
    iteration then evaluates ``B`` (dimensionless) and its (pseudo-)inverse; an update
    shorter than 1e-5 (dimensionless) is applied and the residual at the new point checked
    (one residual evaluation): below ``tol`` (rad, mm / length scale), or after an update
    below 1e-12 (a least-squares point: defects that do not re-assemble), the row is done,
    and ``B_p``, its inverse, the conditioning bounds and the branch tangent
    ``dq_p/dq_a = -B_p^+ B_a`` are those of the last iterate ``q_b``, within ``last`` (the
    final update) of the end point.  A row fails when an update does not contract by
    ``theta_max`` (``|dq_{k+1}| / |dq_k|``, updates above 1e-9 only) or within
    ``max_newton`` iterations.
    """
    m = kin.mechanism
    act, pas = m.actuated, m.passive
    jp = kin.joint_scale[pas]
    k = len(q)
    out = _empty(k, 6 * len(m.closures), len(pas), len(act), kin.n_q)
    prev_dq = np.full(k, np.inf)
    if pinv0 is not None:
        r0 = _residual(kin, q, xi)
        rn0 = np.sqrt(np.einsum("ij,ij->i", r0, r0))
        out.residual[:] = rn0
        out.first = rn0
        dq0 = -(pinv0 @ r0[..., None])[..., 0]  # the chord step: its contraction is not counted (linear, not Newton)
        q[:, pas] += dq0 * jp
    live = np.arange(k)
    square = out.bp.shape[1] == len(pas) and rank == len(pas)
    for it in range(opt.max_newton):
        if live.size == 0:
            break
        r, b = _dimensionless_state(kin, q[live], xi)
        bp = b[:, :, pas]
        dq = None
        if square:
            try:
                dq = -np.linalg.solve(bp, r[..., None])[..., 0]
            except np.linalg.LinAlgError:  # an exactly singular matrix: the damped least-squares step
                dq = None
        if dq is None:
            dq = -batched_lstsq(bp, r[..., None])[..., 0]
        n = np.sqrt(np.einsum("ij,ij->i", dq, dq))
        out.residual[live] = np.sqrt(np.einsum("ij,ij->i", r, r))
        pd = prev_dq[live]
        th = np.where(np.isfinite(pd) & (pd > 1e-9), n / np.maximum(pd, 1e-300), 0.0)
        out.theta[live] = np.maximum(out.theta[live], th)
        go = th <= opt.theta_max
        if not go.all():
            live, dq, n, b, bp = (x[go] for x in (live, dq, n, b, bp))
        q_before = q[live]
        q[np.ix_(live, pas)] += dq * jp
        prev_dq[live] = n
        small = np.nonzero(n < 1e-5)[0]
        if small.size:
            ls = live[small]
            rr = _residual(kin, q[ls], xi)
            rn = np.sqrt(np.einsum("ij,ij->i", rr, rr))
            out.residual[ls] = rn
            # closed, or (Gauss-Newton on defects that do not re-assemble) at a least-squares point: no update left
            conv = small[(rn <= tol) | (n[small] <= 1e-12)]
            if conv.size:
                lc = live[conv]
                pinv, sig, cond = _inverse_parts(bp[conv], rank)
                out.ok[lc] = True
                out.q_b[lc], out.bp[lc], out.pinv[lc], out.sigma[lc], out.cond[lc] = q_before[conv], bp[conv], pinv, \
                    sig, cond
                out.tangent[lc] = -pinv @ b[conv][:, :, act]
                out.last[lc] = n[conv]
                rest = np.ones(len(live), bool)
                rest[conv] = False
                live = live[rest]
    return out


@dataclass
class OneStep:
    """What :func:`one_step` leaves per target (dimensionless ``B_p`` and its inverse at ``q_b``).

    Attributes
    ----------
    ok : ndarray of bool, (K,)
        The target passed every test of the certificate (see :func:`one_step`).
    q : ndarray, (K, n_q)
        End points (rad / mm); meaningful where ``ok``.
    q_b : ndarray, (K, n_q)
        Where the one Jacobian was evaluated (within ``last`` of ``q``).
    bp, pinv, tangent : ndarray
        ``B_p`` at ``q_b``, its (pseudo-)inverse and the branch tangent ``-B_p^+ B_a``.
    sigma, cond : ndarray, (K,)
        Lower bounds of ``sigma_r(B_p)`` and ``sigma_r / sigma_1`` at ``q``.
    theta : ndarray, (K,)
        Largest contraction of the corrector's updates.
    ratio : ndarray, (K,)
        ``omega / 2 max(corr, omega / 2 reach^2)``, the rule of every continuation step.
    kantorovich : ndarray, (K,)
        ``h = omega |B_p(q_b)^+ F(q_b)|`` (at most 1/2 when certified).
    why : ndarray of int, (K,)
        0 where ``ok``; else the code of the first failed test (``_REASONS``).
    """

    ok: np.ndarray
    q: np.ndarray
    q_b: np.ndarray
    bp: np.ndarray
    pinv: np.ndarray
    tangent: np.ndarray
    sigma: np.ndarray
    cond: np.ndarray
    theta: np.ndarray
    ratio: np.ndarray
    kantorovich: np.ndarray
    omega: np.ndarray
    why: np.ndarray


def one_step(kin, q0: np.ndarray, qb0: np.ndarray, b0: np.ndarray, t0: np.ndarray, p0: np.ndarray,
             qa1: np.ndarray, xi=None, rank: int | None = None, options: ContinuationOptions | None = None,
             omega: np.ndarray | None = None) -> OneStep:
    """Targets reached in one step from certified configurations, certified by a Kantorovich test (one Jacobian).

    Batched over targets: target ``k`` starts from the certified configuration ``q0[k]``
    (dimensionless ``B_p`` ``b0[k]`` evaluated at ``qb0[k]``, its (pseudo-)inverse ``p0[k]``
    and branch tangent ``t0[k]``, as :func:`continue_nearest` keeps them).  All lengths
    below are dimensionless (rad, mm / length scale).

    **Method.**  Predictor along the tangent, ``p = p0 + t0 (a1 - a0)`` (paper 1, eq. 3);
    two chord steps with the start's inverse (residual evaluations only); then the
    Jacobian ``B`` at that point ``x_b``, its inverse ``P_b = B_p(x_b)^+`` and the first
    Newton update ``alpha = |P_b F(x_b)|``.  When the Kantorovich number ``h = alpha omega``
    (below) is at most 1/2, simplified Newton with ``P_b`` (residual evaluations only) down
    to an update below 1e-12: **one Jacobian per certificate**.  Otherwise Newton goes on
    (a new Jacobian after each update, at most ``max_newton``), each update contracting by
    ``theta_max`` against the one before; right after a Newton update taken with
    ``h > 1/2``, one simplified update that does not contract at all (Deuflhard's
    monotonicity test) fails the target without spending another Jacobian.

    **Certificate.**  ``omega``, the affine-covariant Lipschitz constant of ``B_p``, is
    estimated by the chord ``||P_b (B_p(x0) - B_p(x_b))||_F / |x_b - x0|`` (Frobenius,
    never below the spectral estimate; at least ``omega`` given, the largest met on the
    path so far).

    1. *Kantorovich* (Kantorovich 1948; Deuflhard, *Newton Methods for Nonlinear Problems*,
       2004, sec. 2.1, for the simplified Newton method): with ``h <= 1/2`` the chord
       iteration from ``x_b`` converges to a solution ``x*`` within
       ``(1 - sqrt(1 - 2h)) / omega`` of ``x_b``, and no other solution with the same
       actuated values lies within ``rho = (1 + sqrt(1 - 2h)) / omega`` of ``x_b``;
    2. *same branch as the start*: the branch of ``x0`` reaches the target's actuated
       values within the predictor's error ``omega / 2 reach^2`` of the predicted point
       (``reach``: the step's length), hence within ``omega / 2 reach^2 + |x_b - x_pred|``
       of ``x_b``; that is required below ``rho``, so the branch point is ``x*``.  Also
       required, as for every step of :func:`continue_path`: corrector move and predictor
       error at most ``branch_fraction`` of ``2 / omega``;
    3. *conditioning*: lower bounds of ``sigma_r(B_p)`` and ``sigma_r / sigma_1`` at the end
       point from Frobenius norms (:func:`_inverse_parts`), multiplied by
       ``(1 - omega |x1 - x_b|)`` for the updates after ``x_b``, at least ``cond_tol``.

    The end point is returned after its last update (below 1e-12: a closed loop, or a
    least-squares point when the defects do not re-assemble, as in :func:`_correct`).  The
    estimates are those of :func:`continue_path` (from the computed points, not interval
    bounds).  A target that fails a test is reported with the reason (``why``).

    Returns
    -------
    OneStep

    Examples
    --------
    Not run here: see ``tests/solver/kinematics/test_continuation.py``.
    """
    opt = options or ContinuationOptions()
    m = kin.mechanism
    act, pas = np.asarray(m.actuated), np.asarray(m.passive)
    jscale = kin.joint_scale
    ja, jp = jscale[act], jscale[pas]
    qa1 = np.atleast_2d(np.asarray(qa1, dtype=float))
    k = len(qa1)
    if rank is None:
        rank = int(np.sum(np.linalg.svd(b0[:1], compute_uv=False)[0] > 1e-8 * np.abs(b0[:1]).max()))
    pred = np.array(q0, dtype=float, copy=True)
    pred[:, act] = qa1
    pred[:, pas] += (t0 @ ((qa1 - q0[:, act]) / ja)[:, :, None])[..., 0] * jp
    reach = np.linalg.norm((pred - q0) / jscale, axis=1)
    q = pred.copy()
    theta = np.zeros(k)
    alive = np.ones(k, bool)
    prev = np.full(k, np.inf)

    def chord(rows: np.ndarray, inv: np.ndarray, stop: float, count: bool,
              fail_above: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """One chord update of ``rows`` with ``inv``: the rows whose update is still above ``stop``, and the stalled.

        An update that does not contract by ``theta_max`` (counted from the second one) is not
        applied and stalls the row (it needs a new Jacobian); above ``fail_above`` it fails it.
        """
        every = rows.size == k
        r = _residual(kin, q if every else q[rows], xi)
        dq = -((inv if every else inv[rows]) @ r[:, :, None])[..., 0]
        n = np.sqrt(np.einsum("ij,ij->i", dq, dq))
        pr = prev[rows]
        th = np.where(np.isfinite(pr) & (pr > 1e-9), n / np.maximum(pr, 1e-300), 0.0)
        good = np.isfinite(n) & ((th <= opt.theta_max) if count else True)
        alive[rows[~np.isfinite(n) | (th > fail_above)]] = False
        rg = rows[good]
        if count:
            theta[rg] = np.maximum(theta[rg], th[good])
        q[np.ix_(rg, pas)] += dq[good] * jp
        prev[rg] = step_n[rg] = n[good]
        return rows[good & (n >= stop)], rows[~good & alive[rows]]

    step_n = np.full(k, np.inf)  # the last update applied
    # the approach: chord steps with the start's inverse, residual evaluations only (no part of the certificate)
    rows = np.arange(k)
    for it in range(2):
        if rows.size == 0:
            break
        rows = chord(rows, p0, 1e-6, it > 0)[0]
    # Newton until the Kantorovich number h = alpha omega at the Jacobian's point x_b is at most 1/2, then simplified
    # Newton with that Jacobian (residual evaluations only) while it contracts by theta_max.  A Newton update must
    # contract by theta_max against the update before it (as in _correct); right after one taken outside the
    # Kantorovich region, a simplified-Newton update that does not contract at all (Deuflhard's monotonicity
    # test) fails the row before another Jacobian is spent on it.
    alpha, w = np.full(k, np.inf), np.zeros(k)
    done = np.zeros(k, bool)
    todo = np.arange(k)
    for j in range(opt.max_newton):
        todo = todo[alive[todo]]
        if todo.size == 0:
            break
        every = todo.size == k
        qt = q.copy() if every else q[todo]
        r, b = _dimensionless_state(kin, qt, xi)
        bj = np.ascontiguousarray(b[:, :, pas])
        pj, sj, cj = _inverse_parts(bj, rank)
        if j == 0 and every:  # the first Jacobian of every row: its arrays, no copies
            bp, pinv, b_act, q_b, sig, cond = bj, pj, b[:, :, act], qt, sj, cj
        else:
            if j == 0:
                bp, pinv = np.zeros((k,) + bj.shape[1:]), np.zeros((k,) + pj.shape[1:])
                b_act, q_b, sig, cond = np.zeros((k,) + b.shape[1:2] + (len(act),)), q.copy(), np.zeros(k), np.zeros(k)
            bp[todo], pinv[todo], b_act[todo], q_b[todo], sig[todo], cond[todo] = bj, pj, b[:, :, act], qt, sj, cj
        first = -(pj @ r[:, :, None])[..., 0]
        a_ = np.sqrt(np.einsum("ij,ij->i", first, first))
        # omega: the chord estimate between the start's B_p and this one (Frobenius, so never below the spectral one)
        moved = np.linalg.norm((qt - (qb0 if every else qb0[todo])) / jscale, axis=1)
        change = pj @ ((b0 if every else b0[todo]) - bj)
        w_ = np.where(moved > 1e-8, np.sqrt(np.einsum("kij,kij->k", change, change)) / np.maximum(moved, 1e-300), 0.0)
        if omega is not None:  # the largest estimate met on the path so far (a shorter chord measures round-off)
            w_ = np.maximum(w_, omega[todo])
        # Newton's contraction: against the Newton update of the Jacobian before (none at the first)
        last_newton = alpha[todo]
        th = np.where(np.isfinite(last_newton) & (last_newton > 1e-9), a_ / np.maximum(last_newton, 1e-300), 0.0)
        theta[todo] = np.maximum(theta[todo], th)
        alpha[todo], w[todo] = a_, w_
        fin = np.isfinite(a_) & (th <= opt.theta_max)
        alive[todo[~fin]] = False
        q[np.ix_(todo[fin], pas)] += first[fin] * jp
        prev[todo] = a_
        step_n[todo] = a_
        inside_k = fin & (a_ * w_ <= 0.5)
        done[todo[inside_k & (a_ < 1e-12)]] = True
        rows = todo[inside_k & (a_ >= 1e-12)]
        stalled = [todo[:0]]
        for _ in range(4):  # simplified Newton in the Kantorovich region
            if rows.size == 0:
                break
            rows, st_ = chord(rows, pinv, 1e-12, True)
            stalled.append(st_)
        done[todo[inside_k]] = True
        again = np.concatenate(stalled + [rows])
        done[again] = False
        outside = todo[fin & ~inside_k]
        if outside.size:
            chord(outside, pinv, 0.0, True, fail_above=1.0)
        todo = np.concatenate([outside, again])
    unconverged = ~done | (step_n >= 1e-12)
    h = alpha * w
    last = np.linalg.norm((q - q_b) / jscale, axis=1)
    eps = np.minimum(w * last, 1.0)
    sig = sig * (1.0 - eps)
    cond = cond * (1.0 - eps) / (1.0 + eps)
    corr = np.linalg.norm((q - pred) / jscale, axis=1)
    ratio = 0.5 * w * np.maximum(corr, 0.5 * w * reach ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.where(w > 0, (1.0 + np.sqrt(np.maximum(1.0 - 2.0 * h, 0.0))) / w, np.inf)
    branch_gap = 0.5 * w * reach ** 2 + np.linalg.norm((q_b - pred) / jscale, axis=1)
    why = np.zeros(k, int)
    # converged: the last update below 1e-12 (a closed loop, or a least-squares point when the defects do not
    # re-assemble, as in _correct)
    failed_corrector = ~alive | unconverged | (h > 0.5)
    why[failed_corrector] = _NO_CONVERGENCE
    why[(why == 0) & (cond < opt.cond_tol)] = _SINGULAR
    why[(why == 0) & ((ratio > opt.branch_fraction) | ~(branch_gap < rho))] = _TOO_FAR
    tangent = -pinv @ b_act
    return OneStep(why == 0, q, q_b, bp, pinv, tangent, sig, cond, theta, ratio, h, w, why)


_BLOCK_POOL = None


def _blocks(k: int, block: int, part) -> list | None:
    """``[part(slice) for each block of block rows]`` on threads, or None when there are fewer than two blocks.

    numpy releases the GIL in its array loops, so blocks of batched kinematics overlap; each block
    is independent (its rows only), so the result does not depend on the number of threads.
    """
    global _BLOCK_POOL
    if k < 2 * block:
        return None
    threads = min(os.cpu_count() or 1, 8)
    if _BLOCK_POOL is None or _BLOCK_POOL._max_workers < threads:  # noqa: SLF001 - size check only
        _BLOCK_POOL = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="hyperstat-step")
    return list(_BLOCK_POOL.map(part, [slice(i, min(i + block, k)) for i in range(0, k, block)]))


def _correct_blocks(kin, q: np.ndarray, xi, rank: int, opt: ContinuationOptions, pinv0: np.ndarray,
                    block: int = 2048) -> _Corrected:
    """:func:`_correct` of ``q`` (in place) in blocks of ``block`` rows on threads (:func:`_blocks`)."""
    parts = _blocks(len(q), block, lambda sl: _correct(kin, q[sl], xi, rank, opt, pinv0=pinv0[sl]))
    if parts is None:
        return _correct(kin, q, xi, rank, opt, pinv0=pinv0)
    return _Corrected(*(np.concatenate([getattr(p_, f.name) for p_ in parts])
                        for f in dataclasses.fields(_Corrected)))


def _one_step_blocks(kin, q0, qb0, b0, t0, p0, qa1, xi, rank, opt, omega, block: int = 2048) -> OneStep:
    """:func:`one_step` in blocks of ``block`` targets on threads (:func:`_blocks`; about 2,000 targets also keep a
    block's arrays in the cache: faster than one large batch even on one thread)."""
    parts = _blocks(len(qa1), block, lambda sl: one_step(kin, q0[sl], qb0[sl], b0[sl], t0[sl], p0[sl], qa1[sl], xi,
                                                         rank, opt, None if omega is None else omega[sl]))
    if parts is None:
        return one_step(kin, q0, qb0, b0, t0, p0, qa1, xi, rank, opt, omega)
    return OneStep(*(np.concatenate([getattr(p_, f.name) for p_ in parts]) for f in dataclasses.fields(OneStep)))


def continue_nearest(
    kin,
    qa_targets: np.ndarray,
    xi: np.ndarray | None = None,
    start: np.ndarray | None = None,
    options: ContinuationOptions | None = None,
    pool: np.ndarray | None = None,
    inside=None,
) -> tuple[np.ndarray, BranchCertificate]:
    """Certified configurations at many actuated values, each continued from the nearest one certified.

    The one workspace sampler of hyperstat: :func:`hyperstat.solver.kinematics.sampling.assemble_nearest`,
    :func:`~hyperstat.solver.kinematics.sampling.sample_configurations` (analysis),
    :func:`hyperstat.solver.tolerances.accuracy.sample_workspace` (accuracy maps, worst
    cases, Monte Carlo) and :meth:`Kinematics.solve` for many targets from one start.

    **Method.** ``start`` (and ``pool``) are corrected onto ``F = 0`` and certified (Newton
    converged, ``B_p`` conditioned).  The targets are then taken in waves: first the
    ``4, 16, 64, ...`` targets nearest to ``start`` (up to 256), then the others in the
    given order in waves as large as the set certified so far (at most ``block``).  Every
    target of a wave starts from its nearest certified configuration (a k-d tree over the
    actuated values, scaled by the length scale for prismatic joints).  With ``one_step``
    (the default), a target within ``reach`` of it is first reached in **one step** by
    :func:`one_step`, all of the wave at once, in blocks of about 2,000 on threads: tangent
    predictor (``dq_p = -B_p^+ B_a dq_a``, paper 1, eq. 3), chord corrector, one Jacobian
    and the Kantorovich test.  The other targets, and those whose step fails, follow an
    adaptive path in steps of at most ``reach`` (shortened after a rejected step, longer
    after easy ones), every step again a :func:`one_step` (without ``one_step``: a Newton
    corrector, :func:`_correct`, as in issues 18 and 24).  A path is given up after two
    failed correctors in a row (the first may be the one-step try), or one on a short step;
    the paths still running after 24 rounds of a wave, and those whose step reached too far,
    are tried again after the waves from their nearest certified configuration at that
    time, with first steps half as long.  At most ``node_memory`` MiB of certified
    configurations are kept as start points; the rest are returned but not continued from.

    **Guarantee** (per step; :func:`one_step` for the one-step certificate): a configuration
    reported ``certified`` is linked to ``start`` by a chain of steps each of which (i)
    converged (the Kantorovich number ``h = alpha omega`` at most 1/2 at the last Jacobian
    with ``one_step``; Newton with contraction at most ``theta_max`` without), (ii) ends
    where a lower bound of the inverse condition number of the dimensionless ``B_p``
    (Frobenius norms, :func:`_inverse_parts`) is at least ``cond_tol``, and (iii) moved the
    passive joints from the predictor by, and predicted with an error of, at most
    ``branch_fraction`` of the estimated distance ``2 / omega`` to another solution with the
    same actuated values (with ``one_step`` also: the branch point inside the Kantorovich
    uniqueness ball), ``omega`` being the largest chord estimate
    ``||B_p(x1)^+ (B_p(x0) - B_p(x1))||_F / |x1 - x0|`` met along the chain (Frobenius, so
    never below the spectral estimate).  Under that estimate of the Lipschitz constant no
    step can reach another solution, so the configuration lies on the assembly branch of
    ``start``.  These are estimates from the computed path, not interval bounds (module
    docstring).  Targets that cannot be certified are reported with the reason, never as
    certified; with ``inside``, a certified configuration outside the workspace is reported
    uncertified with that reason.

    Parameters
    ----------
    kin : Kinematics
    qa_targets : ndarray, (K, n_actuated)
        Actuated values (rad / mm).
    xi : ndarray, (n_xi,), optional
        Defects (rad / mm), the same for every target.
    start : ndarray, (n_q,), optional
        Assembled start configuration (default: home).
    options : ContinuationOptions, optional
        Thresholds and ``reach`` (longest step, dimensionless actuated distance).
    pool : ndarray, (P, n_q), optional
        Configurations already certified on the branch of ``start`` at the same ``xi``; they
        are corrected and certified again and used as further start points.
    inside : callable, optional
        ``inside(q) -> bool (K,)``: configurations in the workspace (e.g. the declared passive
        ranges); only those are kept and continued from.

    Returns
    -------
    q : ndarray, (K, n_q)
        Configurations; an uncertified row holds the last certified point of its path.
    certificate : BranchCertificate
        Per target; ``steps``, ``path_length`` and the conditioning count the path from
        its neighbour (conditioning as lower bounds, see the guarantee).
    """
    from scipy.spatial import cKDTree

    opt = options or ContinuationOptions()
    m = kin.mechanism
    act, pas = np.asarray(m.actuated), np.asarray(m.passive)
    qa = np.atleast_2d(np.asarray(qa_targets, dtype=float))
    k = len(qa)
    if xi is not None and np.ndim(xi) != 1:
        raise ValueError("continue_nearest takes one defect vector (n_xi,) for every target.")
    q_home = np.asarray(m.home if start is None else start, dtype=float)
    jscale = kin.joint_scale
    ja, jp = jscale[act], jscale[pas]
    z = np.zeros(k)
    cert = BranchCertificate(np.zeros(k, bool), ["not reached"] * k, np.ones(k), np.full(k, np.inf), z.copy(),
                             z.copy(), np.zeros(k, int), np.zeros(k, int), z.copy(), np.ones(k), opt)
    q = np.array(np.broadcast_to(q_home, (k, kin.n_q)), dtype=float)
    if k == 0:
        return q, cert
    if len(m.closures) == 0 or len(pas) == 0:
        q[:, act] = qa
        cert.certified[:] = True
        cert.reason = [""] * k
        cert.path_length[:] = np.linalg.norm((qa - q_home[act]) / ja, axis=1)
        if inside is not None:
            out = ~np.asarray(inside(q), bool)
            cert.certified[out] = False
            for i in np.nonzero(out)[0]:
                cert.reason[i] = "outside the workspace's declared ranges"
        return q, cert
    inside = inside or (lambda qq: np.ones(len(qq), bool))
    # roots: the start (and the pool), corrected onto the closure and certified (step 0 of continue_path)
    roots = np.vstack([q_home[None, :]] + ([] if pool is None else [np.atleast_2d(np.asarray(pool, float))]))
    _, b0 = _dimensionless_state(kin, roots[:1], xi)
    s0 = np.linalg.svd(b0[:, :, pas], compute_uv=False)
    rank = int(np.sum(s0[0] > 1e-8 * max(s0[0, 0], 1e-300)))  # generic rank (a passive self-motion keeps it low)
    rc = _correct(kin, roots, xi, rank, opt, tol=1e-12)
    good = rc.ok & (rc.cond >= opt.cond_tol) & np.asarray(inside(roots), bool)
    if not good[0] and rc.ok[0] and rc.cond[0] >= opt.cond_tol:
        good[0] = True  # the start itself need not lie in the workspace; it is a start, not a sample
    if not good[0]:
        why = ("the start configuration could not be corrected onto the closure" if not rc.ok[0] else
               "the start configuration is near a singularity of the passive joints")
        cert.reason = [why] * k
        return q, cert
    # the configurations later targets start from, bounded in memory (opt.node_memory MiB)
    per_node = 8 * (2 * kin.n_q + rc.bp[0].size + rc.tangent[0].size + rc.pinv[0].size)
    cap = min(k + len(roots), max(int(opt.node_memory * 2 ** 20 // per_node), len(roots) + 256))
    node_q = np.zeros((cap, kin.n_q))
    node_b = np.zeros((cap,) + rc.bp.shape[1:])
    node_t = np.zeros((cap,) + rc.tangent.shape[1:])
    node_p = np.zeros((cap,) + rc.pinv.shape[1:])
    node_qb = np.zeros((cap, kin.n_q))  # where each node's B_p was evaluated (within 1e-5 of the node)
    nodes = 0

    def add_nodes(qn, qb, bn, tn, pn) -> None:
        """Keep certified configurations as start points (while the node memory lasts)."""
        nonlocal nodes
        take = min(len(qn), cap - nodes)
        new = slice(nodes, nodes + take)
        node_q[new], node_qb[new], node_b[new], node_t[new], node_p[new] = qn[:take], qb[:take], bn[:take], \
            tn[:take], pn[:take]
        nodes += take

    add_nodes(roots[good], rc.q_b[good], rc.bp[good], rc.tangent[good], rc.pinv[good])
    if len(act) == 0:  # nothing is actuated (a rigid structure): every target is the certified start itself
        q[:] = node_q[0]
        cert.certified[:] = True
        cert.reason = [""] * k
        cert.min_condition[:] = cert.end_condition[:] = rc.cond[0]
        return q, cert
    code = np.full(k, _NOT_REACHED)  # why a target is not certified (index into _REASONS); 0 = certified
    last_d = np.full(k, np.inf)

    def run(idx: np.ndarray, extra: int, tried: np.ndarray | None = None) -> None:
        """Paths of targets ``idx`` from their nearest node; first steps ``2**extra`` times shorter than ``reach``.

        Adaptive steps as in :func:`continue_path`: a rejected step is shortened (to aim at
        70 % of the branch bound when it reached too far, halved when the corrector failed),
        an accepted one lengthened by at most 2x after an easy corrector.  A path is given up
        after ``max_rejections`` consecutive rejections, or after two failed correctors in a
        row (the target is then most likely beyond a fold of the workspace).  Every step is
        one :func:`one_step` (a chord corrector, one Jacobian, the Kantorovich test) with
        ``one_step``, a Newton corrector (:func:`_correct`) without.  ``tried``: the node from which
        :func:`fast` tried each target in one step and failed its corrector (-1: none); from that
        node the path starts with half that step, and that failure counts as the first of two.
        """
        n_i = len(idx)
        d, nn = cKDTree(node_q[:nodes, act] / ja).query(qa[idx] / ja)
        d, nn = np.atleast_1d(d), np.atleast_1d(nn)
        last_d[idx] = d
        h = np.where(d > 0, np.minimum(opt.reach / (2 ** extra) / np.maximum(d, 1e-300), 1.0), 1.0)
        again = np.zeros(n_i, bool) if tried is None else tried == nn
        h[again] *= 0.5
        pos = np.zeros(n_i)
        cur_q, cur_b, cur_t, cur_p = node_q[nn], node_b[nn], node_t[nn], node_p[nn]  # fancy indexing: copies
        cur_qb = node_qb[nn]
        cur_w = np.zeros(n_i)  # the Lipschitz estimate of this path (as continue_path from the neighbour)
        a0 = cur_q[:, act].copy()
        alive = np.ones(n_i, bool)
        finished = np.zeros(n_i, bool)
        why = np.zeros(n_i, int)
        streak, nonconv = again.astype(int), again.astype(int)
        rejected = again.astype(int)
        mincond, minsig, endcond = np.ones(n_i), np.full(n_i, np.inf), np.zeros(n_i)
        maxth, maxratio = np.zeros(n_i), np.zeros(n_i)
        steps = np.zeros(n_i, int)
        # a wave stops after 24 rounds: its few slow paths are taken up again together after the last wave
        for round_ in range(24 if extra == 0 else 100000):
            sel = np.nonzero(alive & ~finished)[0]
            if sel.size == 0 or (extra == 0 and round_ >= 4 and n_i >= 4096 and sel.size < n_i // 50):
                break  # the few slow paths of a wave are taken up again together, after the last wave
            hs = np.minimum(h[sel], 1.0 - pos[sel])
            target = a0[sel] + (qa[idx[sel]] - a0[sel]) * (pos[sel] + hs)[:, None]
            last_step = pos[sel] + hs >= 1.0 - 1e-12
            target[last_step] = qa[idx[sel[last_step]]]
            qc = cur_q[sel]
            da = (target - qc[:, act]) / ja
            pred = qc.copy()
            pred[:, act] = target
            pred[:, pas] += (cur_t[sel] @ da[:, :, None])[..., 0] * jp
            if opt.one_step:
                c = _one_step_blocks(kin, qc, cur_qb[sel], cur_b[sel], cur_t[sel], cur_p[sel], target, xi, rank, opt,
                                     cur_w[sel])
                qn, w, cond, sig = c.q, c.omega, c.cond, c.sigma
                ok = c.why != _NO_CONVERGENCE
                singular, too_far, acc = c.why == _SINGULAR, c.why == _TOO_FAR, c.ok
                ratio = c.ratio
            else:
                qn = pred.copy()
                c = _correct_blocks(kin, qn, xi, rank, opt, cur_p[sel])
                ok = c.ok
                moved = np.linalg.norm((c.q_b - cur_qb[sel]) / jscale, axis=1)  # between the points where B was taken
                corr = np.linalg.norm((qn - pred) / jscale, axis=1)
                reach = np.linalg.norm((pred - qc) / jscale, axis=1)
                chord = c.pinv @ (cur_b[sel] - c.bp)
                w_step = np.sqrt(np.einsum("kij,kij->k", chord, chord)) / np.maximum(moved, 1e-300)
                w = np.maximum(np.where(moved > 1e-8, w_step, 0.0), cur_w[sel])  # (a shorter chord measures round-off)
                # B_p at the end point is B_p(q_b) (I + E) with ||E|| <= w |last|: the bounds move by that factor
                eps = np.minimum(w * c.last, 1.0)
                sig = c.sigma * (1.0 - eps)
                cond = c.cond * (1.0 - eps) / (1.0 + eps)
                ratio = 0.5 * w * np.maximum(corr, 0.5 * w * reach ** 2)
                # the Kantorovich test at the last Jacobian (as one_step): h = omega |last update| <= 1/2 gives the
                # solution and a ball of radius rho about q_b in which it is the only one; the branch point of the
                # start lies within the predictor's error plus |q_b - pred| of q_b, which must be inside it
                kant = w * c.last
                ok = ok & (kant <= 0.5)
                with np.errstate(divide="ignore", invalid="ignore"):
                    rho = np.where(w > 0, (1.0 + np.sqrt(np.maximum(1.0 - 2.0 * kant, 0.0))) / w, np.inf)
                gap = 0.5 * w * reach ** 2 + np.linalg.norm((c.q_b - pred) / jscale, axis=1)
                singular = ok & (cond < opt.cond_tol)
                too_far = ok & ~singular & ((ratio > opt.branch_fraction) | ~(gap < rho))
                acc = ok & ~singular & ~too_far
            sa = sel[acc]
            cur_q[sa], cur_qb[sa], cur_b[sa], cur_t[sa], cur_p[sa], cur_w[sa] = \
                qn[acc], c.q_b[acc], c.bp[acc], c.tangent[acc], c.pinv[acc], w[acc]
            mincond[sa] = np.minimum(mincond[sa], cond[acc])
            endcond[sa] = cond[acc]
            minsig[sa] = np.minimum(minsig[sa], sig[acc])
            maxth[sa] = np.maximum(maxth[sa], c.theta[acc])
            maxratio[sa] = np.maximum(maxratio[sa], ratio[acc])
            steps[sa] += 1
            pos[sa] += hs[acc]
            finished[sa] = last_step[acc]
            aim = np.where(ratio > 0, np.sqrt(0.7 * opt.branch_fraction / np.maximum(ratio, 1e-300)), 2.0)
            easy = c.theta < opt.theta_max / 4
            grow = np.clip(np.where(easy, np.minimum(aim, 2.0), np.minimum(aim, 1.0)), 0.5, 2.0)
            h[sel] = np.where(acc, hs * grow, np.where(too_far, hs * np.clip(aim, 0.1, 0.5), hs * 0.5))
            streak[sa], nonconv[sa] = 0, 0
            rj = sel[~acc]
            streak[rj] += 1
            rejected[rj] += 1
            nonconv[sel[~ok]] += 1
            nonconv[sel[ok]] = 0
            why[sel] = np.where(acc, why[sel], np.where(singular, _SINGULAR, np.where(too_far, _TOO_FAR,
                                                                                       _NO_CONVERGENCE)))
            # two failed correctors in a row, or one on a step already short: beyond a fold (or outside the set)
            beyond = (nonconv[sel] >= 2) | ((nonconv[sel] >= 1) & (hs * d[sel] < 0.25 * opt.reach))
            nonconv[sel[~ok & beyond]] = 2
            dead = singular | (~acc & ((streak[sel] >= opt.max_rejections) | beyond
                                       | (h[sel] * d[sel] < opt.min_step))) | (steps[sel] + rejected[sel] >= 400)
            alive[sel[dead]] = False
        done = alive & finished  # the last accepted step ended at the target
        why[alive & ~finished] = _NOT_REACHED
        cur_q[np.ix_(np.nonzero(done)[0], act)] = qa[idx[done]]
        inn = np.asarray(inside(cur_q), bool)
        q[idx] = cur_q
        cert.min_condition[idx], cert.min_sigma[idx] = mincond, minsig
        cert.max_contraction[idx], cert.max_branch_ratio[idx] = maxth, maxratio
        cert.steps[idx] += steps
        cert.rejected[idx] += rejected
        cert.path_length[idx] = d
        cert.end_condition[idx] = endcond
        keep = done & inn
        # a corrector that fails again with a step half as long: the target is beyond a fold of the workspace
        why = np.where((why == _NO_CONVERGENCE) & (nonconv >= 2), _BEYOND_KANTOROVICH if opt.one_step else _BEYOND,
                       why)
        code[idx] = np.where(keep, 0, np.where(done, _OUTSIDE_RANGES, why))
        cert.certified[idx] = keep
        add_nodes(cur_q[keep], cur_qb[keep], cur_b[keep], cur_t[keep], cur_p[keep])

    def fast(idx: np.ndarray, extra: int = 0) -> None:
        """Targets ``idx`` within ``reach`` of their nearest node in one step each (:func:`one_step`, all at once).

        The others, and those whose step fails, follow the adaptive path of :func:`run`.
        """
        d, nn = cKDTree(node_q[:nodes, act] / ja).query(qa[idx] / ja)
        d, nn = np.atleast_1d(d), np.atleast_1d(nn)
        near = np.nonzero(d <= opt.reach)[0]
        tried = np.full(len(idx), -1)
        done = np.zeros(len(idx), bool)
        if near.size:
            m_ = nn[near]
            st = _one_step_blocks(kin, node_q[m_], node_qb[m_], node_b[m_], node_t[m_], node_p[m_], qa[idx[near]], xi,
                                  rank, opt, None)
            inn = np.asarray(inside(st.q), bool)
            keep = st.ok & inn
            ks = idx[near[keep]]
            q[ks] = st.q[keep]
            cert.certified[ks] = True
            code[ks] = 0
            cert.min_condition[ks] = cert.end_condition[ks] = st.cond[keep]
            cert.min_sigma[ks], cert.max_contraction[ks], cert.max_branch_ratio[ks] = st.sigma[keep], \
                st.theta[keep], st.ratio[keep]
            cert.steps[ks] = 1
            cert.path_length[ks] = d[near[keep]]
            add_nodes(st.q[keep], st.q_b[keep], st.bp[keep], st.tangent[keep], st.pinv[keep])
            out = st.ok & ~inn  # on the branch, outside the declared passive ranges: no other path changes that
            ko = idx[near[out]]
            q[ko], code[ko], cert.steps[ko], cert.path_length[ko] = st.q[out], _OUTSIDE_RANGES, 1, d[near[out]]
            done[near[st.ok]] = True
            failed = st.why == _NO_CONVERGENCE
            tried[near[failed]] = m_[failed]
        if not done.all():
            run(idx[~done], extra, tried[~done])

    def retryable(idx: np.ndarray) -> np.ndarray:
        return idx[np.isin(code[idx], (_NOT_REACHED, _TOO_FAR))]

    # waves: the nearest targets to the roots first (growing 4x from 4), then the rest in order, each wave about as
    # large as the set certified before it; a failed path is tried once more at once with steps half as long
    d0, _ = cKDTree(node_q[:nodes, act] / ja).query(qa / ja)
    near_first = np.argsort(d0, kind="stable")[: min(k, 256)]
    rest = np.setdiff1d(np.arange(k), near_first, assume_unique=True)
    waves, pos, size = [], 0, 4
    while pos < len(near_first):
        waves.append(near_first[pos: pos + size])
        pos += size
        size *= 4
    pos = 0
    while pos < len(rest):
        size = min(max(sum(len(w_) for w_ in waves), 256), max(opt.block, 256))
        waves.append(rest[pos: pos + size])
        pos += size
    for wave in waves:
        (fast if opt.one_step else run)(wave, 0)
    # then, from the nearest certified configuration at that time, with shorter first steps
    for extra in range(1, opt.retries + 1):
        again = retryable(np.arange(k))
        if again.size == 0:
            break
        run(again, extra)
    cert.reason = [_REASONS[c_] for c_ in code]
    return q, cert


_NOT_REACHED, _SINGULAR, _TOO_FAR, _NO_CONVERGENCE, _OUTSIDE_RANGES, _BEYOND, _BEYOND_KANTOROVICH = range(1, 8)
_REASONS = ["", "not reached", "the path passes near a singularity of the passive joints",
            "the step reaches too far against the distance to another solution",
            "the corrector did not converge (the step is too long or the target beyond a fold)",
            "certified on the branch but outside the workspace's declared ranges",
            "the corrector did not converge on a short step or twice in a row (the target outside the reachable set "
            "or beyond a fold of the workspace?)",
            "the Kantorovich test failed on a short step or twice in a row (the target outside the reachable set, or "
            "beyond a singularity of the passive joints such as a fold of the workspace?)"]
