"""The drawing read as a whole: every assembly condition at a corner of its tolerance at once.

Units: violations in mm and rad; clearances as declared (mm, rad).

Each assembly condition's value (:mod:`hyperstat.solver.tolerances.clearance`) is the largest
violation the joint clearances absorb *alone*, at every configuration of the workspace.  A workshop
reads a drawing as a whole: every part may be anywhere within its zones at once, so the violations
add up.  At a configuration ``q``, with ``W_i`` the closure rows left to the clearances per unit of
condition ``i`` (``U0^T A d_i``) and ``F`` those per unit of each play (``U0^T A C``), the conditions
at values ``v`` assemble for every choice of signs when the box ``{sum s_i v_i W_i, |s_i| <= 1}`` lies
in the set the plays reach, ``F Y``.  The smallest factor ``alpha(q)`` on the plays that makes it so
(the **clearance need**) is, by linear-programming duality,

    alpha(q) = max over u with h_Y(F^T u) <= 1 of  sum_i v_i |u . W_i|

(``h_Y`` the support function of the play set, a sum of maxima of linear pieces,
:func:`hyperstat.solver.tolerances.clearance._dual_pieces``): a convex function maximised over a
polytope, solved exactly as a mixed-integer linear programme (one binary per condition: the sign it
takes; HiGHS through :func:`scipy.optimize.milp`).  ``alpha <= 1`` at every configuration: the drawing
assembles.

:func:`allocate_together` gives the conditions their values together: all of them scaled by the same
factor from their single values until the worst configuration binds (``alpha = 1``), then the
conditions that do not enter a binding configuration's worst case grow on (max-min, progressive
filling), each never beyond its single value.  The configurations are those the single values were
searched from, the workspace's corners, edges, faces and dead centres, and every condition's own worst
configuration.  :func:`confirm_corner` re-assembles the worst corner through the nonlinear model,
the plays as bounded joints.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["clearance_need", "allocate_together", "confirm_corner", "whole_drawing_summary", "EXACT_TOP"]

#: where the plays leave more than three closure rows (a spatial model of a planar parallel robot): the clearance
#: need is solved exactly (mixed-integer programme) at this many worst configurations of a local search, which
#: gives a lower bound elsewhere
EXACT_TOP = 4
#: where more than three rows are left: the upper bound is solved at this many configurations of largest lower bound
#: and this many of largest triangle bound
GENERAL_SOLVED = 6
#: above this size per configuration (conditions times plays and twice the polygon rows), the decision rule's linear
#: programme takes minutes per configuration: the triangle bound is used alone (safe, more conservative); the
#: revolute Delta has 19,740, the 3-RRR 3,780, the planar 3-RPR 3,477
DECISION_RULE_VARIABLES = 10000


def _pieces_matrix(model, f: np.ndarray) -> np.ndarray:
    """``pieces(u) = sum_j u_j P[j]``: the linear pieces of ``h_Y(F^T u)`` per unit of each closure row, (m, T, N)."""
    from hyperstat.solver.tolerances.clearance import _dual_pieces

    # every row in one call, each as a (1, n_g) matrix: numpy multiplies each by the polygon's vertices as it does a
    # single row (a vector-matrix product: the same bits, unlike one (m, n_g) matrix product)
    return _dual_pieces(model, np.asarray(f)[:, None, :])[:, 0]


def _need_at(model, f: np.ndarray, w: np.ndarray, v: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """``alpha``, the worst signs and the dual direction ``u`` at one configuration (module docstring)."""
    from scipy.optimize import Bounds, LinearConstraint, milp

    m, n = w.shape
    if m == 0 or not np.any(v * np.linalg.norm(w, axis=0) > 0):
        return 0.0, np.ones(n), np.zeros(m)
    pieces = _pieces_matrix(model, f)  # (m, T, N)
    n_t, n_p = pieces.shape[1], pieces.shape[2]
    scale = max(float(np.max(np.abs(pieces))), 1e-300)
    # big-M: |u . W_i| <= max over the polar of it; bounded through u's box from the polar (each |u_j| <= 1 / h
    # of +-e_j), computed by a first relaxation: the polar is bounded when the plays reach every closure row
    cap = _polar_box(pieces)
    if not np.all(np.isfinite(cap)):
        return math.inf, np.ones(n), np.zeros(m)
    big = 2.0 * (np.abs(w).T @ cap) + 1e-12  # (n,): twice the largest |u . W_i|
    # variables: u (m), tau (T), z (n), b (n)
    nv = m + n_t + 2 * n
    iu, it, iz, ib = 0, m, m + n_t, m + n_t + n
    rows, lo, hi = [], [], []
    # tau_T >= pieces_Tk(u):  pieces_Tk . u - tau_T <= 0
    for t in range(n_t):
        for k in range(n_p):
            r = np.zeros(nv)
            r[iu:iu + m] = pieces[:, t, k] / scale
            r[it + t] = -1.0 / scale
            rows.append(r), lo.append(-np.inf), hi.append(0.0)
    r = np.zeros(nv)
    r[it:it + n_t] = 1.0
    rows.append(r), lo.append(-np.inf), hi.append(1.0)
    for i in range(n):
        wi = w[:, i]
        r = np.zeros(nv)  # z_i - u.W_i + M b_i <= M
        r[iz + i], r[iu:iu + m], r[ib + i] = 1.0, -wi, big[i]
        rows.append(r), lo.append(-np.inf), hi.append(big[i])
        r = np.zeros(nv)  # z_i + u.W_i - M b_i <= 0
        r[iz + i], r[iu:iu + m], r[ib + i] = 1.0, wi, -big[i]
        rows.append(r), lo.append(-np.inf), hi.append(0.0)
    cost = np.zeros(nv)
    cost[iz:iz + n] = -v
    lb = np.r_[-cap, np.full(n_t, -np.inf), -big, np.zeros(n)]
    ub = np.r_[cap, np.full(n_t, np.inf), big, np.ones(n)]
    integrality = np.r_[np.zeros(m + n_t + n), np.ones(n)]
    res = milp(cost, constraints=LinearConstraint(np.array(rows), lo, hi), integrality=integrality,
               bounds=Bounds(lb, ub), options={"mip_rel_gap": 1e-9})
    if res.x is None:
        return math.inf, np.ones(n), np.zeros(m)
    u = res.x[iu:iu + m]
    signs = np.sign(w.T @ u)
    signs[signs == 0] = 1.0
    return float(np.sum(v * np.abs(w.T @ u))), signs, u


def _polar_box(pieces: np.ndarray) -> np.ndarray:
    """A box containing the polar set ``{u : h(u) <= 1}``: ``|u_j| <= 1 / min(h(e_j), h(-e_j))`` is not a bound in
    general, so the box comes from one linear programme per coordinate (m small)."""
    from scipy.optimize import linprog

    m, n_t, n_p = pieces.shape
    out = np.zeros(m)
    nv = m + n_t
    a_ub, b_ub = [], []
    for t in range(n_t):
        for k in range(n_p):
            r = np.zeros(nv)
            r[:m] = pieces[:, t, k]
            r[m + t] = -1.0
            a_ub.append(r), b_ub.append(0.0)
    r = np.zeros(nv)
    r[m:] = 1.0
    a_ub.append(r), b_ub.append(1.0)
    a_ub = np.array(a_ub)
    for j in range(m):
        c = np.zeros(nv)
        c[j] = -1.0
        res = linprog(c, A_ub=a_ub, b_ub=b_ub, bounds=[(None, None)] * nv, method="highs")
        if res.status == 3 or not res.success:
            out[j] = math.inf
            continue
        hi = -res.fun
        c[j] = 1.0
        res = linprog(c, A_ub=a_ub, b_ub=b_ub, bounds=[(None, None)] * nv, method="highs")
        if res.status == 3 or not res.success:
            out[j] = math.inf
            continue
        out[j] = max(hi, -res.fun) * (1 + 1e-9) + 1e-300
    return out


def _edges(pieces: np.ndarray) -> np.ndarray:
    """Edge directions of the images of the play set's pieces (polygons, segments) in the closure rows, (E, m)."""
    m, n_t, n_p = pieces.shape
    pts = pieces.transpose(1, 2, 0)  # (T, N, m): each piece's vertices
    e = (np.roll(pts, -1, axis=1) - pts).reshape(n_t * n_p, m)  # piece by piece, as one concatenation of them
    norm = np.linalg.norm(e, axis=1)
    e = e[norm > 1e-12 * max(float(norm.max(initial=0.0)), 1e-300)]
    e = e / np.linalg.norm(e, axis=1, keepdims=True)
    e = e * np.where(e[:, :1] < 0, -1.0, 1.0)  # one sign per direction
    return np.unique(np.round(e, 12), axis=0)


