"""The one worst-case engine: extremes of a function of the configuration over the workspace, searched.

Units: joint values in mm and rad; the functions in their own units (coefficients in rad/rad,
mm/rad, ...; assembly violations in mm or rad).

Every worst case of hyperstat goes through :func:`search_extremes`: the largest accuracy
coefficients (paper 2, eq. 18, whole or restricted to the task) that the allocation divides by,
and the smallest violation of an assembly condition that the joint clearances absorb
(:mod:`hyperstat.solver.tolerances.clearance`).  A sampled extreme is on the unsafe side (a
sampled maximum is low, a sampled minimum high), so the workspace is *searched*:

1. **Candidates**: the given sample of the workspace; the corners of the actuated box; points
   along its edges; and every configuration where a joint velocity changes sign along an edge
   or along a coordinate line of a full-turn actuator (a *dead centre*: the slider-crank at
   ``theta1 = 0, pi``), found by bracketing the sign change on a grid and solving for it
   (regula falsi, :func:`workspace_candidates`; a joint the line does not move has none).  All are
   assembled on the branch of the workspace by certified continuation from the nearest of the
   workspace's fixed checkpoints, the same for every sample and command.
2. **Local search** from the best separate candidates, batched over all functions and starts:
   a projected-gradient method *on the configuration manifold* (all joints the function depends
   on are the variables, the closure holds them on the manifold): the gradient is taken by
   forward differences along a basis of the tangent space (the null space of the closure
   Jacobian with the joints at an active bound held), the step is projected on the bounds
   (actuated box, declared passive ranges moved inwards by :data:`MARGIN`), and the new point is
   brought back onto the closure by minimum-norm Newton corrections.  A step is refused if its
   correction is not small against it (the branch could change), if it leaves a bound, or if it
   comes to a configuration whose passive Jacobian is conditioned below :data:`CONDITIONING_FLOOR`
   times its median over the sample away from any declared passive bound (a singular edge
   inside the workspace, where a coefficient can grow without bound).  So interiors, faces,
   edges and corners are all searched: a bound that becomes active is held, and released
   when the gradient points inwards.
3. **A singular edge refined once.** When the extreme lies on a declared passive bound where the
   passive Jacobian is singular (the Triflex-II's PRRU leg stretched), the value is a supremum,
   approached and not attained.  Instead of optimising again at several margins, the one path
   found at :data:`MARGIN` is moved towards the edge along the bounded joint only (the other
   coordinates follow by minimum-norm corrections), the function is evaluated at margins
   1e-3 ... 1e-6 in one batch, and the remaining gap to the edge is estimated from that
   sequence (Richardson, its order estimated from the sequence itself): the cost does not grow
   with the number of margins.
4. **Checks**: the end point is re-assembled at its actuated values, checked inside the workspace,
   and checked to be on the branch of its start (a certified continuation back to the start
   must land on it).  The value reported is never less extreme than the best candidate.

A local method finds the global extreme only if one start lies in its basin; the candidates
make that likely on the shipped templates, and the tests compare every value with an
independent search (its own kinematics, dense grids and root-finding of the dead centres).
The stated ``tolerance`` is 0 where no ascent direction is left within the bounds (a stationary
point, to the accuracy of the forward differences), the first-order gain of the shortest step tried
where no step down to 1e-8 improved (a kink), the last accepted improvement where the improvements
fell below 1e-12 of the value (the remaining improvement is smaller when the search converges
linearly with a ratio below 1/2), or the estimated remaining gap of a supremum; a search stopped at
its iteration limit says so, with its last improvement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.continuation import batched_lstsq
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.tolerances.accuracy import (COEFFICIENT_NAMES, AccuracyMaps, geometric_parameters,
                                                  largest_singular_value)
from hyperstat.solver.tolerances.spilled import SpilledArray, row_blocks, take_rows
from hyperstat.solver.tolerances.workspace import Workspace, workspace_of

__all__ = ["Extreme", "Objective", "Coefficients", "TaskCoefficients", "search_extremes", "refine_extremes",
           "workspace_candidates", "remember_candidates", "coefficient_at", "branch_conditioning", "prepare_searches",
           "TASK_COEFFICIENTS"]

#: passive bounds are moved inwards by this much (rad; times the length scale for mm)
MARGIN = 1e-4
#: relative smallest singular value of the scaled passive Jacobian below which a configuration is singular
SINGULAR = 1e-2
#: a step is refused where the conditioning falls below this fraction of its median over the sample, away from
#: the declared passive bounds: at a singular edge inside the workspace a coefficient can grow without bound
CONDITIONING_FLOOR = 1e-2
#: the task-restricted coefficients the allocation divides by (paper 2, eq. 18, task rows only)
TASK_COEFFICIENTS = ("delta_gP", "delta_gR", "epsilon_gP", "epsilon_gR")
#: a passive joint whose largest velocity along a line of the actuated box is below this share of the line's largest
#: (scaled: rad, or mm per length scale, per unit of the actuator) does not move along it: no dead centre there
NOT_MOVING = 1e-9
#: margins (rad, or times the length scale) at which a supremum at a singular edge is evaluated, in one batch
EDGE_MARGINS = (1e-3, 1e-4, 1e-5, 1e-6)


@dataclass
class Extreme:
    """An extreme (largest or smallest value) of one function over the workspace.

    Attributes
    ----------
    coefficient : str
        The function's name (an accuracy coefficient of paper 2, eq. 18, or a tolerance id).
    kind : str
        ``"max"`` or ``"min"``.
    value : float
        The extreme found (never less extreme than ``sampled``).
    sampled : float
        The extreme over the candidates (sample, corners, edges, dead centres).
    q : ndarray, (n_q,)
        Where it is reached (all joints, mm / rad).
    actuated : dict
        Actuated joint name -> value there.
    position : list of float
        Output origin there (mm).
    location : str
        ``"interior"``, ``"boundary"`` (a workspace bound is active) or ``"constant"``.
    bounds : list of str
        Active workspace bounds there, in words (the actuated ones say face, edge or corner).
    singular : bool
        The passive Jacobian is (nearly) singular there (edge of the assembly branch).
    supremum : bool
        The value is approached at a singular boundary, not attained.
    tolerance : float
        Estimated distance of ``value`` from the true (local) extreme, in the function's unit; NaN
        when the search stopped at its iteration limit while still improving.
    starts, agreeing : int
        Local searches run, and how many reached ``value`` within the tolerance.
    iterations : int
        Iterations of the search path that gave ``value``.
    start : str
        The candidate the best path started from (``sample``, ``corner``, ``edge``, ``dead centre ...``).
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
    iterations: int = 0
    start: str = ""
    evidence: str = ""

    def as_dict(self) -> dict:
        """JSON-ready (lengths in mm, angles in rad)."""
        return {"kind": self.kind, "value": self.value, "sampled": self.sampled, "tolerance": self.tolerance,
                "location": self.location, "where": self.where(), "bounds": list(self.bounds),
                "singular": self.singular, "supremum_on_boundary": self.supremum, "actuated": dict(self.actuated),
                "position_mm": list(self.position), "configuration": self.q.tolist(), "starts": self.starts,
                "agreeing_starts": self.agreeing, "iterations": self.iterations, "start": self.start,
                "evidence": self.evidence}

    def where(self) -> str:
        """One line saying where the extreme is reached."""
        if self.location == "constant":
            return "constant over the workspace"
        at = ", ".join(f"{k}={v:.6g}" for k, v in self.actuated.items())
        text = f"{self.location} at {at} (O_p = {', '.join(f'{v:.4g}' for v in self.position)} mm)"
        if self.bounds:
            text += "; " + "; ".join(self.bounds)
        if self.supremum:
            text += "; a supremum on the boundary (approached, not attained: the passive Jacobian is singular there)"
        return text


class Objective:
    """Functions of assembled configurations that :func:`search_extremes` extremises.

    Subclasses set ``names`` and implement :meth:`values`; ``loop_only`` says that the functions
    depend only on the joints of the closed loops (an assembly condition), so the serial tail is
    held still.
    """

    names: tuple = ()
    loop_only: bool = False

    def values(self, q: np.ndarray) -> dict:
        """Name -> (K,) values at configurations ``q`` (K, n_q)."""
        raise NotImplementedError

    def pick(self, q: np.ndarray, which: list) -> np.ndarray:
        """Value of function ``which[k]`` at ``q[k]`` (K,)."""
        v = self.values(q)
        return np.array([v[n][k] for k, n in enumerate(which)], dtype=float)


#: configurations per block of the coefficients' full Jacobians (:func:`_in_blocks`): each configuration is computed
#: alone, so the values are the same bits whatever the block, and a block's defect Jacobians (the hexapod's: 36 x 234
#: per configuration) stay near the cache instead of 1,095 configurations' 74 MiB at once (issue 39)
EVALUATION_BLOCK = 256


def _in_blocks(values, q: np.ndarray) -> dict:
    """``values(q)`` (name -> (K,) array) computed :data:`EVALUATION_BLOCK` configurations at a time, joined."""
    q = np.atleast_2d(q)
    if len(q) <= EVALUATION_BLOCK:
        return values(q)
    parts = [values(q[i:i + EVALUATION_BLOCK]) for i in range(0, len(q), EVALUATION_BLOCK)]
    return {n: np.concatenate([p[n] for p in parts]) for n in parts[0]}


