"""Exact (rational) stationarity rows with sympy, to certify rank decisions.

Units: lengths in mm, angles in rad.

Floating-point rank decisions rest on a singular-value gap.  When the nominal
geometry is rational (every placement entry a rational number, as in axis-aligned
skeletons) and the mechanism has configurations where every joint value is
*rational-trigonometric* (``cos`` and ``sin`` rational, i.e. ``tan(q/2)`` rational or
``q = pi``), the stationarity matrices of paper 1, eq. (3) can be computed exactly over
the rationals.  Their exact rank, and the exact set of parameters they force to zero,
then certify the numerical verdicts.  Rows taken at any configuration are valid
constraints, so the exact rank is a lower bound of the generic rank; equality with
the numerical rank, together with the nonlinear re-assembly of the free parameters
(:mod:`hyperstat.solver.analysis.verify`), settles the decision.

Rational configurations are found by rationalising assembled floating-point
configurations (from a sample and from actuated values at multiples of pi/2 and
integers) and keeping those that close *exactly*.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np


class _LazySympy:
    """``sympy``, imported on first use: it takes about a second to import and only
    ``--exact`` needs it, so ``import solver`` stays fast."""

    def __getattr__(self, name: str):
        import sympy

        return getattr(sympy, name)


sp = _LazySympy()

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Joint, Mechanism
from hyperstat.solver.analysis.stationarity import gauge_parameters

__all__ = ["ExactCheck", "exact_check", "rational_placement", "find_rational_configurations"]


@dataclass
class ExactCheck:
    """Outcome of :func:`exact_check`.

    Attributes
    ----------
    available : bool
        Whether an exact computation could be made.
    reason : str
        Why not, when not available; otherwise a summary.
    rank : int
        Exact rank of the stacked constraint rows (non-gauge parameters).
    forced : list of str
        Parameters the exact rows force to zero.
    relations : list of dict
        The relations between the other parameters, exact: ``{"terms": {name: "p/q"}, "text"}``, from
        the reduced row-echelon form of the exact rows (pivots in parameter order; exact arithmetic has no
        conditioning to keep).
    configurations : list of list of str
        The exact configurations used (joint values as ``tan(q/2)`` or ``pi`` for
        revolutes, lengths for prismatics).
    """

    available: bool
    reason: str
    rank: int = 0
    forced: list = field(default_factory=list)
    configurations: list = field(default_factory=list)
    relations: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready dictionary (exact relations' coefficients as rational strings)."""
        return {"available": self.available, "reason": self.reason, "rank": self.rank, "forced": self.forced,
                "configurations": self.configurations, "relations": [dict(r) for r in self.relations]}


def _rat(x: float, max_den: int = 10**6, tol: float = 1e-12) -> sp.Rational | None:
    f = Fraction(x).limit_denominator(max_den)
    if abs(float(f) - x) > tol * max(1.0, abs(x)):
        return None
    return sp.Rational(f.numerator, f.denominator)


def rational_placement(t: np.ndarray) -> sp.Matrix | None:
    """Exact rational 4x4 matrix of a rigid placement, or ``None`` if it is not rational."""
    out = sp.zeros(4, 4)
    for i in range(3):
        for j in range(4):
            r = _rat(float(t[i, j]))
            if r is None:
                return None
            out[i, j] = r
    out[3, 3] = 1
    rot = out[:3, :3]
    if rot.T * rot != sp.eye(3) or rot.det() != 1:
        return None
    return out


def _trig(kind: str, value: float) -> tuple | None:
    """Exact (cos, sin) of a revolute value or the exact length of a prismatic value."""
    if kind == "P":
        r = _rat(value, 10**4, 1e-11)
        return None if r is None else (r,)
    v = (value + np.pi) % (2 * np.pi) - np.pi
    if abs(abs(v) - np.pi) < 1e-11:
        return (sp.Integer(-1), sp.Integer(0))
    t = _rat(float(np.tan(v / 2.0)), 10**4, 1e-11)
    if t is None:
        return None
    return ((1 - t**2) / (1 + t**2), 2 * t / (1 + t**2))


