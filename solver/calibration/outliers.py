"""Observations out of line with the others, and poses repeated within the noise.

Units: lengths in mm, angles in rad; residuals weighted by the stated noise (1 = one standard
deviation per axis) when the data state one.

**Outliers** (:func:`deleted_residual_test`).  One gross error (a reflector knocked, a row of
another pose) pulls a least-squares fit towards itself and spreads over every residual: its own
residual shrinks, the others grow, and a test on the fitted residuals misses it or blames a
missing effect.  Each observation is therefore judged with itself left out: for the block ``B``
of its residual rows (3 positions, and 3 orientations with 6-D data), the deleted residual of the
linearised fit is ``e_(B) = (I - H_BB)^-1 r_B`` with ``H = J (J^T J)^-1 J^T`` the hat matrix of
the weighted Jacobian at the solution (Cook and Weisberg, *Residuals and Influence in
Regression*, 1982, sec. 4.2; the case-deletion formula, exact for the linearised problem), and
its covariance is ``s^2 (I - H_BB)^-1``.  The normalised statistic

``t_B^2 = r_B^T (I - H_BB)^-1 r_B / s^2``

follows a chi-square law with ``|B|`` degrees of freedom.  The scale ``s`` is robust: the median
of ``t^2 s^2`` over the observations divided by the chi-square median (a few gross errors do not
hide themselves by inflating it), and never below 1 when the data state their noise (an outlier
is then out of line with the stated noise too).  An observation is flagged when its p-value is
below :data:`FAMILY_ALPHA` divided by the number of observations (Bonferroni: in a clean
campaign, all observations together are flagged with probability 0.1 %).  Held-out observations
are prediction errors already: ``t^2 = |r|^2 / s^2`` with the identification's ``s``.

**Repeated poses** (:func:`coincident_poses`).  Two poses whose actuated values differ by less
than the stated noise can tell (the output point moves by less than one standard deviation per
axis between them, to first order) and whose metadata are equal observe the same thing; a copied
row with a jitter of 1e-9 passes an exact-equality check and doubles the count of "independent"
equations, so every standard deviation comes out ``sqrt(2)`` too small.  They are grouped, and
:func:`~hyperstat.solver.calibration.identify.identify` counts each group once.

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> j = rng.normal(size=(60, 3))                    # 20 observations of 3 rows, 3 parameters
>>> y = j @ [1.0, -2.0, 0.5] + rng.normal(size=60)  # unit noise
>>> y[30:33] += 40.0                                # a gross error in observation 10
>>> r = y - j @ np.linalg.lstsq(j, y, rcond=None)[0]
>>> t2, scale, flagged = deleted_residual_test(r, j, [np.arange(3 * i, 3 * i + 3) for i in range(20)], True)
>>> np.flatnonzero(flagged).tolist()
[10]
"""

from __future__ import annotations

import numpy as np

__all__ = ["FAMILY_ALPHA", "deleted_residual_test", "threshold", "coincident_poses", "coincident_across", "chi2_isf",
           "chi2_median", "copied_reading", "COPY_FRACTION"]

#: two readings of one pose that agree to this fraction of the noise on every axis are one row copied: independent
#: readings differ by about the noise (the chance that two agree this closely on three axes is about 1e-9)
COPY_FRACTION = 1e-3

#: family-wise false-alarm probability of the outlier test over a whole campaign (Bonferroni)
FAMILY_ALPHA = 1e-3


def chi2_isf(p: float | np.ndarray, k: int | np.ndarray) -> float | np.ndarray:
    """The chi-square quantile of upper tail ``p`` (0 < p < 1) with ``k`` > 0 degrees of freedom, as
    ``scipy.stats.chi2.isf`` computes it (``chdtri``) without importing scipy.stats (0.3 s).

    >>> from scipy.stats import chi2
    >>> all(chi2_isf(p, k) == chi2.isf(p, k) for p in (1e-6, 1e-3 / 7, 0.5) for k in (1, 3, 6))
    True
    """
    from scipy.special import chdtri

    return chdtri(k, p)


def chi2_median(k: int | np.ndarray) -> float | np.ndarray:
    """The chi-square median with ``k`` > 0 degrees of freedom, as ``scipy.stats.chi2.ppf(0.5, k)`` computes it.

    >>> from scipy.stats import chi2
    >>> all(chi2_median(k) == chi2.ppf(0.5, k) for k in (1, 2, 3, 6, 9))
    True
    """
    from scipy.special import gammaincinv

    return 2 * gammaincinv(np.asarray(k) / 2, 0.5)


def threshold(k: int, n_observations: int) -> float:
    """The value of ``t^2`` above which an observation of ``k`` rows is flagged among ``n_observations``."""
    return float(chi2_isf(FAMILY_ALPHA / max(n_observations, 1), k))