def _facet_directions(pieces: np.ndarray) -> np.ndarray | None:
    """Every candidate facet normal of the set the plays reach (m <= 3), both signs, (C, m); None for m > 3.

    The set is a Minkowski sum of polygons and segments: a facet is spanned by m - 1 edge directions of
    its summands, so its normal is orthogonal to them (m = 2: each edge turned by 90 degrees; m = 3: the
    cross product of two edges).
    """
    m = pieces.shape[0]
    if m == 1:
        return np.array([[1.0], [-1.0]])
    e = _edges(pieces)
    if m == 2:
        nrm = np.stack([-e[:, 1], e[:, 0]], axis=1)
    elif m == 3:
        i, j = np.triu_indices(len(e), k=1)
        nrm = np.cross(e[i], e[j])
        keep = np.linalg.norm(nrm, axis=1) > 1e-9
        nrm = nrm[keep] / np.linalg.norm(nrm[keep], axis=1, keepdims=True)
    else:
        return None
    return np.concatenate([nrm, -nrm])


def _support(pieces: np.ndarray, u: np.ndarray) -> np.ndarray:
    """``h_Y(F^T u)`` for directions ``u`` (C, m): the sum over pieces of the largest vertex product, (C,)."""
    return np.sum(np.max(np.einsum("mtk,cm->ctk", pieces, u), axis=-1), axis=-1)