def _motion(kind: str, exact: tuple) -> sp.Matrix:
    if kind == "P":
        m = sp.eye(4)
        m[2, 3] = exact[0]
        return m
    c, s = exact
    return sp.Matrix([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def _exact_frames(mech: Mechanism, placements: dict, joints: list) -> tuple[dict, dict, dict]:
    frames = {mech.base: sp.eye(4)}
    ends: dict = {}
    lframes: dict = {}
    parents: dict = {}
    for ci in mech.topology["order"]:
        ch = mech.chains[ci]
        t = frames[ch.start]
        for ei, el in enumerate(ch.elements):
            parents[(ci, ei)] = t
            lf = t * placements[(ci, ei)]
            lframes[(ci, ei)] = lf
            t = lf * _motion(el.type, joints[mech.joint_index[el.name]]) if isinstance(el, Joint) else lf
        if ch.end in frames:
            ends[ci] = t
        else:
            frames[ch.end] = t
    return frames, ends, (lframes, parents)


def find_rational_configurations(mechanism: Mechanism, kin: Kinematics | None = None,
                                 candidates: np.ndarray | None = None, limit: int = 6) -> list[list[tuple]]:
    """Configurations of the nominal mechanism where every joint value is exact and closure is exact.

    Candidates: actuated values at multiples of pi/2 (revolute) and whole millimetres
    around home (prismatic), assembled from home, plus ``candidates``.
    """
    kin = kin or Kinematics(mechanism)
    m = mechanism
    act = m.actuated
    placements = {}
    for ci, ch in enumerate(m.chains):
        for ei, el in enumerate(ch.elements):
            placements[(ci, ei)] = rational_placement(el.placement.matrix())
    grid = []
    for i in act:
        j = m.joints[i]
        lo, hi = j.range
        if j.type == "R":
            vals = [v for v in np.arange(-2, 3) * np.pi / 2 if lo - 1e-12 <= v <= hi + 1e-12]
        else:
            vals = list(np.round(np.linspace(lo, hi, 5)))
        grid.append(vals or [j.home])
    mesh = np.array(np.meshgrid(*grid, indexing="ij")).reshape(len(act), -1).T if len(act) else np.zeros((1, 0))
    qa = mesh[:64]
    res = kin.solve(qa, steps=12)
    pool = [res.q[i] for i in range(len(qa)) if res.converged[i]]
    if candidates is not None:
        pool += list(np.atleast_2d(candidates))
    found: list[list[tuple]] = []
    for q in pool:
        exact = [_trig(j.type, float(v)) for j, v in zip(m.joints, q)]
        if any(e is None for e in exact):
            continue
        frames, ends, _ = _exact_frames(m, placements, exact)
        if all((ends[cl.chain] - frames[cl.frame]).is_zero_matrix for cl in m.closures):
            if exact not in found:
                found.append(exact)
        if len(found) >= limit:
            break
    return found


def _cross(a: sp.Matrix, b: sp.Matrix) -> sp.Matrix:
    return a.cross(b)


def exact_check(mechanism: Mechanism, configurations: list | None = None, kin: Kinematics | None = None) -> ExactCheck:
    """Exact rank of the stationarity rows at rational configurations (paper 1, eq. 3).

    Parameters
    ----------
    mechanism : Mechanism
        Nominal model; its placements must be rational.
    configurations : list, optional
        Exact configurations as returned by :func:`find_rational_configurations`;
        searched for when omitted.
    kin : Kinematics, optional
        Reuse a forward model.

    Returns
    -------
    ExactCheck
    """
    m = mechanism
    placements = {}
    for ci, ch in enumerate(m.chains):
        for ei, el in enumerate(ch.elements):
            p = rational_placement(el.placement.matrix())
            if p is None:
                return ExactCheck(False, f"the nominal placement of element '{el.name}' is not rational")
            placements[(ci, ei)] = p
    if not m.closures:
        return ExactCheck(True, "no loop closure: nothing is forced", 0, [], [])
    configs = configurations if configurations is not None else find_rational_configurations(m, kin)
    if not configs:
        return ExactCheck(False, "no configuration with exact rational joint values closes the nominal mechanism")
    gauges = gauge_parameters(m)
    params = [p for p in m.parameters if p.name not in gauges]
    rows = []
    e = [sp.Matrix([1, 0, 0]), sp.Matrix([0, 1, 0]), sp.Matrix([0, 0, 1])]
    comp = {"I": 0, "J": 1, "K": 2, "a": 0, "b": 1, "c": 2}
    for exact in configs:
        frames, ends, (lframes, parents) = _exact_frames(m, placements, exact)
        for cl in m.closures:
            p_x = frames[cl.frame][:3, 3]
            members = {}
            for key in cl.path:
                members[key] = members.get(key, 0) + 1
            for key in cl.reference_path:
                members[key] = members.get(key, 0) - 1

            def column(key, twist):
                sign = members.get(key, 0)
                if sign == 0:
                    return sp.zeros(6, 1)
                w, v = twist
                return sign * w.col_join(v + _cross(w, p_x))

            a_cols = []
            for p in params:
                key = (p.chain, p.index)
                rp = parents[key][:3, :3]
                o = lframes[key][:3, 3]
                n0 = placements[key][:3, 2]
                if p.component in "IJK":
                    w = rp * _cross(n0, e[comp[p.component]])
                    tw = (w, _cross(o, w))
                elif p.component in "abc":
                    tw = (sp.zeros(3, 1), rp * e[comp[p.component]])
                else:
                    w = lframes[key][:3, 2]
                    tw = (w, _cross(o, w))
                a_cols.append(column(key, tw))
            b_cols = []
            for ji in m.passive:
                j = m.joints[ji]
                key = next(k for k in lframes if m.chains[k[0]].elements[k[1]].name == j.name)
                z = lframes[key][:3, 2]
                o = lframes[key][:3, 3]
                tw = (z, _cross(o, z)) if j.type == "R" else (sp.zeros(3, 1), z)
                b_cols.append(column(key, tw))
            a = sp.Matrix.hstack(*a_cols) if a_cols else sp.zeros(6, 0)
            b = sp.Matrix.hstack(*b_cols) if b_cols else sp.zeros(6, 0)
            rows.append((a, b))
    # Stack closures of one configuration together before taking the left null space.
    n_cl = len(m.closures)
    g_rows = []
    for c in range(0, len(rows), n_cl):
        a = sp.Matrix.vstack(*[r[0] for r in rows[c:c + n_cl]])
        b = sp.Matrix.vstack(*[r[1] for r in rows[c:c + n_cl]])
        left = (b.T).nullspace() if b.shape[1] else [sp.eye(a.shape[0])[:, i] for i in range(a.shape[0])]
        for v in left:
            g_rows.append(v.T * a)
    g = sp.Matrix.vstack(*g_rows) if g_rows else sp.zeros(0, len(params))
    rank = g.rank()
    null = g.nullspace()
    forced = [p.name for i, p in enumerate(params) if all(v[i] == 0 for v in null)]
    free = [i for i, p in enumerate(params) if p.name not in forced]
    relations = []
    if free and g.shape[0]:
        reduced, pivots = g[:, free].rref()
        for row in range(len(pivots)):
            terms = {params[free[j]].name: reduced[row, j] for j in range(len(free)) if reduced[row, j] != 0}
            if len(terms) > 1:
                text = " ".join((("" if k == 0 and c > 0 else "-" if k == 0 else "+ " if c > 0 else "- ")
                                 + ("" if abs(c) == 1 else f"{abs(c)}*") + n)
                                for k, (n, c) in enumerate(terms.items())) + " = 0"
                relations.append({"terms": {n: str(c) for n, c in terms.items()}, "text": text})
    shown = [[("pi" if (len(x) == 2 and x == (-1, 0)) else str(x[0]) if len(x) == 1 else str(sp.nsimplify(x[1] / (1 + x[0]))))
              for x in cfg] for cfg in configs]
    return ExactCheck(True, f"exact rank {rank} over the rationals at {len(configs)} configuration(s)", int(rank),
                      forced, shown, relations)