class Coefficients(Objective):
    """The accuracy coefficients of paper 2, eq. (18), as functions of configurations.

    Parameters
    ----------
    kin : Kinematics
    analysis : StationarityResult, optional
        Restricts the geometric errors to the admissible influential coordinates
        (:func:`hyperstat.solver.tolerances.accuracy.geometric_parameters`).
    names : tuple of str, optional
        A subset of :data:`~hyperstat.solver.tolerances.accuracy.COEFFICIENT_NAMES`.
    """

    def __init__(self, kin: Kinematics, analysis=None, names: tuple | None = None) -> None:
        m = kin.mechanism
        self.kin = kin
        self.names = tuple(names or COEFFICIENT_NAMES)
        gnames, self.matrix = geometric_parameters(m, analysis)
        units = {p.name: p.unit for p in m.parameters}
        self.cols = {}
        for name in self.names:
            label, kind = name.split("_")[1][0], name.split("_")[1][1]
            rows = slice(0, 3) if name.startswith("delta") else slice(3, 6)
            if label == "f":
                cols = [a for a, i in enumerate(m.actuated) if (m.joints[i].type == "P") == (kind == "P")]
            else:
                cols = [j for j, n in enumerate(gnames) if (units[n] == "mm") == (kind == "P")]
            self.cols[name] = (label, rows, cols)

    def values(self, q: np.ndarray) -> dict:
        return _in_blocks(self._values, q)

    def _values(self, q: np.ndarray) -> dict:
        from hyperstat.solver.tolerances.twist_blocks import nominal_twist_maps

        k_xi, k_a, _ = nominal_twist_maps(self.kin, q)
        k_g = k_xi @ self.matrix
        return {n: largest_singular_value((k_a if label == "f" else k_g)[:, rows][:, :, cols])
                for n, (label, rows, cols) in self.cols.items()}