class _Block:
    """One configuration: the play pieces, and for m <= 3 the polar's vertex directions (cached)."""

    def __init__(self, model, f: np.ndarray, ua: np.ndarray, dirs: np.ndarray, alone: np.ndarray | None = None) -> None:
        self.model = model
        self.f = f
        self.w = ua @ dirs  # (m, n)
        self.m = f.shape[0]
        self.pieces = _pieces_matrix(model, f) if self.m else np.zeros((0, 0, 0))
        self.rows = None
        self.bound = "exact"
        if self.m > 3 and alone is not None:
            # more than three closure rows: the triangle bound sum_i v_i / t_i (t_i: condition i alone here), an
            # upper bound of the need (safe); the local search gives a lower bound beside it
            with np.errstate(divide="ignore"):
                self.rows = np.where(np.isfinite(alone) & (alone > 0), 1.0 / alone, 0.0)[None, :]
            self.u = np.full((1, self.m), np.nan)
            self.bound = "triangle"
        elif 0 < self.m <= 3:
            u = _facet_directions(self.pieces)
            h = _support(self.pieces, u)
            ok = h > 1e-300
            self.u = u[ok] / h[ok][:, None]  # polar vertices (a superset): h(u) = 1
            self.rows = np.abs(self.u @ self.w)  # (C, n): sum_i v_i rows_ci <= 1 for every c

        self.known: list = []  # polar points found before (m > 3)

    def need(self, v: np.ndarray, exact: bool = True) -> tuple[float, np.ndarray, np.ndarray]:
        """``alpha`` here, the worst signs and the polar point reaching it.  For m > 3 without ``exact``: a lower
        bound by alternating sign patterns and polar linear programmes (a local search)."""
        if self.m == 0 or not np.any(v * np.linalg.norm(self.w, axis=0) > 0):
            return 0.0, np.ones(len(v)), np.zeros(self.m)
        if self.rows is not None and self.bound == "triangle":
            low, s, u = self._local(v)
            self.low = low
            return float((self.rows @ v)[0]), s, u
        if self.rows is not None:
            val = self.rows @ v
            c = int(np.argmax(val))
            u = self.u[c]
            s = np.sign(self.w.T @ u)
            s[s == 0] = 1.0
            return float(val[c]), s, u
        if exact:
            out = _need_at(self.model, self.f, self.w, v)
        else:
            out = self._local(v)
        self.known.append(out[2])
        return out

    def _local(self, v: np.ndarray, starts: int = 4) -> tuple[float, np.ndarray, np.ndarray]:
        """A lower bound: from polar points (a condition's own direction, the points found before), alternate the
        worst signs ``s = sign(W^T u)`` and the point ``u = r / h(r)`` on the polar's boundary along ``r = W (s v)``."""
        scores = v * np.linalg.norm(self.w, axis=0)
        seeds = [self.w[:, i] for i in np.argsort(-scores)[:starts]] + list(self.known[-4:])
        best = (0.0, np.ones(len(v)), np.zeros(self.m))
        for u in seeds:
            h = float(_support(self.pieces, u[None])[0])
            if not h > 0:
                continue
            u = u / h
            for _ in range(20):
                s = np.sign(self.w.T @ u)
                s[s == 0] = 1.0
                r = self.w @ (s * v)
                h = float(_support(self.pieces, r[None])[0])
                if not h > 0:
                    break
                u_new = r / h
                if np.allclose(u_new, u, rtol=1e-12, atol=0):
                    break
                u = u_new
            val = float(np.sum(v * np.abs(self.w.T @ u)))
            if val > best[0]:
                s = np.sign(self.w.T @ u)
                s[s == 0] = 1.0
                best = (val, s, u)
        return best


