"""Assembly tolerances from joint clearances: worst-case assemblability over the workspace, searched.

Units: clearances and violations in mm and rad.

An assembly condition (a forced defect or a relation, :mod:`hyperstat.solver.tolerances.classification`)
must hold for the loops to close without deforming the parts; real joints have play,
and the play lets the loops close with a small violation.  Following the tolerance
analysis of over-constrained mechanisms with gaps, where assemblability is the
quantified statement "for every configuration there exist gap displacements, each
within its clearance, that close the loops" (Dantan & Qureshi, *Worst-case and
statistical tolerance analysis based on quantified constraint satisfaction problems
and Monte Carlo simulation*, Computer-Aided Design 41(1), 2009, 1-12; Ballu, Plantec
& Mathieu, *Geometrical reliability of overconstrained mechanisms with gaps*, CIRP
Annals 57(1), 2008, 159-162), the tolerance of a condition is the largest violation
``t`` that is absorbed at every configuration of the workspace.

**The play of a joint** (:func:`clearance_model`, the declaration of
:mod:`hyperstat.solver.tolerances.declaration`).  A joint is held by two supports ``span``
apart along its axis, centred ``centre`` along the axis from the joint's frame on its
``side``: a revolute's two bearings (or a pin's engagement length), a prismatic joint's
carriage between its two pads.  The play is a small rigid displacement of the moving part
about that centre, a shift ``(v1, v2, v3)`` and a rotation ``(w1, w2, w3)`` in the support's
axes ``(u1, u2, n)``, such that

* each support moves radially by at most ``radial`` in every direction: at ``z = +-span/2``
  along the axis the radial displacement ``(v1 + z w2, v2 - z w1)`` lies in a disc of radius
  ``radial`` (so the tilt is at most ``2 radial / span``, and only when the shift is zero);
  the disc is replaced by the inscribed regular polygon of :data:`POLYGON_SIDES` sides, on the
  safe side (at most ``1 - cos(pi / 8)`` = 7.6 % less play in the worst direction);
* the axial play ``|v3| <= axial``, and a prismatic joint's twist ``|w3| <= twist``.

A carriage on the *moving* side (a slider on a rail) tilts about itself wherever it is; a
guide on the *fixed* side (a leg sliding through its base joint) about the guide.  The
displacement enters the model as defects of the joint's own frame (fixed side) or of a
frame added right after the joint (moving side).

**At one configuration**, with ``U0`` a basis of the left null space of the passive
joints' closure Jacobian (their motion is free), the largest violation ``t(q)`` is the
linear programme ``max t`` subject to ``U0^T A (d t + C y) = 0``, ``y`` within the play
(``A``: closure motion per defect, paper 1 eq. 3; ``d``: one unit of violation; ``C``: the
play columns), solved by HiGHS through :func:`scipy.optimize.linprog`; many configurations
and conditions are one block-diagonal programme with one ``t`` per block.  For the value alone the
programme is written on the play set as a zonotope (:meth:`ClearanceModel.generators`): a support's
regular octagon is the sum of four segments, so ``y = G lam`` with ``lam`` in ``[-1, 1]`` maps the box
onto the play set exactly, and the programme has only the closure's equality rows and bounded
variables; ``t`` is scaled by its bound from duality (``u = e / |e|^2``), so that HiGHS' absolute
tolerance is a relative one on ``t``.  How close that is, measured on the revolute Delta (12 closure rows left to
168 segments): at the analysis' first four configurations (188 programmes) ``t`` is at most 3e-15 below the optimum
of an interior-point solve and up to 6.7e-8 above a bound of weak duality (16 of them more than 1e-9 above), and on 959
programmes recorded from its report's search at most 6.3e-8 above it (2.8 % more than 1e-8).  These are the dual
simplex' answers within its tolerances (1e-10 on the orthonormal rows), not exact vertices; a bound from HiGHS' own
row duals cuts the largest excess to 1.5e-8 only.  A single value can therefore be that much high (about 1e-9 rad
on the Delta's first condition, 0.0166 rad; the search's stated tolerance there, 1e-11 rad, does not cover it); the
values drawn are the single values scaled for all conditions together (2.2 % of them on the Delta), far below.
``tests/solver/tolerances/test_clearance.py`` holds the excess within 1e-7.  The polygon form with ``t`` unscaled
agrees to 1e-6.

**Over the workspace** the value is ``min_q t(q)``, found by the one worst-case engine
(:func:`hyperstat.solver.tolerances.worst_case.search_extremes`): the given configurations,
the corners, edges, faces and dead centres of the actuated box, then a local search on the
configuration manifold; the value stated is that minimum less the search's stated
tolerance.  Each condition is taken alone (the others held).

:func:`confirm_nonlinear` checks a value with the full nonlinear model: the plays become
bounded extra variables of each joint (small prismatic and revolute joints), and the loops
are re-assembled just below the tolerance and the largest violation found by sequential
linear programming.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import NamedTuple

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Defect, FixedTransform, Joint, Mechanism, Placement
from hyperstat.solver.tolerances.declaration import Declaration
from hyperstat.solver.tolerances.worst_case import Objective

__all__ = ["ClearanceModel", "clearance_model", "AssemblyConditions", "assembly_tolerances", "confirm_nonlinear",
           "POLYGON_SIDES"]

#: sides of the regular polygon inscribed in a support's disc of radial play (safe side)
POLYGON_SIDES = 8
#: a violation the clearances absorb beyond this (mm or rad) is "not limited to first order"
_UNBOUNDED = 1e3


@dataclasses.dataclass
class ClearanceModel:
    """The mechanism with the plays of every joint as extra defects, and the set of admissible plays.

    Attributes
    ----------
    mechanism : Mechanism
        The original defects keep their names; a joint whose play sits on its fixed side carries
        ``I J K a b c`` (and ``G`` when prismatic), the added components named ``g<component><joint>``;
        a joint whose play sits on its moving side is followed by a fixed frame ``play<joint>`` with
        defects ``gI, gJ, ga, gb, gc, gG`` + joint.
    columns : ndarray, (n_xi_aug, n_g)
        Defect vector (rad / mm) of one unit of each play variable ``y`` (a unit is the variable's
        largest value alone: the radial play, the tilt ``2 radial / span``, the axial play, the twist).
    polygon : ndarray, (n_c, n_g)
        Rows ``P`` of the supports' polygons: the plays are admissible when ``|P y| <= limit`` and
        ``|y| <= 1``.
    limit : float
        ``cos(pi / POLYGON_SIDES)``.
    labels : list of str
        ``"joint 21 shift u1"``, ``"joint 21 tilt about u2"`` ...
    joint_of : list of str
        The joint of each play variable.
    groups : list of tuple
        ``(kind, columns)`` of the separable pieces of the play set: ``"pads"`` (``v1, v2, w1, w2``:
        two supports, each in the polygon), ``"pad"`` (``v1, v2``: one support), ``"disc"``
        (``w1, w2``: a tilt alone), ``"segment"`` (one variable in ``[-1, 1]``).
    index_of : dict
        Original parameter name -> index in the augmented mechanism.
    sources : dict
        Joint -> its resolved clearance (with the source).
    """

    mechanism: Mechanism
    columns: np.ndarray
    polygon: np.ndarray
    limit: float
    labels: list
    joint_of: list
    groups: list
    index_of: dict
    sources: dict

    @functools.cached_property
    def generators(self) -> np.ndarray:
        """``G`` (n_g, n_lam): the play set is ``{G lam : |lam| <= 1}`` (a zonotope).

        A regular polygon of :data:`POLYGON_SIDES` sides inscribed in the unit disc is the sum of
        ``POLYGON_SIDES / 2`` segments ``[-g, g]``, ``g = sin(pi / POLYGON_SIDES) (cos phi, sin phi)`` along its
        edges (``phi = k pi / (POLYGON_SIDES / 2)``): a support's position ``(v1 + s w2, v2 - s w1)``
        (``"pads"``, ``s = -1, +1``), ``(v1, v2)`` (``"pad"``) or ``(w1, w2)`` (``"disc"``) is such a sum, and
        a segment is its own variable.  The box ``|y| <= 1`` adds nothing to the polygons (their points have
        coordinates of at most ``cos(pi / POLYGON_SIDES)``), so the image of the box is the play set.

        Examples
        --------
        >>> import numpy as np
        >>> m = ClearanceModel(None, np.zeros((0, 2)), np.zeros((0, 2)), 1.0, [], [], [("pad", [0, 1])], {}, {})
        >>> g = m.generators                          # one support: four segments of an octagon
        >>> g.shape
        (2, 4)
        >>> bool(np.isclose(np.linalg.norm(g @ np.ones(4)), 1.0))   # all at +1: a vertex, on the unit circle
        True
        """
        n_g = self.columns.shape[1]
        half = POLYGON_SIDES // 2
        phi = np.pi * np.arange(half) / half
        seg = math.sin(math.pi / POLYGON_SIDES) * np.stack([np.cos(phi), np.sin(phi)])  # (2, half)
        cols = []
        for kind, idx in self.groups:
            if kind == "pads":  # y = (v1, v2, w1, w2) from the supports p_s = (v1 + s w2, v2 - s w1), s = -1, 1
                for s in (-1.0, 1.0):
                    for k in range(half):
                        col = np.zeros(n_g)
                        col[idx[0]], col[idx[1]] = seg[0, k] / 2, seg[1, k] / 2
                        col[idx[3]], col[idx[2]] = s * seg[0, k] / 2, -s * seg[1, k] / 2
                        cols.append(col)
            elif kind in ("pad", "disc"):
                for k in range(half):
                    col = np.zeros(n_g)
                    col[idx[0]], col[idx[1]] = seg[0, k], seg[1, k]
                    cols.append(col)
            else:
                col = np.zeros(n_g)
                col[idx[0]] = 1.0
                cols.append(col)
        return np.array(cols).T if cols else np.zeros((n_g, 0))

    def use(self, y: np.ndarray) -> dict:
        """Joint -> largest share of its play used by the plays ``y`` (1 = at the clearance)."""
        out: dict = {}
        rows = np.abs(self.polygon @ y) / self.limit if len(self.polygon) else np.zeros(0)
        for j, joint in enumerate(self.joint_of):
            out[joint] = max(out.get(joint, 0.0), float(abs(y[j])))
        for r, row in enumerate(self.polygon):
            joint = self.joint_of[int(np.nonzero(row)[0][0])]
            out[joint] = max(out[joint], float(rows[r]))
        return out


def clearance_model(mechanism: Mechanism, declaration: Declaration) -> ClearanceModel:
    """Add the plays of every joint to the mechanism (see the module docstring)."""
    chains, where = [], {}  # where: joint -> (element carrying the play, its axes in that element's parent frame)
    for ch in mechanism.chains:
        els = []
        for el in ch.elements:
            if not isinstance(el, Joint):
                els.append(el)
                continue
            c = declaration.clearance(el.name, el.type)
            if c["side"] == "moving":
                els.append(el)
                comps = "IJabc" + ("G" if el.type == "P" else "")
                play = FixedTransform(f"play{el.name}", Placement((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0)),
                                      tuple(Defect(k, f"g{k}{el.name}") for k in comps))
                els.append(play)
                where[el.name] = (play, np.eye(3)[:, 2], np.eye(3)[:, 0])
            else:
                have = {d.component: d for d in el.defects}
                comps = "IJKabc" + ("G" if el.type == "P" else "")
                defects = tuple(have.get(k, Defect(k, f"g{k}{el.name}")) for k in comps)
                defects += tuple(d for k, d in have.items() if k not in comps)
                new = dataclasses.replace(el, defects=defects)
                els.append(new)
                where[el.name] = (new, np.asarray(el.placement.z_axis, float), np.asarray(el.placement.x_axis, float))
        chains.append(dataclasses.replace(ch, elements=tuple(els)))
    aug = dataclasses.replace(mechanism, chains=tuple(chains))
    index = aug.parameter_index
    n = len(aug.parameters)
    cols, labels, joints, poly_rows, sources, groups = [], [], [], [], {}, []
    sides = POLYGON_SIDES
    angles = 2 * np.pi * np.arange(sides // 2) / sides
    for joint in mechanism.joints:
        c = declaration.clearance(joint.name, joint.type)
        sources[joint.name] = c
        el, n0, u1 = where[joint.name]
        u2 = np.cross(n0, u1)
        names = {d.component: d.name for d in el.defects}
        e = c["centre_mm"]
        radial = c["radial_mm"]
        tilt = c["tilt_rad"] if math.isfinite(c["tilt_rad"]) and (radial == 0 or math.isfinite(c["span_mm"])) else 0.0
        first = len(cols)

        def column(dn: np.ndarray, dp: np.ndarray, g: float = 0.0) -> np.ndarray:
            col = np.zeros(n)
            for k, letter in enumerate("IJK"):
                if abs(dn[k]) > 0:
                    col[index[names[letter]]] = dn[k]
            for k, letter in enumerate("abc"):
                if abs(dp[k]) > 0:
                    col[index[names[letter]]] = dp[k]
            if g:
                col[index[names["G"]]] = g
            return col

        def add(col: np.ndarray, size: float, label: str) -> None:
            cols.append(col * size)
            labels.append(f"joint {joint.name} {label}")
            joints.append(joint.name)

        slot = {}
        if radial > 0:
            slot["v1"] = len(cols)
            add(column(np.zeros(3), u1), radial, "support shift along u1")
            slot["v2"] = len(cols)
            add(column(np.zeros(3), u2), radial, "support shift along u2")
        if tilt > 0:
            # a rotation w about u1 (or u2) through the centre c = o + e n0: the axis turns by w x n0, the
            # frame's origin moves by w x (o - c) = -e (w x n0)
            slot["w1"] = len(cols)
            add(column(-u2, e * u2), tilt, "tilt about u1")
            slot["w2"] = len(cols)
            add(column(u1, -e * u1), tilt, "tilt about u2")
        if c["axial_mm"] > 0:
            groups.append(("segment", [len(cols)]))
            add(column(np.zeros(3), n0), c["axial_mm"], "axial shift")
        if joint.type == "P" and c["twist_rad"] > 0:
            groups.append(("segment", [len(cols)]))
            add(column(np.zeros(3), np.zeros(3), 1.0), c["twist_rad"], "twist about its axis")
        if radial > 0 and tilt > 0:
            groups.append(("pads", [slot["v1"], slot["v2"], slot["w1"], slot["w2"]]))
        elif radial > 0:
            groups.append(("pad", [slot["v1"], slot["v2"]]))
        elif tilt > 0:
            groups.append(("disc", [slot["w1"], slot["w2"]]))
        if radial > 0:  # the supports' radial plays: (v1 + s w2, v2 - s w1) in the polygon, s = +-1 (units above)
            pads = (-1.0, 1.0) if tilt > 0 else (0.0,)
            for s in pads:
                for phi in angles:
                    row = np.zeros(len(cols) - first)
                    row[slot["v1"] - first] += math.cos(phi)
                    row[slot["v2"] - first] += math.sin(phi)
                    if s:
                        row[slot["w2"] - first] += s * math.cos(phi)
                        row[slot["w1"] - first] -= s * math.sin(phi)
                    poly_rows.append((first, row))
        elif tilt > 0:  # no radial play given but a tilt: the tilt alone in its disc
            for phi in angles:
                row = np.zeros(len(cols) - first)
                row[slot["w1"] - first], row[slot["w2"] - first] = math.cos(phi), math.sin(phi)
                poly_rows.append((first, row))
    n_g = len(cols)
    polygon = np.zeros((len(poly_rows), n_g))
    for r, (first, row) in enumerate(poly_rows):
        polygon[r, first:first + len(row)] = row
    index_of = {p.name: index[p.name] for p in mechanism.parameters}
    columns = np.array(cols).T if cols else np.zeros((n, 0))
    return ClearanceModel(aug, columns, polygon, math.cos(math.pi / sides), labels, joints, groups, index_of, sources)


def _lift(model: ClearanceModel, direction: np.ndarray) -> np.ndarray:
    out = np.zeros(len(model.mechanism.parameters))
    out[list(model.index_of.values())] = direction  # index_of follows the original parameter order
    return out


def _constraint_blocks(model: ClearanceModel, q: np.ndarray, kin: Kinematics | None = None):
    """Per configuration: ``U0^T A C`` and ``U0^T A`` (scaled rows: rotations times the length scale)."""
    kin = kin or Kinematics(model.mechanism)
    st = kin.evaluate(q, None, jacobians=True)
    a = kin.scaled_rows(st.closure_xi)  # (K, m, n_aug)
    bp = kin.scaled_rows(st.closure_q)[:, :, model.mechanism.passive]
    out = []
    if bp.shape[2] and len(q):  # one batched call: LAPACK factors each matrix alone, as one call per matrix would
        us, ss = np.linalg.svd(bp, full_matrices=True)[:2]
    for k in range(len(q)):
        if bp.shape[2]:
            u, s = us[k], ss[k]
            r = int(np.sum(s > 1e-9 * s[0])) if s.size and s[0] > 0 else 0
        else:
            u, r = np.eye(a.shape[1]), 0
        u0 = u[:, r:]
        ua = u0.T @ a[k]
        out.append((ua @ model.columns, ua))
    return out


#: blocks per block-diagonal programme of :func:`_solve`: HiGHS' dual simplex takes superlinear time in the number
#: of blocks (per block on the revolute Delta, the polygon form: 4.1 ms in programmes of 8 blocks, 4.9 ms of 32,
#: 8.9 ms of 128, 15.9 ms of 256); each block's maximum is its own, so the grouping changes the time, not the programme
LP_GROUP = 8
#: groups of :data:`LP_GROUP` blocks from which :func:`_solve` gives half of them to a child when a core is idle
#: (:func:`hyperstat.solver.forked.beside`): 8 groups take about 0.25-0.4 s, a fork about 5-10 ms
PARALLEL_GROUPS = 8


def _solve(model: ClearanceModel, pairs: list, plays: bool = False) -> tuple[np.ndarray, list]:
    """Largest violation ``t`` of each ``(U0^T A C, U0^T A d)`` pair: block-diagonal linear programmes.

    Each block has its own plays and its own ``t`` (the objective is their sum, so each is its own
    block's maximum); ``t`` is capped at :data:`_UNBOUNDED` (reported as infinite: the plays absorb any
    small violation to first order).  Returns ``t`` (K,) and the plays ``y`` of each block (None where
    unsolved).  The blocks are solved :data:`LP_GROUP` at a time, on the zonotope form of the play set
    (:func:`_solve_zonotope`); with ``plays`` on its polygon form (:func:`_solve_polygon`), whose vertex
    names the joints whose play is used up (the value is the same).
    """
    if len(pairs) > LP_GROUP:
        starts = list(range(0, len(pairs), LP_GROUP))

        def groups(part: list) -> tuple:
            ts, ys = [], []
            for start in part:
                t, y = _solve_group(model, pairs[start:start + LP_GROUP], plays)
                ts.append(t)
                ys += y
            return np.concatenate(ts), ys
        if len(starts) < PARALLEL_GROUPS:
            return groups(starts)
        # many groups: the second half by a forked child when a core is idle (the same groups, so the same
        # programmes and bits; issue 39: the planar 3-RRR's searches and whole drawing solve thousands of blocks)
        from hyperstat.solver.forked import beside

        half = (len(starts) + 1) // 2
        (t1, y1), (t2, y2) = beside(lambda: groups(starts[:half]), lambda: groups(starts[half:]))
        return np.concatenate([t1, t2]), list(y1) + list(y2)
    return _solve_group(model, pairs, plays)


def _solve_group(model: ClearanceModel, pairs: list, plays: bool = False) -> tuple[np.ndarray, list]:
    """:func:`_solve` of a few blocks: one block-diagonal linear programme."""
    return _solve_polygon(model, pairs) if plays else _solve_zonotope(model, pairs)


def _felt(cg: np.ndarray, av: np.ndarray) -> float | None:
    """The scale of a block (largest entry), or None when the violation is not felt at its configuration."""
    scale = max(float(np.max(np.abs(cg))) if cg.size else 0.0, float(np.max(np.abs(av))) if av.size else 0.0,
                1e-300)
    return None if av.size == 0 or float(np.linalg.norm(av)) <= 1e-12 * scale else scale


def _solve_zonotope(model: ClearanceModel, pairs: list) -> tuple[np.ndarray, list]:
    """:func:`_solve_group` on the play set as a zonotope: ``max t`` s.t. ``E G lam + e t = 0``, ``|lam| <= 1``.

    ``G`` is :attr:`ClearanceModel.generators` (``E G`` has as many rows as the closure leaves, about 12 on the
    revolute Delta, against 12 + 336 rows of the polygon form).  ``t = b tau`` with ``b = h(E^T u)`` at
    ``u = e / |e|^2`` (``h`` the support function of the play set, a sum of ``|g . E^T u|``): by duality
    ``t <= b``, so ``tau`` is at most 1 and HiGHS' absolute feasibility tolerance (1e-10) is a relative one
    on ``t``.  The homogeneous programme is feasible at ``lam = 0``: it never fails but for the solver.

    The blocks of one configuration share ``E`` (one block per condition): ``E G`` is formed once for them,
    and the blocks' factorisations are one batched call per shape (LAPACK factors each matrix alone): the
    same programme, to the bit, as one product and one factorisation per block.
    """
    from scipy.optimize import linprog
    from scipy.sparse import csc_matrix

    k_all = len(pairs)
    t = np.full(k_all, np.inf)
    ys: list = [None] * k_all
    gen = model.generators
    n_lam = gen.shape[1]
    eg: dict = {}  # id(E) -> E G (the pairs hold every E alive while this runs: an id is not reused)
    by_shape: dict = {}  # shape -> [(k, [E G, b e] / scale, b)]
    for k, (cg, av) in enumerate(pairs):
        scale = _felt(cg, av)
        if scale is None:
            continue  # not felt at this configuration
        g = eg.get(id(cg))
        if g is None:
            g = eg[id(cg)] = cg @ gen
        b = min(float(np.sum(np.abs(av @ g))) / float(av @ av), _UNBOUNDED)
        if not b > 0:  # every play moves the closure across the violation: nothing absorbs it
            t[k], ys[k] = 0.0, np.zeros(gen.shape[0])
            continue
        mat = np.concatenate([g, b * av[:, None]], axis=1) / scale
        by_shape.setdefault(mat.shape, []).append((k, mat, b))
    rows_of: dict = {}  # k -> (orthonormal rows, b)
    for items in by_shape.values():
        _, s, vt = np.linalg.svd(np.stack([mat for _, mat, _ in items]), full_matrices=False)
        for (k, _, b), sk, vk in zip(items, s, vt):
            r = int(np.sum(sk > 1e-10 * sk[0]))
            rows_of[k] = (vk[:r], b)  # orthonormal rows: the solver's feasibility tolerance is absolute per row
    felt = sorted(rows_of)
    if not felt:
        return t, ys
    nb = len(felt)
    eq_blocks, bound = [rows_of[k][0] for k in felt], [rows_of[k][1] for k in felt]
    # variables: (lam_1, tau_1, lam_2, tau_2, ...); rows: each block's equalities
    a_eq = _block_diagonal(eq_blocks)
    cost = np.zeros(nb * (n_lam + 1))
    cost[n_lam::n_lam + 1] = -1.0
    lower = np.tile(np.r_[np.full(n_lam, -1.0), 0.0], nb)
    upper = np.concatenate([np.r_[np.full(n_lam, 1.0), _UNBOUNDED / b] for b in bound])
    x = _highs_direct(cost, a_eq, lower, upper)
    if x is None:
        a_sparse = csc_matrix((a_eq.data, a_eq.indices, a_eq.indptr), shape=a_eq.shape)
        res = linprog(cost, A_eq=a_sparse, b_eq=np.zeros(a_eq.shape[0]), bounds=np.stack([lower, upper], axis=1),
                      method="highs-ds", options={"presolve": False, **_HIGHS_TOLERANCES})
        x = res.x if res.success else None
    if x is None:
        if nb > 1:  # one block at a time (the solver's failure on one block would lose the others)
            for k in felt:
                tk, yk = _solve_zonotope(model, [pairs[k]])
                t[k], ys[k] = tk[0], yk[0]
            return t, ys
        return _solve_polygon(model, pairs)
    x = x.reshape(nb, n_lam + 1)
    for j, k in enumerate(felt):
        tk = x[j, -1] * bound[j]
        t[k] = tk if tk < 0.5 * _UNBOUNDED else np.inf
        ys[k] = gen @ x[j, :n_lam]
    return t, ys


class _Columns(NamedTuple):
    """A sparse matrix by columns (CSC arrays, 32-bit indices), as HiGHS reads it."""

    shape: tuple
    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray

    @property
    def nnz(self) -> int:
        return len(self.data)


def _block_diagonal(blocks: list) -> _Columns:
    """The block-diagonal matrix of dense ``blocks`` by columns, every entry of a block stored (zeros too): the
    arrays of ``scipy.sparse.block_diag(blocks, format="csc")``, without its general-purpose assembly (0.65 ms
    per programme of 8 blocks on the revolute Delta).  HiGHS itself leaves out the entries below 1e-9.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.sparse import block_diag
    >>> blocks = [np.array([[1.0, 0.0, 2.0]]), np.array([[0.0, 3.0], [4.0, 5.0]])]
    >>> m, ref = _block_diagonal(blocks), block_diag(blocks, format="csc")
    >>> bool(np.array_equal(m.indptr, ref.indptr) and np.array_equal(m.indices, ref.indices)
    ...      and np.array_equal(m.data, ref.data)), m.shape
    (True, (3, 5))
    """
    data, indices, counts, row0 = [], [], [], 0
    for block in blocks:
        rows, cols = block.shape
        data.append(block.T.ravel())  # column by column, each column's rows in increasing order
        indices.append(np.tile(np.arange(row0, row0 + rows, dtype=np.int32), cols))
        counts.append(np.full(cols, rows, dtype=np.int32))
        row0 += rows
    counts = np.concatenate(counts)
    indptr = np.zeros(len(counts) + 1, dtype=np.int32)
    np.cumsum(counts, out=indptr[1:])
    return _Columns((row0, len(counts)), indptr, np.concatenate(indices), np.concatenate(data))


_HIGHS_TOLERANCES = {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10}
_HIGHS: dict = {}


def _highs_direct(cost: np.ndarray, a_eq: _Columns, lower: np.ndarray, upper: np.ndarray) -> np.ndarray | None:
    """``min cost . x`` s.t. ``a_eq x = 0``, ``lower <= x <= upper`` by HiGHS' dual simplex, presolve off, called
    directly: the copy of HiGHS' own Python interface that scipy ships (``scipy.optimize._highspy``, the engine of
    :func:`scipy.optimize.linprog`), one solver object per process.  :func:`scipy.optimize.linprog` costs 0.6 ms
    more per block on the revolute Delta (its wrapper reads the basis back column by column); the same HiGHS gives
    the same bits.  The model is passed as arrays (``passModel``'s array form: no element-by-element copy through
    a ``HighsLp`` object, 0.35 ms less per programme of 8 blocks on the planar 3-RRR).  Returns ``x``, or None when
    that interface is missing (another scipy: the caller uses :func:`~scipy.optimize.linprog`) or the programme is
    not solved to optimality.
    """
    if "highs" not in _HIGHS:
        try:
            from scipy.optimize._highspy import _core

            highs = _core._Highs()
            for key, value in {"output_flag": False, "presolve": "off", "solver": "simplex", "simplex_strategy": 1,
                               **_HIGHS_TOLERANCES}.items():
                highs.setOptionValue(key, value)
            _HIGHS.update(highs=highs, core=_core)
        except (ImportError, AttributeError, TypeError):  # another scipy: linprog
            _HIGHS.update(highs=None, core=None)
    highs, core = _HIGHS["highs"], _HIGHS["core"]
    if highs is None:
        return None
    n_row, n_col = a_eq.shape
    rhs = np.zeros(n_row)
    highs.clearModel()
    try:  # columnwise (1), minimise (1), no offset, no integer column
        passed = highs.passModel(n_col, n_row, a_eq.nnz, 1, 1, 0.0, cost, lower, upper, rhs, rhs, a_eq.indptr,
                                 a_eq.indices, a_eq.data, np.zeros(n_col, dtype=np.int32))
    except TypeError:  # another interface of passModel: linprog
        return None
    if passed == core.HighsStatus.kError:  # a warning (entries below 1e-9 left out, as from an HighsLp) is fine
        return None
    highs.run()
    if highs.getModelStatus() != core.HighsModelStatus.kOptimal:
        return None
    return np.array(highs.getSolution().col_value)


def _solve_polygon(model: ClearanceModel, pairs: list) -> tuple[np.ndarray, list]:
    """:func:`_solve_group` on the play set as the supports' polygons (``|P y| <= limit``, ``|y| <= 1``)."""
    from scipy.optimize import linprog
    from scipy.sparse import block_diag, csr_matrix

    k_all = len(pairs)
    t = np.full(k_all, np.inf)
    ys: list = [None] * k_all
    n_g = model.columns.shape[1]
    eq_blocks, felt = [], []
    for k, (cg, av) in enumerate(pairs):
        scale = max(float(np.max(np.abs(cg))) if cg.size else 0.0, float(np.max(np.abs(av))) if av.size else 0.0,
                    1e-300)
        if av.size == 0 or float(np.linalg.norm(av)) <= 1e-12 * scale:
            continue  # not felt at this configuration
        mat = np.concatenate([cg, av[:, None]], axis=1) / scale
        _, s, vt = np.linalg.svd(mat, full_matrices=False)
        r = int(np.sum(s > 1e-10 * s[0]))
        eq_blocks.append(vt[:r])  # orthonormal rows: the solver's feasibility tolerance is absolute per row
        felt.append(k)
    if not felt:
        return t, ys
    nb = len(felt)
    # variables: (y_1, t_1, y_2, t_2, ...); rows: each block's equalities, then its polygon rows (both signs)
    a_eq = block_diag([csr_matrix(b) for b in eq_blocks], format="csr")
    poly = np.concatenate([model.polygon, np.zeros((len(model.polygon), 1))], axis=1)
    a_ub = block_diag([csr_matrix(np.vstack([poly, -poly]))] * nb, format="csr") if len(poly) else None
    cost = np.zeros(nb * (n_g + 1))
    cost[n_g::n_g + 1] = -1.0
    bounds = ([(-1.0, 1.0)] * n_g + [(0.0, _UNBOUNDED)]) * nb
    res = linprog(cost, A_eq=a_eq, b_eq=np.zeros(a_eq.shape[0]),
                  A_ub=a_ub, b_ub=None if a_ub is None else np.full(a_ub.shape[0], model.limit),
                  bounds=bounds, method="highs-ds",
                  options={"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10})
    if not res.success:
        # a block that cannot close even without violation would make the whole programme infeasible: solve
        # the blocks one by one (rare: only at a configuration where the linearisation fails)
        if nb > 1:
            for j, k in enumerate(felt):
                tk, yk = _solve_polygon(model, [pairs[k]])
                t[k], ys[k] = tk[0], yk[0]
            return t, ys
        t[felt[0]] = 0.0
        return t, ys
    x = res.x.reshape(nb, n_g + 1)
    for j, k in enumerate(felt):
        t[k] = x[j, -1] if x[j, -1] < 0.5 * _UNBOUNDED else np.inf
        ys[k] = x[j, :n_g]
    return t, ys


def _dual_pieces(model: ClearanceModel, c: np.ndarray) -> np.ndarray:
    """The support function of the play set as pieces: ``h_Y(c) = sum_terms max_k pieces[..., term, k]``.

    ``c`` (..., n_g) -> (..., n_terms, POLYGON_SIDES): per support (a polygon), the products with its
    vertices; per segment, ``+c`` and ``-c`` (padded).  Linear in ``c``.

    The supports of one kind are multiplied in one stacked product whose every factor is the ``(..., 2)`` matrix of
    one support (a ``(1, 2)`` row for a single ``c``), as one product per support would be: numpy hands each to
    BLAS alike, so the pieces are the same bits as support by support.
    """
    sides = POLYGON_SIDES
    theta = (2 * np.arange(sides) + 1) * np.pi / sides  # the vertices of the inscribed polygon (radius 1)
    vert = np.stack([np.cos(theta), np.sin(theta)])  # (2, N)
    c = np.asarray(c)
    single = c.ndim == 1
    if single:
        c = c[None]
    pads, pairs, segments, order = [], [], [], []  # order: (kind, index) of each term, in the groups' order
    for kind, cols in model.groups:
        if kind == "pads":  # y = (v1, v2, w1, w2); support A: (v1 - w2, v2 + w1), B: (v1 + w2, v2 - w1)
            order += [("a", len(pads)), ("b", len(pads))]
            pads.append(cols)
        elif kind in ("pad", "disc"):
            order.append(("p", len(pairs)))
            pairs.append(cols)
        else:
            order.append(("s", len(segments)))
            segments.append(cols[0])
    if not order:
        out = np.zeros(c.shape[:-1] + (0, sides))
        return out[0] if single else out
    blocks = {}
    if pads:
        cc = np.moveaxis(c[..., np.array(pads)], -2, 0)  # (n_pads, ..., 4)
        ca = np.stack([(cc[..., 0] - cc[..., 3]) / 2, (cc[..., 1] + cc[..., 2]) / 2], axis=-1)
        cb = np.stack([(cc[..., 0] + cc[..., 3]) / 2, (cc[..., 1] - cc[..., 2]) / 2], axis=-1)
        blocks["a"], blocks["b"] = ca @ vert, cb @ vert
    if pairs:
        blocks["p"] = np.ascontiguousarray(np.moveaxis(c[..., np.array(pairs)], -2, 0)) @ vert
    if segments:
        x = np.moveaxis(c[..., np.array(segments)], -1, 0)[..., None]  # (n_seg, ..., 1)
        blocks["s"] = np.concatenate([np.repeat(x, sides // 2, axis=-1), np.repeat(-x, sides // 2, axis=-1)],
                                     axis=-1)
    out = np.stack([blocks[kind][i] for kind, i in order], axis=-2)
    return out[0] if single else out


def _violation_dual(model: ClearanceModel, cg: np.ndarray, av: np.ndarray) -> np.ndarray:
    """Largest violation at configurations with one or two closure constraints left, without a programme.

    By linear-programming duality ``t = min_{u . e = 1} h_Y(E^T u)`` (``E = U0^T A C``, ``e = U0^T A d``,
    ``h_Y`` the support function of the play set, a sum of maxima of linear pieces).  With one row
    ``u = 1 / e``; with two, ``u = e / |e|^2 + s n`` (``n`` orthogonal to ``e``) and the convex
    piecewise-linear function of ``s`` is minimised by bisection on the sign of its right derivative
    (to round-off).  ``cg`` (K, r, n_g), ``av`` (K, r) with ``r`` 1 or 2; returns ``t`` (K,).
    """
    k, r, _ = cg.shape
    norm2 = np.sum(av * av, axis=1)
    u0 = av / norm2[:, None]
    a = _dual_pieces(model, np.einsum("krg,kr->kg", cg, u0))  # (K, T, N)
    if r == 1:
        return np.sum(np.max(a, axis=-1), axis=-1)
    n = np.stack([-av[:, 1], av[:, 0]], axis=1) / np.sqrt(norm2)[:, None]
    b = _dual_pieces(model, np.einsum("krg,kr->kg", cg, n))
    scale = np.maximum(np.max(np.abs(a), axis=(1, 2)), np.max(np.abs(b), axis=(1, 2))) + 1e-300

    eps = 1e-13 * scale[:, None]  # (K, 1)
    # the linear pieces along the first axis, (N, K, T): the maxima over them are elementwise over (K, T) slices
    # (a reduction over a short last axis runs row by row: 30 % of this function's time on the Tripteor; the same bits)
    a_n = np.ascontiguousarray(np.moveaxis(a, -1, 0))
    b_n = np.ascontiguousarray(np.moveaxis(b, -1, 0))

    def value_slopes_at(idx: np.ndarray | None, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """f, its left and its right derivative at ``s`` for the rows ``idx`` (None: every row)."""
        aa, bb, ee = (a_n, b_n, eps) if idx is None else (a_n[:, idx], b_n[:, idx], eps[idx])
        v = s[None, :, None] * bb
        v += aa
        # the ufuncs' reductions called directly (numpy.max and numpy.sum call them, through Python wrappers)
        top = np.maximum.reduce(v, axis=0)  # (K, T)
        act = v >= top - ee
        right = np.add.reduce(np.maximum.reduce(np.where(act, bb, -np.inf), axis=0), axis=-1)
        left = np.add.reduce(np.minimum.reduce(np.where(act, bb, np.inf), axis=0), axis=-1)
        return np.add.reduce(top, axis=-1), left, right

    # bracket the minimiser: the right derivative is negative at lo, the left one positive at hi
    width = np.full(k, 1.0) / np.sqrt(norm2)
    lo, hi = -width.copy(), width.copy()
    both = np.concatenate([np.arange(k), np.arange(k)])  # lo and hi in one evaluation (each row its own)
    for _ in range(80):
        f, left, right = value_slopes_at(both, np.concatenate([lo, hi]))
        f_lo, g_lo, f_hi, g_hi = f[:k], right[:k], f[k:], left[k:]
        bad_lo, bad_hi = g_lo >= 0, g_hi <= 0
        if not (bad_lo.any() or bad_hi.any()):
            break
        lo = np.where(bad_lo, 2 * lo, lo)
        hi = np.where(bad_hi, 2 * hi, hi)
    # cutting planes: the supporting lines at lo and hi meet at s, a lower bound of the minimum there; the
    # function is piecewise linear, so this ends on the minimiser after a few cuts
    best = np.minimum(f_lo, f_hi)
    open_ = np.ones(k, dtype=bool)
    for _ in range(200):
        idx = np.nonzero(open_)[0]
        if not len(idx):
            break
        denom = g_lo[idx] - g_hi[idx]
        s_new = (f_hi[idx] - f_lo[idx] + g_lo[idx] * lo[idx] - g_hi[idx] * hi[idx]) / denom
        s_new = np.clip(s_new, lo[idx], hi[idx])
        bound = f_lo[idx] + g_lo[idx] * (s_new - lo[idx])
        f_new, left, right = value_slopes_at(idx, s_new)
        best[idx] = np.minimum(best[idx], f_new)
        done = (best[idx] - bound <= 1e-13 * np.abs(best[idx])) | ((left <= 0) & (right >= 0))
        go_right = right < 0
        lo[idx] = np.where(go_right, s_new, lo[idx])
        f_lo[idx], g_lo[idx] = np.where(go_right, f_new, f_lo[idx]), np.where(go_right, right, g_lo[idx])
        hi[idx] = np.where(go_right, hi[idx], s_new)
        f_hi[idx], g_hi[idx] = np.where(go_right, f_hi[idx], f_new), np.where(go_right, g_hi[idx], left)
        open_[idx[done]] = False
    return best


class AssemblyConditions(Objective):
    """The largest violation the clearances absorb, per assembly condition, as functions of configurations.

    Where one or two closure constraints are left (``U0`` of one or two columns: the Tripteor) the
    value comes from the dual of the programme (:func:`_violation_dual`, no solver call); otherwise
    from the programme itself (:func:`_solve`).

    Parameters
    ----------
    model : ClearanceModel
    items : list of Tolerance
        Assembly conditions (``direction``: one unit of violation, rad / mm).
    """

    loop_only = True

    def __init__(self, model: ClearanceModel, items: list, kinematics: Kinematics | None = None) -> None:
        self.model = model
        self.kin = kinematics or Kinematics(model.mechanism)
        self.names = tuple(it.id for it in items)
        self.d = {it.id: _lift(model, it.direction) for it in items}

    def plays(self, q: np.ndarray, which: list, exact: bool = False) -> tuple[np.ndarray, list]:
        """``t`` of condition ``which[k]`` at ``q[k]``, and the plays there (with ``exact``: from the programme)."""
        q = np.atleast_2d(q)
        uniq, inverse = np.unique(q, axis=0, return_inverse=True)
        blocks = _constraint_blocks(self.model, uniq, self.kin)
        pairs = [(blocks[i][0], blocks[i][1] @ self.d[w]) for i, w in zip(np.ravel(inverse), which)]
        t = np.full(len(pairs), np.inf)
        ys: list = [None] * len(pairs)
        rows = np.array([len(av) for _, av in pairs])
        felt = np.array([len(av) > 0 and float(np.linalg.norm(av)) > 1e-12 * max(
            float(np.max(np.abs(cg))) if cg.size else 0.0, float(np.max(np.abs(av))), 1e-300) for cg, av in pairs],
            dtype=bool)
        lp = [k for k in range(len(pairs)) if felt[k] and (exact or rows[k] > 2)]
        for r in (1, 2):
            idx = [k for k in range(len(pairs)) if felt[k] and not exact and rows[k] == r]
            if idx:
                t[idx] = _violation_dual(self.model, np.stack([pairs[k][0] for k in idx]),
                                         np.stack([pairs[k][1] for k in idx]))
        if lp:
            tk, yk = _solve(self.model, [pairs[k] for k in lp], plays=exact)
            t[lp] = tk
            for k, y in zip(lp, yk):
                ys[k] = y
        t[t >= 0.5 * _UNBOUNDED] = np.inf
        return t, ys

    def pick(self, q: np.ndarray, which: list) -> np.ndarray:
        return self.plays(q, which)[0]

    def values(self, q: np.ndarray) -> dict:
        q = np.atleast_2d(q)
        k = len(q)
        t = self.pick(np.repeat(q, len(self.names), axis=0), [n for _ in range(k) for n in self.names])
        return {n: t[i::len(self.names)] for i, n in enumerate(self.names)}


def assembly_tolerances(mechanism: Mechanism, items: list, declaration: Declaration, configurations: np.ndarray,
                        model: ClearanceModel | None = None, reference: int | None = None, workspace=None,
                        search: bool = True) -> dict:
    """Tolerance of every assembly condition from the clearances (see the module docstring).

    Parameters
    ----------
    items : list of Tolerance
        Assembly conditions (``direction``: one unit of violation, rad / mm).
    configurations : ndarray, (K, n_q)
        Assembled configurations of the workspace (the search starts from them).
    reference : int, optional
        The first ``reference`` configurations form a reference set (e.g. the analysis'
        configurations) whose own worst case is reported beside the value
        (``reference_value``), to show what the search changed.
    workspace : Workspace, optional
        Bounds of the search (default: the mechanism's declared workspace).
    search : bool
        Search the workspace (:func:`hyperstat.solver.tolerances.worst_case.search_extremes`);
        ``False``: the smallest value over ``configurations`` only.

    Returns
    -------
    dict
        Tolerance id -> {"value" (the smallest violation absorbed over the workspace less the search's
        tolerance; None when the plays absorb any small violation), "searched" (the minimum found),
        "sampled_value" (over ``configurations``), "reference_value", "worst_q", "where", "start",
        "location", "limiting" (joints whose play is used up there), "configurations", "evidence"}.
    """
    from hyperstat.solver.tolerances.worst_case import search_extremes
    from hyperstat.solver.tolerances.workspace import workspace_of

    model = model or clearance_model(mechanism, declaration)
    kin = Kinematics(model.mechanism)
    objective = AssemblyConditions(model, items, kin)
    q = np.atleast_2d(configurations)
    sampled = objective.values(q)
    ws = workspace or workspace_of(model.mechanism)
    found = search_extremes(kin, objective, q, ws, kinds=("min",), starts=2, sampled=sampled) if search else {}
    out = {}
    for it in items:
        v = sampled[it.id]
        e = found.get((it.id, "min"))
        best = int(np.argmin(v)) if len(v) else 0
        entry = {"configurations": int(len(q)), "sampled_value": float(v[best]) if len(v) and np.isfinite(v[best])
                 else None}
        if reference:
            ref = float(np.min(v[:reference]))
            entry["reference_value"] = ref if np.isfinite(ref) else None
            entry["reference_configurations"] = min(reference, len(q))
        if e is not None and np.isfinite(e.value):
            tol = e.tolerance if math.isfinite(e.tolerance) else 0.0
            worst_q = e.q
            entry.update(value=max(e.value - tol, 0.0), searched=e.value, search_tolerance=e.tolerance,
                         where=e.where(), start=e.start, location=e.location, evidence=e.evidence,
                         candidates=e.starts)
        elif len(v) and np.isfinite(v[best]):
            worst_q = q[best]
            entry.update(value=float(v[best]), searched=None, where="at a given configuration", start="sample",
                         location="sample", evidence="not searched")
        else:
            worst_q = None
            entry.update(value=None, searched=None, where=None, start=None, location=None,
                         evidence="the clearances absorb any small violation at every configuration")
        entry["worst_q"] = None if worst_q is None else np.asarray(worst_q, float)
        entry["limiting"], entry["at_bound"] = [], 0
        if worst_q is not None:
            t_w, y_w = objective.plays(worst_q[None], [it.id], exact=True)
            if y_w[0] is not None:
                use = model.use(y_w[0])
                full = [j for j, u in sorted(use.items(), key=lambda kv: -kv[1]) if u > 0.999]
                entry["limiting"] = [f"joint {j} ({_play_words(model.sources[j])})" for j in full[:4]]
                entry["at_bound"] = len(full)
        out[it.id] = entry
    return out


def _play_words(c: dict) -> str:
    kind = "carriage" if c["side"] == "moving" else "supports"
    return (f"{kind} {c['span_mm']:g} mm apart, radial play {1000 * c['radial_mm']:g} µm"
            if math.isfinite(c["span_mm"]) else f"radial play {1000 * c['radial_mm']:g} µm")


def _closure(kin: Kinematics, model: ClearanceModel, qq: np.ndarray, d: np.ndarray, t: float, y: np.ndarray):
    """Scaled residual and Jacobians (passive joints, plays, violation) at one configuration."""
    xi = t * d + model.columns @ y
    st = kin.evaluate(qq, xi, jacobians=True)
    ja = kin.scaled_rows(st.closure_xi)[0]
    return (kin.scaled(st.residual)[0], kin.scaled_rows(st.closure_q)[0][:, model.mechanism.passive],
            ja @ model.columns, ja @ d)


def confirm_nonlinear(mechanism: Mechanism, direction: np.ndarray, value: float, q: np.ndarray,
                      declaration: Declaration, model: ClearanceModel | None = None, margin: float = 0.01,
                      iterations: int = 40) -> dict:
    """Check a linear assembly tolerance with the full nonlinear model, the plays as bounded extra joints.

    The plays become extra variables of each joint (small prismatic and revolute joints:
    support shifts and tilts, axial shifts, a slide's twist), within the supports' polygons.
    Two checks at the configuration ``q``:

    * **below**: at ``(1 - margin) value`` the loops are closed by Newton steps on the
      passive joints and the plays (minimum-norm corrections), starting from the linear
      programme's plays; the residual must fall to round-off with every play within its
      clearance;
    * **maximum**: the largest violation for which the loops close is found by sequential
      linear programming (the closure linearised at the current point, ``max t`` with the
      plays admissible and a shrinking trust region on them), then the loops are
      re-assembled there with the passive joints alone.

    Returns
    -------
    dict
        ``linear`` (the value given), ``below`` {``violation``, ``closure_residual_mm``,
        ``largest_clearance_use``}, ``value`` (nonlinear maximum), ``relative_difference``,
        ``closure_residual_mm`` (re-assembled at the nonlinear maximum), ``iterations``.
    """
    from scipy.optimize import linprog

    model = model or clearance_model(mechanism, declaration)
    kin = Kinematics(model.mechanism)
    passive = model.mechanism.passive
    d = _lift(model, direction)
    q0 = np.array(q, dtype=float)[None]
    n_g = model.columns.shape[1]
    poly = model.polygon

    def use(y: np.ndarray) -> float:
        return max(model.use(y).values(), default=0.0)

    def step_lp(qq, t, y, radius):
        r, jq, jy, jt = _closure(kin, model, qq, d, t, y)
        u, sv, _ = np.linalg.svd(jq, full_matrices=True)
        rank = int(np.sum(sv > 1e-9 * sv[0])) if sv.size and sv[0] > 0 else 0
        u0 = u[:, rank:]
        a_eq = u0.T @ np.concatenate([jy, jt[:, None]], axis=1)
        b_eq = -(u0.T @ (r - jy @ y - jt * t))
        scale = max(float(np.max(np.abs(a_eq))), 1e-300)
        bounds = [(max(-1.0, yi - radius), min(1.0, yi + radius)) for yi in y] + [(0.0, None)]
        a_ub = np.concatenate([np.vstack([poly, -poly]), np.zeros((2 * len(poly), 1))], axis=1) if len(poly) else None
        res = linprog(np.r_[np.zeros(n_g), -1.0], A_eq=a_eq / scale, b_eq=b_eq / scale, bounds=bounds,
                      A_ub=a_ub, b_ub=None if a_ub is None else np.full(len(a_ub), model.limit), method="highs")
        if not res.success:
            return None
        y_new, t_new = res.x[:n_g], float(res.x[-1])
        dq = -np.linalg.lstsq(jq, r + jy @ (y_new - y) + jt * (t_new - t), rcond=1e-12)[0]
        return dq, y_new, t_new

    # below: linear plays at (1 - margin) value, then Newton (minimum-norm corrections)
    qq = q0.copy()
    first = step_lp(qq, 0.0, np.zeros(n_g), 1.0)
    below = {"violation": (1 - margin) * value, "closure_residual_mm": None, "largest_clearance_use": None}
    if first is not None and first[2] > 0:
        y = first[1] * (1 - margin) * value / first[2]
        qq[0, passive] += first[0] * (1 - margin) * value / first[2]
        t = (1 - margin) * value
        for _ in range(20):
            r, jq, jy, _ = _closure(kin, model, qq, d, t, y)
            if np.linalg.norm(r) < 1e-12 * kin.length_scale:
                break
            step = -np.linalg.lstsq(np.concatenate([jq, jy], axis=1), r, rcond=1e-12)[0]
            qq[0, passive] += step[: len(passive)]
            y = y + step[len(passive):]
        r = _closure(kin, model, qq, d, t, y)[0]
        below.update(closure_residual_mm=float(np.linalg.norm(r)), largest_clearance_use=use(y))

    # maximum: sequential linear programming with a shrinking trust region
    qq = q0.copy()
    t, y, radius, steps = 0.0, np.zeros(n_g), 1.0, 0
    for steps in range(1, iterations + 1):
        out = step_lp(qq, t, y, radius)
        if out is None:
            break
        dq, y_new, t_new = out
        qq[0, passive] += dq
        change = abs(t_new - t)
        t, y = t_new, y_new
        radius = max(radius * 0.6, 1e-9) if steps > 1 else 0.2
        if change <= 1e-9 * max(abs(t), 1e-300) and steps > 3:
            break
    xi = t * d + model.columns @ y
    closed = kin.assemble(qq, xi, tol=1e-13)
    return {"linear": float(value), "below": below, "value": t,
            "relative_difference": abs(t - value) / max(abs(value), 1e-300),
            "closure_residual_mm": float(closed.residual[0]), "largest_clearance_use": use(y) if n_g else 0.0,
            "iterations": steps}