class TaskCoefficients(Objective):
    """The four task-restricted coefficients (eq. 18 on the task rows) of given tolerance directions.

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

    names = TASK_COEFFICIENTS

    def __init__(self, kin: Kinematics, task: tuple, directions: np.ndarray, is_length: np.ndarray) -> None:
        from hyperstat.solver.tolerances.declaration import n_rotation_rows

        self.kin, self.task, self.directions = kin, tuple(task), directions
        self.is_length = np.asarray(is_length, dtype=bool)
        self.n_rot = n_rotation_rows(self.task)

    def values(self, q: np.ndarray) -> dict:
        return _in_blocks(self._values, q)

    def _values(self, q: np.ndarray) -> dict:
        from hyperstat.solver.tolerances.declaration import task_rows

        from hyperstat.solver.tolerances.twist_blocks import nominal_twist_maps

        k_xi, _, pose = nominal_twist_maps(self.kin, q)
        t = task_rows(self.task, pose) @ k_xi @ self.directions
        out = {}
        for kind, cols in (("P", self.is_length), ("R", ~self.is_length)):
            for name, rows in (("delta", t[:, :self.n_rot]), ("epsilon", t[:, self.n_rot:])):
                block = rows[:, :, cols]
                out[f"{name}_g{kind}"] = (np.zeros(len(t)) if block.shape[1] == 0 or block.shape[2] == 0
                                          else np.linalg.svd(block, compute_uv=False)[:, 0])
        return out


def coefficient_at(mechanism: Mechanism, q: np.ndarray, name: str, analysis=None,
                   kinematics: Kinematics | None = None) -> np.ndarray:
    """One accuracy coefficient (eq. 18, :data:`COEFFICIENT_NAMES`) at assembled configurations ``q`` (K, n_q)."""
    if name not in COEFFICIENT_NAMES:
        raise ValueError(f"unknown accuracy coefficient '{name}' (one of {', '.join(COEFFICIENT_NAMES)}).")
    return Coefficients(kinematics or Kinematics(mechanism), analysis, (name,)).values(np.atleast_2d(q))[name]


#: configurations per block of :func:`branch_conditioning` (memory: one closure Jacobian each)
CONDITIONING_BLOCK = 4096
#: at most this many configurations of a sample serve as start points of the structured candidates and as the
#: reference of the conditioning floor (evenly taken: a 100,000-configuration sample was certified again, 600 MiB)
POOL = 2048


def _spread(sample: np.ndarray, n: int) -> np.ndarray:
    """At most ``n`` configurations of ``sample``, evenly taken (all of them when there are fewer)."""
    if len(sample) <= n:
        return sample if isinstance(sample, np.ndarray) else take_rows(sample, np.arange(len(sample)))
    return take_rows(sample, np.linspace(0, len(sample) - 1, n).round().astype(int))


_MEDIANS: dict = {}


def _median_conditioning(kin: Kinematics, q: np.ndarray) -> float:
    """The median of :func:`branch_conditioning` over ``q``, kept for the last few (kinematics, configurations): the
    searches of one command share their sample (issue 39: the hexapod's three searches computed it three times)."""
    from hyperstat.solver.tolerances.spilled import array_digest

    q = np.asarray(q, dtype=float)
    key = (id(kin), q.shape, array_digest(q))
    if key not in _MEDIANS:
        _remember(key, kin, float(np.median(branch_conditioning(kin, q))), _MEDIANS)
    return _MEDIANS[key][1]


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
    out = np.empty(len(q))
    for start in range(0, len(q), CONDITIONING_BLOCK):  # blocks: the closure Jacobians of a whole sample do not fit
        block = q[start:start + CONDITIONING_BLOCK]
        b = kin.scaled_rows(kin.evaluate(block, None, "joints").closure_q)[:, :, m.passive]
        s = np.linalg.svd(b, compute_uv=False)
        out[start:start + CONDITIONING_BLOCK] = s[:, min(b.shape[1:]) - 1] / np.maximum(s[:, 0], 1e-300)
    return out


# ---------------------------------------------------------------------------------------------- the manifold
class _Space:
    """The search space: joints, their bounds and the closure, in dimensionless joint coordinates z = q / scale."""

    def __init__(self, kin: Kinematics, ws: Workspace, loop_only: bool, margin: float) -> None:
        m = kin.mechanism
        self.kin, self.ws, self.m = kin, ws, m
        self.scale = kin.joint_scale
        n = kin.n_q
        self.act = np.zeros(n, dtype=bool)
        self.act[m.actuated] = True
        lo, hi = ws.lower.astype(float).copy(), ws.upper.astype(float).copy()
        rev = np.array([j.type == "R" for j in m.joints])
        self.turn = rev & (hi - lo >= 2 * math.pi - 1e-9) & self.act  # full-turn actuators: no bound
        lo[self.turn], hi[self.turn] = -np.inf, np.inf
        self.exact_lo, self.exact_hi = lo.copy(), hi.copy()
        pas = ~self.act
        step = margin * kin.length_scale / self.scale  # margin in rad, or times the length scale (mm)
        lo[pas] += np.where(np.isfinite(lo[pas]), step[pas] * self.scale[pas], 0.0)
        hi[pas] -= np.where(np.isfinite(hi[pas]), step[pas] * self.scale[pas], 0.0)
        self.lo, self.hi = lo, hi
        self.free = np.ones(n, dtype=bool)
        if loop_only:  # joints of the serial tail do not enter a closure
            probe = kin.evaluate(m.home[None], None, "joints").closure_q[0]
            self.free = np.any(np.abs(probe) > 0, axis=0)
        self.declared = ws.passive_declared if ws.passive_declared is not None else np.zeros(n, dtype=bool)

    def jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scaled residual (K, r) and closure Jacobian per unit of z (K, r, n_q)."""
        st = self.kin.evaluate(q, None, "joints")
        return self.kin.scaled(st.residual), self.kin.scaled_rows(st.closure_q) * self.scale

    def tangent(self, jac: np.ndarray, held: np.ndarray) -> np.ndarray:
        """Orthonormal basis of the tangent space with the ``held`` joints fixed, (n_q, d) (d may be 0)."""
        cols = np.nonzero(~held)[0]
        basis = np.zeros((len(held), 0))
        if not len(cols):
            return basis
        sub = jac[:, cols]
        if sub.shape[0] == 0:
            null = np.eye(len(cols))
        else:
            _, s, vt = np.linalg.svd(sub, full_matrices=True)
            rank = int(np.sum(s > 1e-9 * max(float(s[0]) if s.size else 0.0, 1e-300))) if s.size else 0
            null = vt[rank:].T
        out = np.zeros((len(held), null.shape[1]))
        out[cols] = null
        return out

    def retract(self, q: np.ndarray, held: np.ndarray, iterations: int = 12) -> tuple[np.ndarray, np.ndarray]:
        """Bring configurations back onto the closure by minimum-norm corrections of the joints not held.

        Returns the corrected configurations and whether each converged (scaled residual below 1e-9 of the
        length scale).
        """
        q = np.array(q, dtype=float, copy=True)
        if not len(self.m.closures):
            return q, np.ones(len(q), dtype=bool)
        tol = 1e-9 * self.kin.length_scale
        done = np.zeros(len(q), dtype=bool)
        for _ in range(iterations):
            idx = np.nonzero(~done)[0]
            if not len(idx):
                break
            r, jac = self.jacobian(q[idx])
            small = np.linalg.norm(r, axis=1) <= tol
            done[idx[small]] = True
            idx, r, jac = idx[~small], r[~small], jac[~small]
            if not len(idx):
                break
            jac = jac * (~held[idx])[:, None, :]  # held joints do not move
            dz = -batched_lstsq(jac, r[..., None], damping=1e-14)[..., 0]
            q[idx] += dz * self.scale
        r, _ = self.jacobian(q)
        return q, np.linalg.norm(r, axis=1) <= 10 * tol

    def at_bound(self, q: np.ndarray, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
        """Joints at their lower and upper search bounds (K, n_q) each."""
        z, lo, hi = q / self.scale, self.lo / self.scale, self.hi / self.scale
        return (z <= lo + tol), (z >= hi - tol)


# ---------------------------------------------------------------------------------------------- candidates
_CANDIDATES: dict = {}


def workspace_candidates(kin: Kinematics, workspace: Workspace, sample: np.ndarray, points_per_edge: int = 3,
                         grid: int = 16, max_edges: int = 96, varied: np.ndarray | None = None) -> tuple[np.ndarray, list]:
    """Structured configurations of the workspace: corners, edges and dead centres of the actuated box.

    * corners: every combination of the bounded actuated joints at their bounds (a full-turn
      revolute actuator has no bound: it stays at its home value); at most 2^8;
    * edges: ``points_per_edge`` points inside each edge of the box (at most ``max_edges`` edges,
      taken evenly when there are more);
    * faces: the centre of every face of dimension 2 and more (and of the box), up to 6 bounded
      actuators (3^6 points at most);
    * dead centres: along every edge, and along the whole turn of a full-turn actuator, the
      configurations where the velocity of a passive joint per unit of the moving actuator changes
      sign, bracketed on a grid of ``grid`` points and solved by regula falsi, and the grid points where
      it is zero (below :data:`NOT_MOVING` of the line's largest: round-off, whatever its sign).  A
      joint the line does not move at all has none there.

    Everything is assembled on the workspace's branch by certified continuation
    (:func:`hyperstat.solver.kinematics.continuation.continue_nearest`) from the nearest of the workspace's
    fixed checkpoints (:func:`hyperstat.solver.tolerances.classification.workspace_checkpoints`: a sample of
    seed 0 and the corners of the actuated box), whatever ``sample`` the caller gives: the same candidates for
    every stage and command of one model, computed once per process (issue 39: the report computed them four
    times from four samples, the same configurations to the continuation's tolerance).  ``sample`` (at most
    :data:`POOL` of its configurations, evenly taken) is the start only where no checkpoint assembles.  What
    does not assemble inside the workspace is left out.  ``varied`` (bool per actuated joint) restricts the
    box to the actuators a function depends on (the others stay at home).

    Returns
    -------
    q : ndarray, (C, n_q)
    labels : list of str
        ``corner``, ``edge``, ``face``, ``dead centre of joint 4 along joint 1`` ...
    """
    varied = np.ones(len(kin.mechanism.actuated), dtype=bool) if varied is None else np.asarray(varied, dtype=bool)
    pool = _start_pool(kin, workspace)
    key = _candidates_key(kin, workspace, sample if pool is None else None,
                          (points_per_edge, grid, max_edges, tuple(varied)))
    if key in _CANDIDATES:
        return _CANDIDATES[key][1]
    from hyperstat.solver.kinematics.continuation import continue_nearest

    m = kin.mechanism
    lo, hi = workspace.actuated_box(m)
    home = m.home[m.actuated].astype(float)
    n_a = len(lo)
    rev = np.array([m.joints[i].type == "R" for i in m.actuated])
    turn = rev & (hi - lo >= 2 * math.pi - 1e-9)
    bounded = np.nonzero(~turn & np.isfinite(lo) & np.isfinite(hi) & varied)[0][:8]
    targets, labels, lines = [], [], []  # lines: (start actuated values, axis, from, to, periodic, label)
    if len(bounded):
        bits = (np.arange(2 ** len(bounded))[:, None] >> np.arange(len(bounded))[None, :]) & 1
        corners = np.tile(home, (len(bits), 1))
        corners[:, bounded] = np.where(bits == 1, hi[bounded], lo[bounded])
        targets += list(corners)
        labels += ["corner"] * len(corners)
        edges = [(c, a) for c in corners for a in bounded if c[a] == lo[a]]
        if len(edges) > max_edges:
            edges = [edges[i] for i in np.linspace(0, len(edges) - 1, max_edges).round().astype(int)]
        for c, a in edges:
            for f in (np.arange(points_per_edge) + 1) / (points_per_edge + 1):
                t = c.copy()
                t[a] = lo[a] + f * (hi[a] - lo[a])
                targets.append(t)
                labels.append("edge")
            lines.append((c, a, lo[a], hi[a], False))
        if len(bounded) <= 6:  # the centres of the faces of dimension 2 and more (and of the box)
            digits = (np.arange(3 ** len(bounded))[:, None] // 3 ** np.arange(len(bounded))[None, :]) % 3
            digits = digits[np.sum(digits == 2, axis=1) >= 2]
            faces = np.tile(home, (len(digits), 1))
            faces[:, bounded] = np.choose(digits, [lo[bounded], hi[bounded], 0.5 * (lo[bounded] + hi[bounded])])
            targets += list(faces)
            labels += ["face"] * len(faces)
    for a in np.nonzero(turn & varied)[0]:
        lines.append((home, a, lo[a], lo[a] + 2 * math.pi, True))
    # grids along the lines, assembled with the other targets
    grid_rows = []
    for li, (base, a, s0, s1, periodic) in enumerate(lines):
        s = s0 + (s1 - s0) * np.arange(grid) / grid if periodic else np.linspace(s0, s1, grid)
        pts = np.tile(base, (len(s), 1))
        pts[:, a] = s
        grid_rows.append((li, s, pts))
    all_targets = targets + [p for _, _, pts in grid_rows for p in pts]
    if not all_targets:
        out = (np.zeros((0, kin.n_q)), [])
        _remember(key, kin, out)
        return out
    if pool is None:
        pool = _spread(sample, POOL) if len(sample) else None
    q, cert = continue_nearest(kin, np.array(all_targets), None, m.home, pool=pool, inside=workspace.inside)
    ok = cert.certified
    n_t = len(targets)
    out_q = [q[i] for i in range(n_t) if ok[i]]
    out_l = [labels[i] for i in range(n_t) if ok[i]]
    # dead centres: sign changes of each passive joint's velocity along the lines
    pos = n_t
    brackets = []  # (q_left, q_right, s_left, s_right, v_left, v_right, axis, joint, label)
    resting = []  # (q, axis, joint): grid points where a moving passive joint's velocity is round-off zero
    pas = np.asarray(m.passive)
    for li, s, pts in grid_rows:
        qq, good = q[pos:pos + len(s)], ok[pos:pos + len(s)]
        pos += len(s)
        if good.sum() < 2 or not len(pas):
            continue
        a = lines[li][1]
        vel = _passive_velocity(kin, qq[good], a)
        # a passive joint the line does not move (its velocity round-off zero at every grid point: 1e-20 on the
        # Tripteor's symmetric lines) has no dead centre there: the signs of its round-off are not sign changes
        # and a joint that moves but stands still at a grid point (a dead centre at a bound of the box, the corpus'
        # PRS-3: 4e-19) has its dead centre there, whatever the sign of that round-off
        scaled = np.abs(vel) * (kin.joint_scale[m.actuated[a]] / kin.joint_scale[pas])[None, :]
        at_rest = scaled <= NOT_MOVING * max(float(scaled.max()), 1e-300)
        moves = ~at_rest.all(axis=0)
        ss, qg = s[good], qq[good]
        resting += [(qg[i], a, p) for i, p in zip(*np.nonzero(at_rest & moves[None, :]))]
        periodic = lines[li][4]
        pairs = [(i, i + 1) for i in range(len(ss) - 1)] + ([(len(ss) - 1, 0)] if periodic and good[0] and good[-1]
                                                            else [])
        for i, j in pairs:
            if periodic and j == 0:
                s_j = ss[0] + 2 * math.pi
            else:
                s_j = ss[j]
            if s_j - ss[i] > 2.5 * (s[1] - s[0]):  # not neighbours on the grid (a gap of unassembled points)
                continue
            for p in np.nonzero((vel[i] * vel[j] < 0) & ~at_rest[i] & ~at_rest[j])[0]:
                brackets.append((qg[i], qg[j], ss[i], s_j, vel[i, p], vel[j, p], a, p))
    found = _dead_centres(kin, workspace, brackets) if brackets else []
    if found or resting:
        for (qd, a, p) in found + resting:
            out_q.append(qd)
            out_l.append(f"dead centre of joint {m.joints[pas[p]].name} along joint {m.joints[m.actuated[a]].name}")
    out = (np.array(out_q) if out_q else np.zeros((0, kin.n_q)), out_l)
    _remember(key, kin, out)
    return out


def prepare_searches(kin: Kinematics, workspace: Workspace, sample) -> None:
    """What every search of one sample reads, computed now and kept in this process (before a child is forked).

    The structured candidates of :func:`workspace_candidates` (every actuator varied), the nominal twist maps of
    their blocks of :data:`EVALUATION_BLOCK` configurations (:func:`hyperstat.solver.tolerances.twist_blocks.
    nominal_twist_maps`: what :class:`Coefficients`, :class:`TaskCoefficients` and the bounds' task rows evaluate
    first) and the sample's conditioning median (the searches' floor).  A forked child inherits them instead of
    computing them again (issue 39: the hexapod's refining child computed the candidates' maps that this process
    computed again for the allocation's and the bounds' searches); the same arrays, computed once.
    """
    from hyperstat.solver.tolerances.twist_blocks import nominal_twist_maps

    cq, _ = workspace_candidates(kin, workspace, sample, varied=np.ones(len(kin.mechanism.actuated), dtype=bool))
    for start in range(0, len(cq), EVALUATION_BLOCK):  # the blocks of _in_blocks and of the task rows' blocks
        nominal_twist_maps(kin, cq[start:start + EVALUATION_BLOCK])
    if len(sample):
        _median_conditioning(kin, _spread(sample, POOL))


def remember_candidates(kin: Kinematics, workspace: Workspace, sample: np.ndarray, found: tuple, points_per_edge: int = 3,
                        grid: int = 16, max_edges: int = 96, varied: np.ndarray | None = None) -> None:
    """Keep ``found``, what :func:`workspace_candidates` returned for these arguments in another process (a forked
    child, its arrays handed back bit for bit), as this process' answer to them: the next call reads it."""
    varied = np.ones(len(kin.mechanism.actuated), dtype=bool) if varied is None else np.asarray(varied, dtype=bool)
    key = _candidates_key(kin, workspace, sample if _start_pool(kin, workspace) is None else None,
                          (points_per_edge, grid, max_edges, tuple(varied)))
    _remember(key, kin, (np.asarray(found[0], dtype=float).reshape(-1, kin.n_q), list(found[1])))


#: _candidates_key without a sample or options -> (kinematics, the candidates' start configurations or None); see
#: _start_pool
_POOLS: dict = {}


def _start_pool(kin: Kinematics, workspace: Workspace) -> np.ndarray | None:
    """The configurations the candidates of ``workspace`` are continued from: its fixed checkpoints (a sample of
    seed 0 and the certified corners of the actuated box, :func:`hyperstat.solver.tolerances.classification.
    workspace_checkpoints`; the classification's own when ``workspace`` is the declared one), or None when none
    assembles (the caller's sample is then the start).  Kept per kinematics and workspace (by value)."""
    from hyperstat.solver.tolerances.classification import workspace_checkpoints

    m = kin.mechanism
    key = _candidates_key(kin, workspace, None, ())
    if key in _POOLS:
        return _POOLS[key][1]
    declared = key == _candidates_key(kin, workspace_of(m), None, ())
    sample, corners = workspace_checkpoints(m, kin, None if declared else workspace)
    pool = np.vstack([sample, corners]) if len(sample) + len(corners) else None
    _remember(key, kin, pool, _POOLS)
    return pool


def _candidates_key(kin: Kinematics, workspace: Workspace, sample: np.ndarray | None, options: tuple) -> tuple:
    """What the candidates depend on: the kinematics (the object: it is kept alive with its entry, so its ``id`` is
    not reused), the workspace's bounds by value (every stage builds its own :class:`Workspace` of the same
    declaration) and, when the candidates start from it (:func:`_start_pool`), the sample's bytes."""
    import hashlib

    if sample is not None and not isinstance(sample, SpilledArray):
        sample = np.ascontiguousarray(sample, dtype=float)
    bounds = [np.ascontiguousarray(a, dtype=float) for a in (workspace.lower, workspace.upper)]
    flags = [np.ascontiguousarray(a, dtype=bool) for a in (workspace.passive_declared, workspace.revolute)
             if a is not None]
    digest = hashlib.sha256()
    for a in ([] if sample is None else [sample]) + bounds + flags:
        digest.update(str(a.shape).encode())
        if isinstance(a, SpilledArray):  # read a block at a time: the same bytes
            for _, block in row_blocks(a):
                digest.update(memoryview(np.ascontiguousarray(block).reshape(-1)).cast("B"))
            continue
        digest.update(memoryview(a.reshape(-1)).cast("B"))  # the bytes where they lie (no copy of the sample)
    return (id(kin), workspace.passive_declared is None, workspace.revolute is None, digest.hexdigest(), options)


def _remember(key, kin: Kinematics, value, store: dict | None = None) -> None:
    """Keep ``value`` for the last few keys of ``store`` (default: the candidates of (kinematics, workspace, sample);
    one command uses two or three), with the kinematics its key names by ``id`` (kept alive: the id is not reused)."""
    store = _CANDIDATES if store is None else store
    if len(store) >= 4:
        store.pop(next(iter(store)))
    store[key] = (kin, value)


def _passive_velocity(kin: Kinematics, q: np.ndarray, axis) -> np.ndarray:
    """Velocity of every passive joint per unit of actuated joint ``axis`` (one per row, or one for all), (K, n_p).

    ``-B_p^+ B_a e_a`` (paper 1, eq. 3).
    """
    m = kin.mechanism
    b = kin.scaled_rows(kin.evaluate(q, None, "joints").closure_q)
    cols = m.actuated[np.broadcast_to(np.asarray(axis), (len(q),))]
    return -_pinv_apply(b[:, :, m.passive], b[np.arange(len(q)), :, cols], rcond=1e-10)


def _pinv_apply(a: np.ndarray, v: np.ndarray, rcond: float) -> np.ndarray:
    """``pinv(a[k], rcond) @ v[k]`` for a stack (K, r, n) and (K, r): for square matrices whose singular values all
    lie above ``1e3 rcond`` of the largest (every configuration but a singular one of the passive joints), the
    solution of ``a x = v`` by LU, the same vector to the round-off (the inverse is the pseudo-inverse there; measured
    on the hexapod: 1e-14 relative), at a third of the cost of the SVD with singular vectors (the singular values
    alone decide); the others by :func:`numpy.linalg.pinv` itself."""
    k, r, n = a.shape
    if r != n or k == 0:
        return np.einsum("kpr,kr->kp", np.linalg.pinv(a, rcond=rcond), v)
    sv = np.linalg.svd(a, compute_uv=False)
    regular = sv[:, -1] > 1e3 * rcond * sv[:, 0]
    out = np.empty((k, n))
    if regular.any():
        out[regular] = np.linalg.solve(a[regular], v[regular][..., None])[..., 0]
    if not regular.all():
        out[~regular] = np.einsum("kpr,kr->kp", np.linalg.pinv(a[~regular], rcond=rcond), v[~regular])
    return out


def _dead_centres(kin: Kinematics, ws: Workspace, brackets: list, iterations: int = 30) -> list:
    """Solve each bracketed sign change of a passive joint's velocity (Illinois regula falsi, batched)."""
    m = kin.mechanism
    act = m.actuated
    n = len(brackets)
    ql = np.array([b[0] for b in brackets])
    qr = np.array([b[1] for b in brackets])
    sl = np.array([b[2] for b in brackets], dtype=float)
    sr = np.array([b[3] for b in brackets], dtype=float)
    vl = np.array([b[4] for b in brackets], dtype=float)
    vr = np.array([b[5] for b in brackets], dtype=float)
    axis = np.array([b[6] for b in brackets])
    joint = np.array([b[7] for b in brackets])
    q = ql.copy()
    ok = np.ones(n, dtype=bool)
    width0 = np.abs(sr - sl)
    side = np.zeros(n, dtype=int)
    for _ in range(iterations):
        s = np.where(vr != vl, sr - vr * (sr - sl) / (vr - vl), 0.5 * (sl + sr))
        s = np.clip(s, np.minimum(sl, sr), np.maximum(sl, sr))
        guess = np.where((np.abs(s - sl) <= np.abs(s - sr))[:, None], ql, qr)
        guess[np.arange(n), act[axis]] = s
        res = kin.assemble(guess)
        q = ws.wrapped(res.q)
        ok = res.converged & ws.inside(q)
        v = _passive_velocity(kin, q, axis)[np.arange(n), joint]
        left = v * vl > 0
        ql = np.where(left[:, None], q, ql)
        sl, vl = np.where(left, s, sl), np.where(left, v, vl)
        qr = np.where(left[:, None], qr, q)
        sr, vr = np.where(left, sr, s), np.where(left, vr, v)
        # Illinois: halve the stale end's value when the same side moves twice
        vr = np.where(left & (side == 1), vr / 2, vr)
        vl = np.where(~left & (side == -1), vl / 2, vl)
        side = np.where(left, 1, -1)
        if np.all(np.abs(sr - sl) <= 1e-12 * np.maximum(width0, 1e-300) + 1e-13):
            break
    return [(q[k], int(axis[k]), int(joint[k])) for k in range(n) if ok[k]]


# ---------------------------------------------------------------------------------------------- the search
def search_extremes(kin: Kinematics, objective: Objective, sample: np.ndarray, workspace: Workspace | None = None,
                    kinds: tuple = ("max",), starts: int = 3, iterations: int = 40, names: tuple | None = None,
                    sampled: dict | None = None, candidates: bool = True, margin: float = MARGIN,
                    structured: int = 2) -> dict:
    """Extremes of ``objective`` over the workspace (see the module docstring).

    Parameters
    ----------
    kin : Kinematics
    objective : Objective
        The functions (:class:`Coefficients`, :class:`TaskCoefficients`, or the assembly
        conditions of :mod:`hyperstat.solver.tolerances.clearance`).
    sample : ndarray, (K, n_q)
        Assembled configurations of the workspace (on its branch).
    workspace : Workspace, optional
        Bounds (default: the mechanism's declared workspace).
    kinds : tuple
        ``"max"`` and/or ``"min"``.
    starts : int
        Local searches per extreme from the best separate configurations of the sample, plus
        ``structured`` from the best corners, edge points and face centres each and one from the best
        dead centre.
    iterations : int
        Largest number of iterations of a search path.
    names : tuple, optional
        The functions to extremise (default: all of ``objective.names``).
    sampled : dict, optional
        The functions' values at ``sample`` if already computed.
    candidates : bool
        Add the corners, edges and dead centres of :func:`workspace_candidates` to the sample.
    margin : float
        Passive bounds are moved inwards by this much (rad, or times the length scale in mm).
    structured : int
        Local searches from the best corners, edge points and face centres (each).

    Returns
    -------
    dict
        ``(name, kind)`` -> :class:`Extreme` (functions identically zero are left out).
    """
    m = kin.mechanism
    ws = workspace or workspace_of(m)
    space = _Space(kin, ws, objective.loop_only, margin)
    names = tuple(names or objective.names)
    if isinstance(sample, SpilledArray) and len(sample):  # read a block at a time (issue 39: memory)
        out, paths, owner, sense, origin, best_of = _streamed_starts(kin, space, objective, sample, ws, names, kinds,
                                                                     starts, sampled, candidates, structured)
        return _searched(space, objective, sample, out, paths, owner, sense, origin, best_of, kinds, iterations)
    sample = np.atleast_2d(np.asarray(sample, dtype=float))
    values = {n: np.asarray(v) for n, v in (sampled or objective.values(sample)).items() if n in names} \
        if len(sample) else {n: np.zeros(0) for n in names}
    pool_q, extra = _Pool(sample, np.zeros((0, kin.n_q)), []), {}
    if candidates and len(sample):
        cq, cl = workspace_candidates(kin, ws, sample, varied=space.free[m.actuated])
        if len(cq):
            cv = objective.values(cq)
            pool_q = _Pool(sample, cq, cl)
            extra = {n: cv[n] for n in names}
    pool_label = pool_q.label

    def pooled(name: str) -> np.ndarray | None:
        """The function's values over the pool (the sample's, then the candidates'), joined when needed: one
        function at a time (a copy of every function's values over a large sample at once is 8 bytes each)."""
        v = values.get(name)
        return v if v is None or name not in extra else np.r_[v, extra[name]]

    out: dict = {}
    paths, owner, sense, origin, best_of = [], [], [], [], {}
    scale_act = space.scale[m.actuated]
    spread_box = pool_q.extent(m.actuated, scale_act)  # the pool's extent in z, without a copy of its columns
    spread_box = np.where(spread_box > 0, spread_box, 1.0)

    def z_act(i) -> np.ndarray:
        """Row ``i`` of the pool's actuated columns in z (the same division as a whole column's)."""
        return pool_q.row(i)[m.actuated] / scale_act

    def of_category(order: np.ndarray, category: str) -> np.ndarray:
        """The rows of ``order`` whose label starts with ``category``, in order (the sample's rows are all
        'sample'; no mask over the pool: issue 39)."""
        n_s = len(pool_q.sample)
        if category == "sample":
            return order[order < n_s]
        rest = order[order >= n_s]
        return rest[pool_q.extra_kind(category)[rest - n_s]]
    for name in names:
        v = pooled(name)
        if v is None or len(v) == 0:
            continue
        finite = np.isfinite(v)
        if not finite.any():
            continue
        if float(np.max(np.abs(v[finite]))) <= 0:
            continue
        for kind in kinds:
            sign = 1.0 if kind == "max" else -1.0
            sv = np.where(finite, sign * v, -np.inf)
            best = int(np.argmax(sv))
            best_of[(name, kind)] = (float(v[best]), pool_q[best], pool_label(best))
            spread = float(np.max(v[finite]) - np.min(v[finite]))
            if spread <= 1e-9 * max(1.0, abs(float(v[best]))):
                out[(name, kind)] = _describe(space, name, kind, float(v[best]), float(v[best]), pool_q[best], 0.0, 0, 0,
                                              0, f"varies by {spread:.2g} over {int(finite.sum())} configurations",
                                              pool_label(best), location="constant")
                continue
            chosen: list = []
            # equal values (to the last bit: a coefficient's maximum is often reached on a whole set) in row order, not
            # in the order of numpy's unstable sort (which depends on the whole array and on the machine's sort
            # kernel): the starts do not depend on how the sample is held (issue 39: read block by block)
            order = np.argsort(-sv, kind="stable")
            for category in ("sample", "corner", "edge", "face", "dead centre"):  # the best separate ones of each kind
                limit = starts if category == "sample" else (1 if category == "dead centre" else structured)
                taken = 0
                for i in of_category(order, category):  # the configurations of this kind, best first
                    if taken == limit or not np.isfinite(sv[i]):
                        break
                    z_i = z_act(i)
                    if all(np.linalg.norm((z_i - z_act(j)) / spread_box) > 0.05 for j in chosen):
                        chosen.append(int(i))
                        taken += 1
            for i in chosen:
                paths.append(pool_q[i].copy())
                owner.append(name)
                sense.append(sign)
                origin.append(pool_label(i))
    return _searched(space, objective, sample, out, paths, owner, sense, origin, best_of, kinds, iterations)


def _searched(space: _Space, objective: Objective, sample, out: dict, paths: list, owner: list, sense: list,
              origin: list, best_of: dict, kinds: tuple, iterations: int) -> dict:
    """The searches from the chosen starts and their conclusions, into ``out`` (the end of :func:`search_extremes`;
    ``best_of``: (function, kind) -> the best candidate's value, configuration and label)."""
    if not paths:
        return out
    floor_at = CONDITIONING_FLOOR * _median_conditioning(space.kin, _spread(sample, POOL)) if len(sample) else 0.0
    result = _ascend(space, objective, np.array(paths), owner, np.array(sense), iterations, floor_at)
    _polish(space, objective, result, owner, np.array(sense))
    for name in dict.fromkeys(owner):
        for kind in kinds:
            sign = 1.0 if kind == "max" else -1.0
            ks = [k for k, (n, s) in enumerate(zip(owner, sense)) if n == name and s == sign]
            if not ks:
                continue
            value, q_best, label = best_of[(name, kind)]
            out[(name, kind)] = _conclude(space, objective, name, kind, sign, value, q_best, label, result, ks,
                                          [origin[k] for k in ks], iterations, sample)
    return out


#: the best configurations of a sample kept per function and kind by the streamed search (:func:`_streamed_starts`);
#: more are gathered (a second pass) only when the separate starts are not all among them
STREAMED_TOP = 4096


def _top(keep_v: np.ndarray, keep_i: np.ndarray, v: np.ndarray, i: np.ndarray, m: int) -> tuple:
    """The ``m`` largest of the values ``keep_v`` and ``v`` (with their row numbers), largest first, equal values
    by row number."""
    if len(v) > m:
        part = np.argpartition(-v, m - 1)[:m]
        cut = v[part].min()
        take = v >= cut  # every row equal to the m-th value too (the order among equals is by row number)
        v, i = v[take], i[take]
    v, i = np.r_[keep_v, v], np.r_[keep_i, i]
    order = np.lexsort((i, -v))[:m]
    return v[order], i[order]


def _streamed_starts(kin: Kinematics, space: _Space, objective: Objective, sample, ws: Workspace, names: tuple,
                     kinds: tuple, starts: int, sampled: dict | None, candidates: bool, structured: int) -> tuple:
    """The start selection of :func:`search_extremes` from a sample read a block at a time (a
    :class:`~hyperstat.solver.tolerances.spilled.SpilledArray`): per function and kind the best
    :data:`STREAMED_TOP` configurations, the extent of the actuated columns and the best candidate are kept instead of
    every configuration's value, its sort order and masks (issue 39: memory independent of the count).

    The same starts as the whole-array path: the best separate configurations of the sample, best first (equal
    values by row number, as the whole-array path's stable sort), walked until ``starts`` are taken (a second pass
    keeps more of them when the walk runs past the kept ones); then the structured candidates in the same order.
    """
    m = kin.mechanism
    values_given = sampled is not None
    names = tuple(n for n in names if not values_given or n in sampled)
    extra, cq, c_labels = {}, np.zeros((0, kin.n_q)), []
    if candidates:
        cq, c_labels = workspace_candidates(kin, ws, sample, varied=space.free[m.actuated])
        if len(cq):
            cv = objective.values(cq)
            extra = {n: np.asarray(cv[n], dtype=float) for n in names}
    n_s = len(sample)
    act = np.asarray(m.actuated)
    scale_act = space.scale[m.actuated]

    def reduce(top_m: int, wanted: set | None = None) -> dict:
        """One pass over the sample: per function its finite count, extremes and largest magnitude, per kind the
        first best row and the ``top_m`` best rows; and the actuated columns' extremes."""
        st = {"hi": np.full(len(act), -np.inf), "lo": np.full(len(act), np.inf), "nan": np.zeros(len(act), bool)}
        for n in names:
            st[n] = {"count": 0, "vmax": -np.inf, "vmin": np.inf, "amax": 0.0}
            for kind in kinds:
                st[(n, kind)] = {"best": -np.inf, "at": -1, "top_v": np.zeros(0), "top_i": np.zeros(0, np.int64)}
        for start, qb in row_blocks(sample):
            cols = qb[:, act]
            st["nan"] |= np.isnan(cols).any(axis=0)  # numpy's max and ptp propagate NaN (below)
            st["hi"], st["lo"] = np.fmax(st["hi"], cols.max(axis=0)), np.fmin(st["lo"], cols.min(axis=0))
            vals = {n: np.asarray(sampled[n][start:start + len(qb)], dtype=float) for n in names} if values_given \
                else objective.values(qb)
            rows = np.arange(start, start + len(qb), dtype=np.int64)
            for n in names:
                v = vals[n]
                finite = np.isfinite(v)
                s = st[n]
                if finite.any():
                    vf = v[finite]
                    s["count"] += int(finite.sum())
                    s["vmax"], s["vmin"] = max(s["vmax"], float(vf.max())), min(s["vmin"], float(vf.min()))
                    s["amax"] = max(s["amax"], float(np.max(np.abs(vf))))
                for kind in kinds:
                    if wanted is not None and (n, kind) not in wanted:
                        continue
                    sign = 1.0 if kind == "max" else -1.0
                    k = st[(n, kind)]
                    sv = sign * v[finite]
                    if not len(sv):
                        continue
                    j = int(np.argmax(sv))
                    if sv[j] > k["best"]:
                        k["best"], k["at"] = float(sv[j]), int(rows[finite][j])
                    k["top_v"], k["top_i"] = _top(k["top_v"], k["top_i"], sv, rows[finite], top_m)
        return st

    st = reduce(STREAMED_TOP)
    # the pool's extent in z (the sample's and the candidates' actuated columns), as the whole-array path
    hi, lo = st["hi"], st["lo"]
    if len(cq):
        hi, lo = np.fmax(hi, cq[:, act].max(axis=0)), np.fmin(lo, cq[:, act].min(axis=0))
        nan = st["nan"] | np.isnan(cq[:, act]).any(axis=0)
    else:
        nan = st["nan"]
    if np.all(scale_act > 0):
        spread_box = np.where(nan, np.nan, hi / scale_act - lo / scale_act)
    else:
        spread_box = np.ptp(np.r_[take_rows(sample, np.arange(n_s))[:, act], cq[:, act]] / scale_act, axis=0)
    spread_box = np.where(spread_box > 0, spread_box, 1.0)
    is_kind = {c: np.array([lb.startswith(c) for lb in c_labels], dtype=bool) for c in
               ("corner", "edge", "face", "dead centre")}
    out: dict = {}
    paths, owner, sense, origin, best_of = [], [], [], [], {}
    for name in names:
        s = st[name]
        ev = extra.get(name, np.zeros(0))
        ef = np.isfinite(ev)
        count = s["count"] + int(ef.sum())
        if not count:
            continue
        vmax = max(s["vmax"], float(ev[ef].max()) if ef.any() else -np.inf)
        vmin = min(s["vmin"], float(ev[ef].min()) if ef.any() else np.inf)
        if max(s["amax"], float(np.max(np.abs(ev[ef]))) if ef.any() else 0.0) <= 0:
            continue
        for kind in kinds:
            sign = 1.0 if kind == "max" else -1.0
            k = st[(name, kind)]
            esv = np.where(ef, sign * ev, -np.inf)
            e_best = int(np.argmax(esv)) if len(esv) else -1
            if k["at"] >= 0 and (e_best < 0 or not esv[e_best] > k["best"]):  # the first best of the pool
                value, q_best, label = sign * k["best"], take_rows(sample, [k["at"]])[0], "sample"
            else:
                value, q_best, label = float(ev[e_best]), cq[e_best].copy(), c_labels[e_best]
            best_of[(name, kind)] = (float(value), q_best, label)
            spread = float(vmax - vmin)
            if spread <= 1e-9 * max(1.0, abs(float(value))):
                out[(name, kind)] = _describe(space, name, kind, float(value), float(value), q_best, 0.0, 0, 0, 0,
                                              f"varies by {spread:.2g} over {count} configurations", label,
                                              location="constant")
                continue
            chosen_z: list = []  # the starts taken so far (of every category), in z

            def walk(rows_q: np.ndarray, limit: int) -> list:
                """The positions in ``rows_q`` (best first) of the next separate starts, at most ``limit``."""
                taken = []
                for pos, qi in enumerate(rows_q):
                    if len(taken) == limit:
                        break
                    z_i = qi[m.actuated] / scale_act
                    if all(np.linalg.norm((z_i - z_j) / spread_box) > 0.05 for z_j in chosen_z):
                        chosen_z.append(z_i)
                        taken.append(pos)
                return taken

            while True:  # the sample's best separate rows: every finite one is among the kept ones, or enough were
                rows_q = take_rows(sample, k["top_i"])
                taken = walk(rows_q, starts)
                if len(taken) == starts or len(k["top_i"]) >= s["count"]:
                    break
                del chosen_z[:]  # a second pass keeping more of the best rows
                k.update(reduce(8 * len(k["top_i"]), {(name, kind)})[(name, kind)])
            chosen = [(rows_q[p].copy(), "sample") for p in taken]
            c_order = np.lexsort((np.arange(len(esv)), -esv)) if len(esv) else np.zeros(0, int)
            for category in ("corner", "edge", "face", "dead centre"):
                limit = 1 if category == "dead centre" else structured
                rows_c = [int(i) for i in c_order if is_kind[category][i] and np.isfinite(esv[i])]
                for p in walk(cq[rows_c] if rows_c else np.zeros((0, kin.n_q)), limit):
                    chosen.append((cq[rows_c[p]].copy(), c_labels[rows_c[p]]))
            for q_i, label in chosen:
                paths.append(q_i)
                owner.append(name)
                sense.append(sign)
                origin.append(label)
    return out, paths, owner, sense, origin, best_of


class _Pool:
    """The sample followed by the structured candidates and their labels, read row by row without copying the
    sample (issue 39: a stacked copy of a 683,000-configuration sample is 82 MiB per search, and its list of labels
    and their kinds 24 MiB more)."""

    def __init__(self, sample: np.ndarray, extra: np.ndarray, extra_labels: list) -> None:
        self.sample, self.extra, self.extra_labels = sample, extra, list(extra_labels)

    def label(self, i) -> str:
        """``sample`` for a row of the sample, else the candidate's label (``corner``, ``edge`` ...)."""
        i = int(i)
        return "sample" if i < len(self.sample) else self.extra_labels[i - len(self.sample)]

    def __len__(self) -> int:
        return len(self.sample) + len(self.extra)

    def __getitem__(self, i) -> np.ndarray:
        i = int(i)
        return (self.sample[i] if i < len(self.sample) else self.extra[i - len(self.sample)]).copy()

    def row(self, i) -> np.ndarray:
        """Row ``i`` (a view, not a copy)."""
        i = int(i)
        return self.sample[i] if i < len(self.sample) else self.extra[i - len(self.sample)]

    def extra_kind(self, category: str) -> np.ndarray:
        """Whether each candidate's label starts with ``category`` (bool per candidate)."""
        return np.array([lb.startswith(category) for lb in self.extra_labels], dtype=bool)

    def extent(self, cols, scale: np.ndarray) -> np.ndarray:
        """``numpy.ptp`` over every row of ``columns(cols, scale)``, column by column without that copy: the largest
        and smallest of ``q / s`` are those of ``q`` divided by ``s > 0`` (a correctly rounded division is monotonic)."""
        if not len(self):
            return np.zeros(len(cols))
        if not np.all(scale > 0):
            return np.ptp(self.columns(cols, scale), axis=0)
        parts = [p for p in (self.sample, self.extra) if len(p)]
        out = np.empty(len(cols))
        for k, (c, s) in enumerate(zip(cols, scale)):
            highs, lows = [float(np.max(p[:, c])) for p in parts], [float(np.min(p[:, c])) for p in parts]
            nan = any(math.isnan(h) for h in highs)  # numpy's max and ptp propagate NaN
            out[k] = float("nan") if nan else max(highs) / s - min(lows) / s
        return out

    def columns(self, cols, scale: np.ndarray) -> np.ndarray:
        """The columns ``cols`` of every row divided by ``scale``, (len, len(cols)), filled in place."""
        out = np.empty((len(self), len(cols)))
        out[:len(self.sample)] = self.sample[:, cols]
        out[len(self.sample):] = self.extra[:, cols]
        out /= scale
        return out


@dataclass
class _Paths:
    q: np.ndarray
    value: np.ndarray
    gain: np.ndarray
    done: np.ndarray
    iterations: np.ndarray
    floor: np.ndarray
    start: np.ndarray
    kink: np.ndarray | None = None


def _ascend(space: _Space, objective: Objective, q: np.ndarray, owner: list, sense: np.ndarray,
            iterations: int, floor_at: float, h: float = 1e-6) -> _Paths:
    """Batched projected-gradient search on the configuration manifold (see the module docstring).

    Conjugate directions (Polak-Ribiere, restarted when not an ascent direction), the step from a
    quadratic model along the direction (its slope and the trial value); a refused step is retried
    shorter along the same direction before a new gradient is taken.  ``floor_at``: the conditioning
    below which a step is refused away from the declared passive bounds.
    """
    kin, m = space.kin, space.m
    p, n = len(q), kin.n_q
    start = q.copy()
    val = sense * objective.pick(q, owner)
    step = np.full(p, 0.05)
    cap = np.full(p, np.inf)  # half the last refused step: a trust radius near a kink, where a model overshoots
    kink = np.zeros(p, dtype=bool)
    gain = np.full(p, np.nan)
    active = np.isfinite(val)
    done = ~active
    iters = np.zeros(p, dtype=int)
    floor = np.zeros(p, dtype=bool)
    scale = space.scale
    lo, hi = space.lo / scale, space.hi / scale
    near = 1e-2 * kin.length_scale / scale  # "near a declared passive bound", in z units
    grad = np.zeros((p, n))
    direction = np.zeros((p, n))
    slope = np.zeros(p)
    held = np.zeros((p, n), dtype=bool)
    stale = np.ones(p, dtype=bool)  # a new gradient is needed
    pas = np.asarray(m.passive)
    loops = bool(len(m.closures) and len(pas))
    # fold detection: U, V^T of B_p = U S V^T at the current point (r = min(rows, columns): B_p may be wide, with
    # an idle motion of the passive joints such as an RSSR's rod spin); a step keeps det(U^T B_p V) > 0
    rank = min(6 * len(m.closures), len(pas))
    frame = np.zeros((p, 6 * len(m.closures), rank))
    rows = np.zeros((p, rank, len(pas)))
    for _ in range(iterations):
        idx = np.nonzero(active)[0]
        if not len(idx):
            break
        fresh = idx[stale[idx]]
        if len(fresh):
            _, jac = space.jacobian(q[fresh])
            if loops:
                u_, _, vt_ = np.linalg.svd(jac[:, :, pas], full_matrices=False)
                frame[fresh], rows[fresh] = u_, vt_
            low, high = space.at_bound(q[fresh])
            bases = [space.tangent(jac[i], ~space.free) for i in range(len(fresh))]
            pert = [q[k] + h * t[:, j] * scale for k, t in zip(fresh, bases) for j in range(t.shape[1])]
            who = [owner[k] for k, t in zip(fresh, bases) for _j in range(t.shape[1])]
            fp = objective.pick(np.array(pert), who) if pert else np.zeros(0)
            pos = 0
            for i, k in enumerate(fresh):
                t = bases[i]
                d = t.shape[1]
                g_new = t @ ((sense[k] * fp[pos:pos + d] - val[k]) / h) if d else np.zeros(n)
                pos += d
                hold = ~space.free.copy()
                for _rep in range(n):  # hold the joints at a bound the gradient pushes out of
                    push = ((low[i] & (g_new < 0)) | (high[i] & (g_new > 0))) & ~hold
                    if not push.any():
                        break
                    hold |= push
                    t = space.tangent(jac[i], hold)
                    g_new = t @ (t.T @ g_new)
                old = grad[k]
                carried = t @ (t.T @ direction[k]) if d else np.zeros(n)
                beta = max(0.0, float(g_new @ (g_new - old)) / float(old @ old)) if float(old @ old) > 0 else 0.0
                dirn = g_new + beta * carried
                if float(dirn @ g_new) <= 0:
                    dirn = g_new
                grad[k], direction[k], held[k] = g_new, dirn, hold
                norm = float(np.linalg.norm(dirn))
                slope[k] = float(g_new @ dirn) / norm if norm > 0 else 0.0
                stale[k] = False
                if not np.isfinite(norm) or norm <= 0 or slope[k] <= 1e-14 * max(abs(val[k]), 1e-300):
                    active[k], done[k] = False, True
                    gain[k] = 0.0  # a stationary point within the bounds: no ascent direction left
        kk = np.nonzero(active)[0]
        if not len(kk):
            break
        unit = direction[kk] / np.linalg.norm(direction[kk], axis=1, keepdims=True)
        z = q[kk] / scale + step[kk, None] * unit
        clipped = (z < lo) | (z > hi)
        pred = np.clip(z, lo, hi) * scale
        cand, conv = space.retract(pred, held[kk] | clipped)
        corr = np.linalg.norm((cand - pred) / scale, axis=1)
        move = np.linalg.norm((pred - q[kk]) / scale, axis=1)
        zc = cand / scale
        inside = np.all((zc >= lo - 1e-9) & (zc <= hi + 1e-9), axis=1)
        ok = conv & inside & (corr <= 0.1 * move + 1e-9)
        if ok.any() and loops:
            cond = np.ones(len(kk))
            cond[ok] = branch_conditioning(kin, cand[ok])
            # a step must not cross a fold of the actuated projection (a singularity of B_p between its ends,
            # where the manifold passes to another assembly branch): det(U^T B_p V) stays positive (it is
            # det(S) > 0 at the step's start), U and V the range and row space of B_p there
            _, jac_new = space.jacobian(cand[ok])
            u = frame[kk[ok]]
            turn = np.sign(np.linalg.det(np.swapaxes(u, 1, 2) @ jac_new[:, :, pas] @ np.swapaxes(rows[kk[ok]], 1, 2)))
            keep = np.ones(len(kk), dtype=bool)
            keep[np.nonzero(ok)[0]] = turn > 0
            ok &= keep
            close = np.any(space.declared[None, :] & ((np.abs(zc - space.exact_lo / scale) <= near)
                                                      | (np.abs(space.exact_hi / scale - zc) <= near)), axis=1)
            edge = ok & (cond < floor_at) & ~close
            floor[kk[edge]] = True
            ok &= ~edge
        v_new = np.full(len(kk), -np.inf)
        if ok.any():
            v_new[ok] = sense[kk[ok]] * objective.pick(cand[ok], [owner[k] for k in kk[ok]])
        for i, k in enumerate(kk):
            iters[k] += 1
            s = step[k]
            # quadratic model along the direction: f(s) = f0 + slope s - c s^2 / 2
            curv = 2.0 * (val[k] + slope[k] * s - v_new[i]) / (s * s) if np.isfinite(v_new[i]) else float("nan")
            best = slope[k] / curv if np.isfinite(curv) and curv > 0 else float("nan")
            if ok[i] and v_new[i] > val[k]:
                gain[k] = v_new[i] - val[k]
                q[k], val[k] = cand[i], v_new[i]
                step[k] = min(float(np.clip(best, 0.5 * s, 4.0 * s)) if np.isfinite(best) else 2.0 * s, 0.25, cap[k])
                cap[k] = min(2.0 * cap[k], np.inf)
                stale[k] = True
                if gain[k] <= 1e-12 * abs(val[k]):
                    active[k], done[k] = False, True
            else:
                step[k] = float(np.clip(best, 0.05 * s, 0.5 * s)) if ok[i] and np.isfinite(best) else 0.25 * s
                if ok[i]:  # a step the function refused (not the bounds or the branch): it bounds the next ones
                    cap[k] = 0.5 * s
            if step[k] < 1e-8 and active[k]:  # no step down to 1e-8 improves: what a shorter one could gain
                active[k], done[k] = False, True
                kink[k] = slope[k] > 1e-8 * max(abs(val[k]), 1e-300)  # a slope left: a kink or a ridge
                gain[k] = min(gain[k], slope[k] * step[k]) if np.isfinite(gain[k]) else slope[k] * step[k]
    return _Paths(q, sense * val, gain, done, iters, floor, start, kink)


def _polish(space: _Space, objective: Objective, res: "_Paths", owner: list, sense: np.ndarray,
            size: float = 1e-3, iterations: int = 60) -> None:
    """Derivative-free polish of the best path of each function that stopped on a kink or a ridge (in place).

    Where the function is the largest (or smallest) of smooth pieces, the extreme may lie on a ridge
    where two of them are equal; a gradient method zig-zags across it and stops short.  There the
    search continues by Nelder-Mead (its simplex adapts to a narrow valley) in the tangent coordinates
    of the manifold at the path's end (the joints at a bound held), every point brought back onto the
    closure; the simplices of all the paths advance together, one batched evaluation per phase
    (reflection; expansion or contraction; shrink).
    """
    best: dict = {}
    for k, (name, sg) in enumerate(zip(owner, sense)):
        if np.isfinite(res.value[k]) and ((name, sg) not in best or sg * res.value[k] > sg * res.value[best[(name, sg)]]):
            best[(name, sg)] = k
    scale = space.scale
    lo, hi = space.lo / scale, space.hi / scale
    paths = []  # (k, q0, tangent basis, held)
    for k in best.values():
        if res.kink is None or not res.kink[k]:
            continue
        q0 = res.q[k].copy()
        _, jac = space.jacobian(q0[None])
        low, high = space.at_bound(q0[None])
        held = ~space.free | low[0] | high[0]
        t = space.tangent(jac[0], held)
        if t.shape[1]:
            paths.append((k, q0, t, held))
    if not paths:
        return
    found = {k: (np.inf, None) for k, *_ in paths}  # the best (value to minimise, configuration) of each path

    def evaluate(points: list) -> np.ndarray:
        """``-sense * f`` at the tangent coordinates ``points[i] = (path index, c)``; inf outside or unclosed."""
        out = np.full(len(points), np.inf)
        zs, helds, which = [], [], []
        for i, (j, c) in enumerate(points):
            k, q0, t, held = paths[j]
            z = q0 / scale + t @ c
            if np.all(z >= lo - 1e-12) and np.all(z <= hi + 1e-12):
                zs.append(z * scale)
                helds.append(held)
                which.append(i)
        if not which:
            return out
        qq, ok = space.retract(np.array(zs), np.array(helds))
        zq = qq / scale
        ok &= np.all((zq >= lo - 1e-9) & (zq <= hi + 1e-9), axis=1)
        if ok.any():
            rows = np.nonzero(ok)[0]
            ks = [paths[points[which[r]][0]][0] for r in rows]
            vals = -sense[ks] * objective.pick(qq[rows], [owner[k] for k in ks])
            for r, v in zip(rows, vals):
                i = which[r]
                out[i] = v
                k = paths[points[i][0]][0]
                if v < found[k][0]:
                    found[k] = (float(v), qq[r].copy())
        return out

    simplices = [np.vstack([np.zeros(t.shape[1]), size * np.eye(t.shape[1])]) for _, _, t, _ in paths]
    flat = evaluate([(j, x) for j, sx in enumerate(simplices) for x in sx])
    values, pos = [], 0
    for sx in simplices:
        values.append(flat[pos:pos + len(sx)])
        pos += len(sx)
    live = list(range(len(paths)))
    for _ in range(iterations):
        live = [j for j in live if np.ptp(values[j]) > 1e-15 * max(abs(values[j].min()), 1e-300)
                and np.max(np.linalg.norm(simplices[j][1:] - simplices[j][0], axis=1)) > 1e-10]
        if not live:
            break
        for j in live:
            order = np.argsort(values[j])
            simplices[j], values[j] = simplices[j][order], values[j][order]
        cents = {j: simplices[j][:-1].mean(axis=0) for j in live}
        refl = {j: 2 * cents[j] - simplices[j][-1] for j in live}
        f_r = dict(zip(live, evaluate([(j, refl[j]) for j in live])))
        second, shrink = [], []
        for j in live:
            f, x = values[j], simplices[j]
            if f_r[j] < f[0]:
                second.append((j, "expand", cents[j] + 2 * (refl[j] - cents[j])))
            elif f_r[j] < f[-2]:
                x[-1], f[-1] = refl[j], f_r[j]
            elif f_r[j] < f[-1]:
                second.append((j, "outside", cents[j] + 0.5 * (refl[j] - cents[j])))
            else:
                second.append((j, "inside", cents[j] - 0.5 * (cents[j] - x[-1])))
        f_s = evaluate([(j, c) for j, _, c in second]) if second else []
        for (j, kind, c), fc in zip(second, f_s):
            f, x = values[j], simplices[j]
            if kind == "expand":
                x[-1], f[-1] = (c, fc) if fc < f_r[j] else (refl[j], f_r[j])
            elif fc <= (f_r[j] if kind == "outside" else f[-1]):
                x[-1], f[-1] = c, fc
            else:
                shrink.append(j)
        if shrink:
            pts = [(j, simplices[j][0] + 0.5 * (x - simplices[j][0])) for j in shrink for x in simplices[j][1:]]
            f_h = evaluate(pts)
            pos = 0
            for j in shrink:
                n = len(simplices[j]) - 1
                simplices[j][1:] = np.array([c for _, c in pts[pos:pos + n]])
                values[j][1:] = f_h[pos:pos + n]
                pos += n
    for k, (value, q) in found.items():
        gain = -value - sense[k] * res.value[k]  # value minimised is -sense f
        if q is not None and gain > 0:
            res.gain[k] = gain
            res.q[k], res.value[k] = q, -value * sense[k]


def _conclude(space: _Space, objective: Objective, name: str, kind: str, sign: float, sampled: float,
              q_sampled: np.ndarray, label_sampled: str, res: _Paths, ks: list, origins: list, iterations: int,
              sample: np.ndarray) -> Extreme:
    kin, m = space.kin, space.m
    vals = res.value[ks]
    ranked = [i for i in np.argsort(-sign * vals) if np.isfinite(vals[i])]
    # the best path whose end is on the branch of its start (a certified continuation back lands on it)
    top_local = next((i for i in ranked if _same_branch(space, res.q[ks[i]], res.start[ks[i]])), None)
    if top_local is None:
        return _describe(space, name, kind, sampled, sampled, q_sampled, float("nan"), len(ks), 0, 0,
                         "no search path stayed on the branch of its start: the best candidate is reported",
                         label_sampled)
    top = ks[top_local]
    value, q = float(res.value[top]), res.q[top].copy()
    if not np.isfinite(value) or sign * value < sign * sampled:  # never less extreme than the candidates
        return _describe(space, name, kind, sampled, sampled, q_sampled, float("nan"), len(ks), 0, 0,
                         "the search did not improve on the best candidate", label_sampled)
    tol = float(res.gain[top]) if np.isfinite(res.gain[top]) else (0.0 if res.done[top] else float("nan"))
    evidence = [f"searched from {len(ks)} candidates ({', '.join(dict.fromkeys(origins))}): projected gradient on "
                "the configuration manifold within the workspace bounds"]
    supremum = False
    singular = bool(branch_conditioning(kin, q[None])[0] < SINGULAR) if len(m.passive) and len(m.closures) else False
    low, high = space.at_bound(q[None])
    pas_active = np.nonzero((low[0] | high[0]) & ~space.act)[0]
    if len(pas_active) and singular:
        seq = _edge_sequence(space, objective, name, q, int(pas_active[0]), bool(low[0, pas_active[0]]))
        if seq is not None:
            margins, fs, q_last = seq
            gaps = np.abs(np.diff(fs))
            finite = np.all(np.isfinite(fs))
            # order of convergence from the sequence itself (ratio of successive changes, margins a decade apart)
            ratio = gaps[-1] / max(gaps[-2], 1e-300) if finite and len(gaps) >= 2 else float("nan")
            if finite and sign * fs[-1] >= sign * value - 1e-12 * abs(value) and ratio < 0.5:
                # the geometric tail of the sequence, and at least the change since the margin the search stopped
                # at (the other coordinates were optimised there, not at the edge)
                remaining = max(gaps[-1] * ratio / (1.0 - ratio), abs(fs[-1] - value))
                value, q = float(fs[-1]), q_last
                tol = max(remaining, 1e-15 * abs(value))
                supremum = True
                evidence.append(f"a supremum at the singular edge of the branch (joint {m.joints[pas_active[0]].name} "
                                f"at its declared bound): values {', '.join(f'{v:.10g}' for v in fs)} at "
                                f"{', '.join(f'{g:g}' for g in margins)} from the edge, one batch from the one search "
                                f"path; remaining gap estimated at {tol:.2g} (successive changes shrink by "
                                f"{ratio:.2g} per decade)")
            else:
                evidence.append("at the singular edge of the branch; the values approaching it do not converge "
                                f"({', '.join(f'{v:.6g}' for v in fs)}): the value holds a margin {MARGIN:g} inside")
    elif len(pas_active):
        evidence.append("attained on a passive joint's workspace bound (moved in by the margin)")
    agreeing = int(np.sum(np.abs(vals - value) <= max(tol if math.isfinite(tol) else 0.0, 1e-7 * max(1.0, abs(value)))))
    if res.floor[top]:
        evidence.append(f"bounded by a singular edge inside the workspace: steps where the passive Jacobian's relative "
                        f"conditioning falls below {CONDITIONING_FLOOR:g} of its median were refused (a coefficient "
                        "can grow without bound there; the value holds on the well-conditioned part)")
    if not res.done[top]:
        evidence.append(f"stopped at the iteration limit ({iterations}) with a last accepted gain of {tol:.2g} "
                        "(the stated tolerance): a value reached, not a certified extreme")
    evidence.append(f"{agreeing} of {len(ks)} starts agree")
    return _describe(space, name, kind, value, sampled, q, tol, len(ks), agreeing, int(res.iterations[top]),
                     "; ".join(evidence), origins[top_local], supremum=supremum, singular=singular)


def _edge_sequence(space: _Space, objective: Objective, name: str, q: np.ndarray, joint: int, lower: bool):
    """The function at margins :data:`EDGE_MARGINS` from a singular passive bound, in one batch."""
    unit = space.kin.length_scale if space.m.joints[joint].type == "P" else 1.0
    edge = space.exact_lo[joint] if lower else space.exact_hi[joint]
    margins = np.array(EDGE_MARGINS)
    pts = np.repeat(q[None], len(margins), axis=0)
    pts[:, joint] = edge + (1 if lower else -1) * margins * unit
    held = ~space.free.copy()
    held[joint] = True
    low, high = space.at_bound(q[None])
    held |= (low[0] | high[0]) & space.act
    held = np.broadcast_to(held, pts.shape).copy()
    moved, ok = space.retract(pts, held, iterations=20)
    if not ok.all():
        return None
    return margins, objective.pick(moved, [name] * len(moved)), moved[-1]


def _same_branch(space: _Space, q: np.ndarray, q_start: np.ndarray) -> bool:
    """A certified continuation from ``q`` back to its start's actuated values lands on the start."""
    from hyperstat.solver.kinematics.continuation import ContinuationOptions, continue_path

    kin, m = space.kin, space.m
    if not (len(m.passive) and len(m.closures)):
        return True
    if np.max(np.abs(q - q_start) / space.scale) <= 1e-12:
        return True
    opt = ContinuationOptions(initial_steps=4, cond_tol=1e-12)
    back, cert = continue_path(kin, q[None], q_start[None, m.actuated], None, opt)
    if not cert.certified[0]:
        qq = back.copy()
        qq[:, m.actuated] = q_start[m.actuated]
        back = kin.assemble(qq).q
    diff = space.ws.wrapped(back[0]) - space.ws.wrapped(q_start)
    rev = np.array([j.type == "R" for j in m.joints])
    diff[rev] = (diff[rev] + math.pi) % (2 * math.pi) - math.pi
    return bool(np.max(np.abs(diff) / space.scale) <= 1e-6)


def _describe(space: _Space, name: str, kind: str, value: float, sampled: float, q: np.ndarray, tol: float,
              starts: int, agreeing: int, iterations: int, evidence: str, start: str, location: str | None = None,
              supremum: bool = False, singular: bool | None = None) -> Extreme:
    kin, m = space.kin, space.m
    bounds = []
    low, high = space.at_bound(q[None], tol=1e-7)
    n_act = 0
    for i, j in enumerate(m.joints):
        if not space.free[i]:
            continue
        unit = "rad" if j.type == "R" else "mm"
        for side, hit, edge in (("lower", low[0, i], space.exact_lo[i]), ("upper", high[0, i], space.exact_hi[i])):
            if hit and np.isfinite(edge):
                what = "actuated" if space.act[i] else "passive"
                n_act += space.act[i]
                bounds.append(f"{what} joint {j.name} at its {side} workspace bound ({edge:.6g} {unit})")
    n_box = int(np.sum(np.isfinite(space.exact_lo) & space.act & space.free))
    if n_act:
        shape = "corner" if n_act == n_box else ("edge" if n_act == n_box - 1 else "face")
        bounds.insert(0, f"on a{'n' if shape == 'edge' else ''} {shape} of the actuated box")
    if singular is None:
        singular = bool(branch_conditioning(kin, q[None])[0] < SINGULAR) if len(m.passive) and len(m.closures) \
            else False
    if location is None:
        location = "boundary" if bounds else "interior"
    if start.startswith("dead centre") and "dead centre" not in evidence:
        evidence += f"; started from a {start}"
    st = kin.evaluate(q[None], None, False)
    return Extreme(name, kind, float(value), float(sampled), np.asarray(q, float),
                   {m.joints[i].name: float(q[i]) for i in m.actuated},
                   [float(v) for v in st.output_pose[0, :3, 3]], location, bounds, bool(singular), bool(supremum),
                   float(tol), int(starts), int(agreeing), int(iterations), start, evidence)


def refine_extremes(mechanism: Mechanism, maps: AccuracyMaps, analysis=None, kinematics: Kinematics | None = None,
                    workspace: Workspace | None = None, kinds: tuple = ("max", "min"), starts: int = 3,
                    margin: float = MARGIN, names: tuple | None = None) -> dict:
    """The extremes of the accuracy coefficients over the workspace, searched from their maps.

    :func:`search_extremes` on :class:`Coefficients`, started from the maps' configurations.

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
        Local searches per extreme, from the best separate candidates.

    Returns
    -------
    dict
        ``(coefficient, kind)`` -> :class:`Extreme`.
    """
    kin = kinematics or Kinematics(mechanism)
    present = tuple(n for n in (names or COEFFICIENT_NAMES) if len(maps.coefficients.get(n, ())))
    sampled = {n: maps.coefficients[n] for n in present}
    return search_extremes(kin, Coefficients(kin, analysis, present), maps.q, workspace, kinds, starts,
                           names=present, sampled=sampled, margin=margin)