def _polar_lp(pieces: np.ndarray, r: np.ndarray) -> tuple[float, np.ndarray | None]:
    """``max u . r`` over the polar set ``h(u) <= 1``: the clearance need of the one violation ``r``, and ``u``."""
    from scipy.optimize import linprog

    m, n_t, n_p = pieces.shape
    nv = m + n_t
    a = np.zeros((n_t * n_p + 1, nv))
    for t in range(n_t):
        a[t * n_p:(t + 1) * n_p, :m] = pieces[:, t, :].T
        a[t * n_p:(t + 1) * n_p, m + t] = -1.0
    a[-1, m:] = 1.0
    b = np.zeros(len(a))
    b[-1] = 1.0
    c = np.zeros(nv)
    c[:m] = -r
    res = linprog(c, A_ub=a, b_ub=b, bounds=[(None, None)] * nv, method="highs")
    if not res.success:
        return math.inf, None
    return float(-res.fun), res.x[:m]


def _blocks(model, raw: list, dirs: np.ndarray, alone: np.ndarray | None = None) -> list:
    """One :class:`_Block` per configuration; ``alone`` (K, n): each condition's single value there (m > 3)."""
    return [_Block(model, cg, ua, dirs, None if alone is None else alone[k]) for k, (cg, ua) in enumerate(raw)]


def clearance_need(model, blocks: list, dirs: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                                        list]:
    """``alpha(q)`` at every configuration of ``blocks`` for conditions ``dirs`` (n_aug, n) at ``values`` (n,); with
    the worst signs (K, n) and the dual directions (list of (m,)).  ``blocks``: ``_constraint_blocks`` pairs or
    :class:`_Block` (cached)."""
    if blocks and not isinstance(blocks[0], _Block):
        blocks = _blocks(model, blocks, dirs)
    alpha = np.zeros(len(blocks))
    signs = np.ones((len(blocks), dirs.shape[1]))
    us = []
    for k, b in enumerate(blocks):
        alpha[k], signs[k], u = b.need(values, exact=False)
        us.append(u)
    # where the plays leave more than three closure rows: exact (mixed-integer) at the worst configurations found
    general = [k for k, b in enumerate(blocks) if b.rows is None and b.m > 3]
    for k in sorted(general, key=lambda k: -alpha[k])[:EXACT_TOP]:
        alpha[k], signs[k], us[k] = blocks[k].need(values, exact=True)
    return alpha, signs, us