def _deleted(r: np.ndarray, j: np.ndarray, blocks: list, active: np.ndarray) -> np.ndarray:
    """``r_B^T (I - H_BB)^-1 r_B`` of every block, with the hat matrix of the active blocks' rows (0 for the others'
    own leverage: a block already out is judged by its residual against the fit without it)."""
    rows = np.concatenate([blocks[i] for i in np.flatnonzero(active)]) if active.any() else np.zeros(0, dtype=int)
    q = np.zeros(len(blocks))
    if j is not None and j.shape[1] and len(rows):
        qa, _ = np.linalg.qr(j[rows])
        where = np.full(len(r), -1)
        where[rows] = np.arange(len(rows))
    else:
        qa, where = None, None
    for i, b in enumerate(blocks):
        rb = r[b]
        if qa is None or not active[i]:
            q[i] = float(rb @ rb)
            continue
        qb = qa[where[b]]
        try:
            q[i] = float(rb @ np.linalg.solve(np.eye(len(b)) - qb @ qb.T, rb))
        except np.linalg.LinAlgError:  # an observation that alone fixes a parameter: it cannot be judged
            q[i] = 0.0
        if not np.isfinite(q[i]) or q[i] < 0:
            q[i] = 0.0
    return q


def deleted_residual_test(r: np.ndarray, j: np.ndarray, blocks: list, noise_stated: bool,
                          scale: float | None = None, max_flagged: int = 20) -> tuple[np.ndarray, float, np.ndarray]:
    """Normalised deleted residuals ``t^2`` of observation blocks, the robust scale, and the outlier flags.

    A gross error pulls the fit and can lift its neighbours' statistics above the limit (swamping),
    and two of them can hide each other (masking).  The test therefore steps backwards: the worst
    flagged block is set aside, the linearised fit is redone without it (``r <- r + J delta``,
    ``delta`` the least-squares step on the remaining rows), and the others are judged again,
    until none is flagged (at most ``max_flagged`` blocks set aside).  The flagged blocks are those
    set aside; each keeps the ``t^2`` it had when it was.

    Parameters
    ----------
    r : ndarray, (N,)
        Weighted residuals at the solution (prediction minus measurement).
    j : ndarray, (N, p)
        Weighted Jacobian of the fitted (base) parameters at the solution (None for held-out data).
    blocks : list of ndarray of int
        Rows of each observation (one block per observation; repeated poses of one target merged).
    noise_stated : bool
        Whether ``r`` is weighted by a stated noise (the scale is then at least 1).
    scale : float, optional
        Impose the scale ``s`` (e.g. the identification's, for held-out data); robust estimate otherwise.
    max_flagged : int
        Most blocks set aside.

    Returns
    -------
    t2 : ndarray, (n_blocks,)
        ``r_B^T (I - H_BB)^-1 r_B / s^2``.
    s : float
        The scale of the last round.
    flagged : ndarray of bool
        p-value below :data:`FAMILY_ALPHA` / n_blocks when set aside.
    """
    r = np.asarray(r, dtype=float).copy()
    k = np.array([len(b) for b in blocks], dtype=int)
    limit = chi2_isf(FAMILY_ALPHA / max(len(blocks), 1), k)
    active = np.ones(len(blocks), dtype=bool)
    flagged = np.zeros(len(blocks), dtype=bool)
    t2_out = np.zeros(len(blocks))
    s2 = 1.0
    while True:
        q = _deleted(r, j, blocks, active)
        if scale is None:
            med = chi2_median(k[active]) if active.any() else np.ones(1)
            s2 = float(np.median(q[active] / med)) if active.any() else 1.0
            if noise_stated:
                s2 = max(s2, 1.0)
            s2 = max(s2, 1e-300)
        else:
            s2 = max(float(scale) ** 2, 1e-300)
        t2 = q / s2
        t2_out[active] = t2[active]
        over = active & (t2 > limit)
        if not over.any() or flagged.sum() >= max_flagged or active.sum() <= 1:
            break
        worst = int(np.argmax(np.where(over, t2, -np.inf)))
        flagged[worst] = True
        active[worst] = False
        if j is not None and j.shape[1]:
            rows = np.concatenate([blocks[i] for i in np.flatnonzero(active)])
            delta = np.linalg.lstsq(j[rows], -r[rows], rcond=None)[0]
            r = r + j @ delta
    return t2_out, float(np.sqrt(s2)), flagged