def allocate_together(cl, mechanism, kin, configurations: np.ndarray, workspace=None, rounds: int = 12) -> dict:
    """Give the assembly conditions of ``cl`` values that hold together (module docstring); in place.

    Each condition keeps its single value in ``evidence["assemblability"]["value_alone"]``.

    Returns
    -------
    dict
        JSON-ready evidence: ``single_condition_need`` (the clearance need of the single values),
        ``clearance_need`` (of the values given, at most 1), ``configurations``, ``worst``
        (configuration and signs), ``factors`` (value / single value per condition).
    """
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.tolerances.clearance import _constraint_blocks, _lift, clearance_model
    from hyperstat.solver.tolerances.workspace import workspace_of
    from hyperstat.solver.tolerances.worst_case import workspace_candidates

    items = [t for t in cl.items if t.cls == "assembly" and t.value is not None and math.isfinite(t.value)
             and t.value > 0]
    if not items:
        return {}
    model = clearance_model(mechanism, cl.declaration)
    kin_aug = Kinematics(model.mechanism)
    ws = workspace or workspace_of(mechanism)
    q = np.atleast_2d(configurations)
    probe = _constraint_blocks(model, q[:1], kin_aug)
    few = not probe or probe[0][0].shape[0] <= 3  # at most three closure rows left: every configuration exactly
    cand = workspace_candidates(kin, ws, q)[0] if few else np.zeros((0, q.shape[1]))
    worst = [np.asarray(t.evidence.get("assemblability", {}).get("worst_configuration"), float) for t in items
             if t.evidence.get("assemblability", {}).get("worst_configuration") is not None]
    qq = np.vstack([q] + ([cand] if len(cand) else []) + ([np.array(worst)] if worst else []))
    qq = np.unique(np.round(qq, 12), axis=0)
    dirs = np.stack([_lift(model, t.direction) for t in items], axis=1)
    at = None
    if not few:  # each condition alone at each configuration: the triangle bound's terms
        from hyperstat.solver.tolerances.clearance import AssemblyConditions

        vals = AssemblyConditions(model, items, kin_aug).values(qq)
        at = np.stack([vals[t.id] for t in items], axis=1)
    alone = np.array([float(t.value) for t in items])
    if not few:
        return _allocate_general(cl, mechanism, items, model, _constraint_blocks(model, qq, kin_aug), dirs, at, alone,
                                 qq, q, worst)
    blocks = _blocks(model, _constraint_blocks(model, qq, kin_aug), dirs)
    need, signs, _ = clearance_need(model, blocks, dirs, alone)
    single = float(np.max(need))
    k_single = int(np.argmax(need))
    factors = np.full(len(items), 1.0 / max(single, 1.0))
    frozen = np.zeros(len(items), dtype=bool)
    if single <= 1.0:
        frozen[:] = True
    cuts: list = []  # (coefficients per unit of each value: |u . W_i|), each sum <= 1
    exact = all(b.rows is not None for b in blocks)
    if exact:  # every polar vertex of every configuration: the cuts are complete (those that can bind)
        rows = np.vstack([b.rows for b in blocks if b.rows is not None and len(b.rows)]) * alone[None, :]
        rows = rows[rows.sum(axis=1) * factors[0] > 1e-3]
        cuts = list(np.unique(np.round(rows, 12), axis=0))
    for _ in range(rounds if exact else min(rounds, 4)):
        if frozen.all():
            break
        v = factors * alone
        if not exact:
            need, signs, us = clearance_need(model, blocks, dirs, v)
            for k in np.argsort(-need)[:6]:
                cuts.append(np.abs(blocks[k].w.T @ us[k]) * alone)
        # the largest common growth of the unfrozen factors within every cut
        lam = math.inf
        for c in cuts:
            fixed = float(np.sum(c[frozen] * factors[frozen]))
            grow = float(np.sum(c[~frozen]))
            if grow > 0:
                lam = min(lam, (1.0 - fixed) / grow)
        lam = min(lam, 1.0)
        trial = factors.copy()
        trial[~frozen] = np.maximum(lam, factors[~frozen])
        t_need, _, _ = clearance_need(model, blocks, dirs, trial * alone)
        if np.max(t_need) > 1.0 + 1e-7:
            continue  # new cuts next round
        factors = trial
        if lam >= 1.0:
            break
        binding = [c for c in cuts if float(np.sum(c * factors)) >= 1.0 - 1e-7]
        newly = np.zeros(len(items), dtype=bool)
        for c in binding:
            newly |= (c > 1e-12 * np.max(c)) & ~frozen
        if not newly.any():
            break
        frozen |= newly
    final, signs, _ = clearance_need(model, blocks, dirs, factors * alone)
    worst_need = float(np.max(final))
    if worst_need > 1.0:  # a cut missed: scale back onto the safe side
        factors = factors / worst_need
        final = final / worst_need
        worst_need = 1.0
    k = int(np.argmax(final))
    for t, f, a in zip(items, factors, alone):
        t.evidence.setdefault("assemblability", {})["value_alone"] = a
        t.evidence["assemblability"]["together_factor"] = float(f)
        t.value = float(f * a)
        t.value_source += (f"; together with the other assembly conditions (every one at a corner of its tolerance at "
                           f"once): {100 * f:.1f} % of its single value {a:.4g} {t.unit}")
    method = ("exact at every configuration: every vertex of the polar of the set the plays reach (at most three "
              "closure rows left to the plays)" if few else
              "an upper bound at every configuration: more than three closure rows are left to the plays, where the "
              "exact need is a mixed-integer programme too slow to run (minutes per configuration); the values are "
              "allocated on the triangle bound sum_i v_i / t_i (t_i: the condition alone there), which is safe, and a "
              "local search gives a lower bound beside it (need_lower_bound)")
    low = max((getattr(b, "low", 0.0) for b in blocks), default=0.0) if not few else None
    return {"single_condition_need": single, "clearance_need": worst_need, "method": method, "exact": few,
            "need_lower_bound": low,
            "configurations": int(len(qq)), "from": {"given": int(len(q)), "workspace_candidates": int(len(cand)),
                                                      "single_worst_cases": len(worst)},
            "worst": {"configuration": qq[k].tolist(), "signs": {t.id: float(s) for t, s in zip(items, signs[k])},
                      "actuated": {mechanism.joints[i].name: float(qq[k][i]) for i in mechanism.actuated}},
            "single_worst": {"configuration": qq[k_single].tolist()},
            "factors": {t.id: float(f) for t, f in zip(items, factors)},
            "values": {t.id: float(t.value) for t in items}, "values_alone": {t.id: float(a) for t, a in
                                                                               zip(items, alone)}}


def _decision_rule(model, f: np.ndarray, w: np.ndarray, v: np.ndarray) -> float:
    """An upper bound of the clearance need at one configuration: each condition's violation ``v_i W_i`` absorbed by
    plays ``y_i`` of its own (``F y_i = -v_i W_i``), every support's polygon row holding the sum of their absolute
    values (``sum_i |P y_i| <= alpha c``, ``sum_i |y_i| <= alpha``): then every sign pattern ``sum_i s_i y_i`` lies in
    ``alpha Y``.  A linear programme; exact for one condition."""
    from scipy.optimize import linprog
    from scipy.sparse import csr_matrix, hstack, identity, kron, vstack

    m, n_g = f.shape
    n = w.shape[1]
    p = model.polygon
    n_r = p.shape[0]
    boxed = np.nonzero(~np.any(p != 0, axis=0))[0] if n_r else np.arange(n_g)  # plays no polygon bounds (segments)
    n_b = len(boxed)
    ny, nzp, nzy = n * n_g, n * n_r, n * n_b
    sel = csr_matrix((np.ones(n_b), (np.arange(n_b), boxed)), shape=(n_b, n_g))
    a_eq = hstack([kron(identity(n), csr_matrix(f)), csr_matrix((n * m, nzp + nzy + 1))])
    b_eq = -(w * v).T.reshape(-1)
    py = kron(identity(n), csr_matrix(p)) if n_r else csr_matrix((0, ny))
    sy = kron(identity(n), sel)
    blocks = [hstack([py, -identity(nzp), csr_matrix((nzp, nzy + 1))]),
              hstack([-py, -identity(nzp), csr_matrix((nzp, nzy + 1))]),
              hstack([sy, csr_matrix((nzy, nzp)), -identity(nzy), csr_matrix((nzy, 1))]),
              hstack([-sy, csr_matrix((nzy, nzp)), -identity(nzy), csr_matrix((nzy, 1))]),
              hstack([csr_matrix((n_r, ny)), kron(csr_matrix(np.ones((1, n))), identity(n_r)), csr_matrix((n_r, nzy)),
                      csr_matrix(-model.limit * np.ones((n_r, 1)))]),
              hstack([csr_matrix((n_b, ny + nzp)), kron(csr_matrix(np.ones((1, n))), identity(n_b)),
                      csr_matrix(-np.ones((n_b, 1)))])]
    a_ub = vstack(blocks).tocsr()
    c = np.zeros(ny + nzp + nzy + 1)
    c[-1] = 1.0
    # a play of a polygon-bounded group is within [-1, 1] by its polygon; the others by the box rows above
    res = linprog(c, A_ub=a_ub, b_ub=np.zeros(a_ub.shape[0]), A_eq=a_eq, b_eq=b_eq,
                  bounds=[(None, None)] * ny + [(0, None)] * (nzp + nzy + 1), method="highs-ipm")
    return float(res.fun) if res.success else math.inf


def _allocate_general(cl, mechanism, items, model, raw, dirs, at, alone, qq, q, worst) -> dict:
    """More than three closure rows left to the plays: every value scaled by one factor, on a safe upper bound of
    the need (:func:`_decision_rule`), evaluated in decreasing order of the triangle bound ``sum_i v_i / t_i``
    (t_i: condition i alone there) until no configuration left can exceed the worst found (the triangle bound is an
    upper bound of the decision rule's)."""
    with np.errstate(divide="ignore"):
        inv = np.where(np.isfinite(at) & (at > 0), 1.0 / at, 0.0)
    tri = inv @ alone
    n_vars = len(items) * (raw[0][0].shape[1] + 2 * model.polygon.shape[0]) if raw else 0
    if n_vars > DECISION_RULE_VARIABLES:
        return _allocate_triangle(cl, mechanism, items, model, raw, dirs, alone, tri, qq, q, worst, n_vars)
    lows = np.array([_Block(model, f, ua, dirs)._local(alone, starts=2)[0] for f, ua in raw])
    own = [int(np.argmin(np.linalg.norm(qq - w_q[None, :], axis=1))) for w_q in worst]  # each condition's worst
    picks = list(dict.fromkeys([int(k) for k in np.argsort(-lows)[:GENERAL_SOLVED]] +
                               [int(k) for k in np.argsort(-tri)[:GENERAL_SOLVED]] + own))
    from hyperstat.solver.forked import beside

    def rules(ks: list) -> list:
        return [_decision_rule(model, raw[k][0], raw[k][1] @ dirs, alone) for k in ks]
    # each programme is its own (0.2-0.3 s each on the planar 3-RRR): half of them by a child when a core is idle
    half = (len(picks) + 1) // 2
    head, tail = beside(lambda: rules(picks[:half]), lambda: rules(picks[half:])) if len(picks) > 1 else \
        (rules(picks), [])
    best, k_best, evaluated = 0.0, picks[0], 0
    for k, val in zip(picks, list(head) + list(tail)):
        evaluated += 1
        if val > best:
            best, k_best = val, int(k)
    unsolved_low = max((float(lows[k]) for k in range(len(raw)) if k not in picks), default=0.0)
    factor = 1.0 / max(best, 1.0)
    block = _Block(model, raw[k_best][0], raw[k_best][1], dirs)
    low, signs, _ = block._local(alone * factor)
    _scale_values(items, alone, factor)
    method = ("an upper bound where it matters most: more than three closure rows are left to the plays, where the "
              "exact need is a mixed-integer programme of minutes per configuration; each condition's violation is "
              "absorbed by plays of its own whose absolute values add up within the clearances (a linear programme, "
              f"safe), at the {evaluated} configurations (of {len(qq)}) where a local search's lower bound or the triangle "
              "bound sum_i v_i / t_i (t_i: condition i alone there) is largest and at every condition's own worst "
              "configuration; at the others only a lower bound is computed, and it stays at "
              f"{unsolved_low / max(best, 1e-300):.2f} of the worst upper bound; every value scaled by one factor")
    return _bound_evidence(mechanism, items, alone, factor, best, method, low, qq, q, worst, k_best, signs,
                           solved=evaluated, unsolved_lower_bound=unsolved_low * factor)