def _pose_table(data) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First row of each distinct pose, its actuated values and its metadata key (rounded), in pose order."""
    first = {}
    for i, p in enumerate(data.pose_id):
        first.setdefault(p, i)
    idx = np.array(list(first.values()), dtype=int)
    meta = np.stack([np.round(np.asarray(data.metadata[n], dtype=float)[idx], 9) for n in sorted(data.metadata)],
                    axis=1) if data.metadata else np.zeros((len(idx), 0))
    return idx, np.asarray(data.q, dtype=float)[idx], meta


def _close_pairs(qa: np.ndarray, qb: np.ndarray | None, width: np.ndarray) -> list:
    """Pairs of rows whose actuated values differ by less than 1e-3 of each joint's range (candidates)."""
    from scipy.spatial import cKDTree

    unit = 1e-3 * np.where(width > 0, width, 1.0)
    ta = cKDTree(qa / unit)
    if qb is None:
        return sorted(ta.query_pairs(1.0, p=np.inf))
    tb = cKDTree(qb / unit)
    return [(i, jj) for i, js in enumerate(ta.query_ball_tree(tb, 1.0, p=np.inf)) for jj in js]


def _moves_less_than(dq: np.ndarray, twist: np.ndarray, length: float, sigma: float) -> bool:
    """Whether actuated steps ``dq`` move the output (twist per unit actuated value, (6, n)) less than ``sigma``."""
    d = twist @ dq
    return float(np.linalg.norm(d[3:]) + length * np.linalg.norm(d[:3])) <= sigma


def coincident_poses(data, twists: np.ndarray, sigma_axis: np.ndarray, width: np.ndarray,
                     length: float) -> list[list[str]]:
    """Groups of poses that coincide within the noise (same metadata), each group listed by pose id.

    Parameters
    ----------
    data : MeasurementSet
    twists : ndarray, (K, 6, n_actuated)
        Output twist (angular, then linear at the output origin) per unit actuated value at each row.
    sigma_axis : ndarray, (K,)
        One standard deviation per axis of each row's measurement (mm).
    width : ndarray, (n_actuated,)
        Actuated joint range widths (rad / mm): candidates differ by less than 1e-3 of them.
    length : float
        The machine's length scale (mm): a rotation of the output moves a target by at most this arm.

    Returns
    -------
    list of list of str
        Groups of two or more poses (the first of each group first), in file order.
    """
    idx, qa, meta = _pose_table(data)
    ids = [data.pose_id[i] for i in idx]
    parent = list(range(len(idx)))

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b in _close_pairs(qa, None, width):
        if not np.array_equal(meta[a], meta[b]):
            continue
        sig = min(sigma_axis[idx[a]], sigma_axis[idx[b]])
        if _moves_less_than(qa[b] - qa[a], twists[idx[a]], length, sig):
            ra, rb = root(a), root(b)
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
    groups: dict = {}
    for a in range(len(idx)):
        groups.setdefault(root(a), []).append(ids[a])
    return [g for _, g in sorted(groups.items()) if len(g) > 1]


def coincident_across(data, held_out, twists: np.ndarray, sigma_axis: np.ndarray, width: np.ndarray,
                      length: float) -> list[tuple[str, str]]:
    """Held-out poses that repeat identification poses within the noise: ``(held-out pose, identification pose)``."""
    ia, qa, ma = _pose_table(data)
    ib, qb, mb = _pose_table(held_out)
    if ma.shape[1] != mb.shape[1]:
        return []
    out = []
    for a, b in _close_pairs(qb, qa, width):
        if np.array_equal(mb[a], ma[b]) and _moves_less_than(qa[b] - qb[a], twists[ia[b]], length, sigma_axis[ia[b]]):
            out.append((held_out.pose_id[ib[a]], data.pose_id[ia[b]]))
    return sorted(set(out), key=lambda p: held_out.pose_id.index(p[0]))


def copied_reading(data, pose: str, other, other_pose: str, sigma: float) -> bool:
    """Whether two poses that coincide within the noise carry the same reading: a row copied, not a pose measured again.

    Two poses measured at one place are two readings: their measured positions differ by about the noise, and each
    is an independent measurement.  A copied row (a campaign pasted twice, with a jitter of the joint values that an
    exact-equality check lets through) repeats the reading itself: every target within :data:`COPY_FRACTION` of the
    noise ``sigma`` (mm per axis) on every axis.

    Parameters
    ----------
    data, other : MeasurementSet
        The sets holding ``pose`` and ``other_pose`` (the same set, or the fitted and the held-out ones).
    pose, other_pose : str
        Pose ids.
    sigma : float
        One standard deviation of the noise per axis (mm).

    Returns
    -------
    bool
    """
    rows_a = [i for i, p in enumerate(data.pose_id) if p == pose]
    rows_b = [i for i, p in enumerate(other.pose_id) if p == other_pose]
    if len(rows_a) != len(rows_b):
        return False
    pa = np.asarray(data.position, dtype=float)[rows_a]
    pb = np.asarray(other.position, dtype=float)[rows_b]
    return bool(np.max(np.abs(pa - pb)) <= COPY_FRACTION * sigma)