def _allocate_triangle(cl, mechanism, items, model, raw, dirs, alone, tri, qq, q, worst, n_vars: int) -> dict:
    """Many conditions and many plays (the revolute Delta's 47 conditions): the decision rule's programme would take
    minutes per configuration, so every value is scaled on the triangle bound ``sum_i v_i / t_i`` alone, at every
    configuration (each condition absorbed by plays of its own, each at its own share of the clearances: safe, and
    never below the decision rule's bound); a local search at the worst configuration gives a lower bound beside it."""
    k_best = int(np.argmax(tri))
    best = float(tri[k_best])
    factor = 1.0 / max(best, 1.0)
    block = _Block(model, raw[k_best][0], raw[k_best][1], dirs)
    low, signs, _ = block._local(alone * factor, starts=2)
    _scale_values(items, alone, factor)
    method = (f"the triangle bound at every configuration: {len(items)} conditions and more than three closure rows "
              f"left to the plays make the decision rule's linear programme too large (size {n_vars}: conditions "
              "times plays and polygon rows, minutes per configuration); each condition is absorbed by plays of its "
              "own at its own share of the clearances, sum_i v_i / t_i (t_i: condition i alone there), which is safe "
              f"and at least the decision rule's bound; at {len(qq)} configurations; every value scaled by one factor")
    return _bound_evidence(mechanism, items, alone, factor, best, method, low, qq, q, worst, k_best, signs,
                           solved=0, unsolved_lower_bound=None)


def _scale_values(items: list, alone: np.ndarray, factor: float) -> None:
    """Every assembly value scaled by one factor from its single value, and the evidence saying so (in place)."""
    for t, a in zip(items, alone):
        t.evidence.setdefault("assemblability", {})["value_alone"] = float(a)
        t.evidence["assemblability"]["together_factor"] = factor
        t.value = float(factor * a)
        t.value_source += (f"; together with the other assembly conditions (every one at a corner of its tolerance at "
                           f"once): {100 * factor:.1f} % of its single value {a:.4g} {t.unit}")


def _bound_evidence(mechanism, items, alone, factor, best, method, low, qq, q, worst, k_best, signs, solved,
                    unsolved_lower_bound) -> dict:
    """The whole drawing's evidence when the need is an upper bound (more than three closure rows), JSON-ready."""
    return {"single_condition_need": best, "clearance_need": best * factor, "method": method, "exact": False,
            "need_lower_bound": low, "configurations": int(len(qq)), "solved": solved,
            "unsolved_lower_bound": unsolved_lower_bound,
            "from": {"given": int(len(q)), "workspace_candidates": 0, "single_worst_cases": len(worst)},
            "worst": {"configuration": qq[k_best].tolist(), "signs": {t.id: float(s) for t, s in zip(items, signs)},
                      "actuated": {mechanism.joints[i].name: float(qq[k_best][i]) for i in mechanism.actuated}},
            "single_worst": {"configuration": qq[k_best].tolist()},
            "factors": {t.id: factor for t in items}, "values": {t.id: float(t.value) for t in items},
            "values_alone": {t.id: float(a) for t, a in zip(items, alone)}}


def confirm_corner(cl, mechanism, evidence: dict, others: bool = True, seed: int = 0) -> dict:
    """Re-assemble the worst corner through the nonlinear model, the plays as bounded joints.

    The corner: every assembly condition at its value with the worst signs at the worst configuration, plus
    (``others``) every accuracy-critical and compensable tolerance at its drawing value with random signs.
    Returns the largest factor on that corner for which the loops still close within the clearances
    (:func:`hyperstat.solver.tolerances.clearance.confirm_nonlinear`): at least 1 when the drawing assembles.
    """
    from hyperstat.solver.tolerances.clearance import confirm_nonlinear

    if not evidence:
        return {}
    q = np.asarray(evidence["worst"]["configuration"], float)
    xi = np.zeros(len(mechanism.parameters))
    for t in cl.items:
        if t.id in evidence["worst"]["signs"]:
            xi += evidence["worst"]["signs"][t.id] * float(t.drawing_value or t.value) * t.direction
    rng = np.random.default_rng(seed)
    if others:
        for t in cl.items:
            if t.cls in ("compensable", "accuracy-critical") and t.drawing_value:
                xi += rng.choice([-1.0, 1.0]) * float(t.drawing_value) * t.direction
    out = confirm_nonlinear(mechanism, xi, 1.0, q, cl.declaration)
    return {"scale_factor": float(out["value"]), "closure_residual_mm": out["closure_residual_mm"],
            "below": out["below"], "largest_clearance_use": out["largest_clearance_use"],
            "with_the_other_tolerances": bool(others)}


def whole_drawing_summary(evidence: dict, cl) -> dict:
    """The ``whole_drawing`` object of ``report.json`` (``docs/drawing-format.md``): what the drawing meets as a whole."""
    if not evidence:
        return {"statement": "no assembly condition: nothing to assemble within the clearances"}
    alloc = getattr(cl, "allocation", {}) or {}
    spec = alloc.get("spec") or {}
    acc = {}
    for key in ("calibrated", "uncalibrated"):
        b = (alloc.get(key) or {}).get("bounds")
        if b:
            acc[key] = {"attainable_linear_worst_case": b.get("attainable_linear_worst_case"), "unit": b.get("unit"),
                        "spec": b.get("spec")}
    cal = getattr(cl, "calibration", {}) or {}
    need = evidence["clearance_need"]
    nl = evidence.get("nonlinear") or {}
    n = len(evidence.get("values", {}))
    words = (f"with every frame of every part at a corner of its zone at once (the {n} assembly conditions at their "
             f"values with the worst signs), the mechanism assembles within the declared joint clearances at each of "
             f"{evidence['configurations']} configurations of the workspace (the starting configurations, the corners, "
             f"edges, faces and dead centres of the actuated box, and every condition's own worst configuration): it "
             f"needs {need:.3g} of the clearances at the worst (the single values together needed "
             f"{evidence['single_condition_need']:.3g} times them)")
    if nl:
        words += (f"; re-assembled through the nonlinear model at the worst configuration, the worst corner (with every "
                  f"compensable and accuracy-critical tolerance at its drawing value too) still closes scaled by "
                  f"{nl['scale_factor']:.4g}")
    b = acc.get("calibrated") or acc.get("uncalibrated")
    if b and b.get("attainable_linear_worst_case") is not None:
        words += (f"; accuracy: the attainable first-order error of the "
                  f"{'calibrated ' if 'calibrated' in acc else ''}machine with every accuracy tolerance at its value is "
                  f"{b['attainable_linear_worst_case']:.4g} {b['unit']} against the {b['spec']} {b['unit']} spec"
                  + (f" (plus the calibration's 3-sigma noise, {cal.get('position_mm', 0.0):.3g} mm)"
                     if 'calibrated' in acc and b['unit'] == 'mm' else ""))
    return {"clearance_need": need, "scale_factor": 1.0 / need if need > 0 else None,
            "single_condition_need": evidence["single_condition_need"],
            "configurations": {"total": evidence["configurations"], **evidence.get("from", {})},
            "method": evidence.get("method"), "exact": evidence.get("exact"),
            "need_lower_bound": evidence.get("need_lower_bound"),
            "unsolved_lower_bound": evidence.get("unsolved_lower_bound"),
            "worst": evidence.get("worst"), "factors": evidence.get("factors"), "values": evidence.get("values"),
            "values_alone": evidence.get("values_alone"),
            "nonlinear": nl or None, "accuracy": acc, "spec": spec, "statement": words}
