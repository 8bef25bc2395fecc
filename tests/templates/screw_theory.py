"""Mobility, degree of over-constraint and assembly conditions from screw theory, independently of the solver.

Units: lengths in mm, angles in rad.

This module is the corpus's second method: it shares no code with ``hyperstat.solver`` (no
joint-invariant frames, no stationarity, no closure solver).  It reads only what a template
*declares* (joint points and axes at home, roles, ranges, chains) and works with the
product-of-exponentials model of screw theory:

* every joint is a unit screw ``xi_j`` at home in world coordinates (``(w, -w x p)`` for a
  revolute about the line through ``p`` along ``w``, ``(0, v)`` for a prismatic along ``v``);
* a frame's displacement from home is ``G_F(q) = G_start(q) prod_j exp(xi_j (q_j - home_j))``
  along the chain that defines it; a closing chain must reach the same displacement, and its
  discrepancy ``log(G_closing G_F^-1)`` is the loop's six closure equations;
* the joint Jacobian of the loops has the joint twists ``Ad(P_{j-1}) xi_j`` as columns (signed by
  the side of the loop); its rank ``r`` at a generic configuration gives the mobility
  ``n - r`` and the degree of over-constraint ``6 L - r`` (``L`` closing chains);
* moving joint ``j``'s line at home by a small rigid motion ``eps`` changes ``exp(xi_j t)`` to
  ``exp(eps) exp(xi_j t) exp(-eps)``: the loop discrepancy changes by ``(Ad(P_{j-1}) - Ad(P_j)) eps``.
  A geometry change keeps the mechanism assembled and mobile to first order only if, at every
  configuration, that discrepancy lies in the span of the passive joints' twists; the number of
  independent conditions this puts on the joint lines is the rank of the stacked projections
  onto the left null space of the passive columns.  It counts conditions on the *lines* of the
  joints (4 per revolute, 2 per prismatic), the geometry itself, so it does not depend on how a
  tool parameterises that geometry.

The configurations are assembled here by Newton's method with continuation from home.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import null_space
from scipy.spatial.transform import Rotation


def _hat(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _exp(xi: np.ndarray, t: float) -> np.ndarray:
    """``exp(xi t)`` of a unit screw of pitch zero (revolute) or infinite pitch (prismatic), closed form."""
    w, v = xi[:3], xi[3:]
    out = np.eye(4)
    if not np.any(w):
        out[:3, 3] = v * t
        return out
    k = _hat(w)
    r = np.eye(3) + np.sin(t) * k + (1.0 - np.cos(t)) * (k @ k)  # Rodrigues
    out[:3, :3] = r
    out[:3, 3] = (np.eye(3) - r) @ np.cross(w, v)  # (I - R) p, p = w x v the axis point nearest the origin
    return out


def _adjoint(g: np.ndarray) -> np.ndarray:
    r, p = g[:3, :3], g[:3, 3]
    out = np.zeros((6, 6))
    out[:3, :3] = r
    out[3:, 3:] = r
    out[3:, :3] = _hat(p) @ r
    return out


def _inverse(g: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = g[:3, :3].T
    out[:3, 3] = -g[:3, :3].T @ g[:3, 3]
    return out


@dataclass
class ScrewJoint:
    """One joint: unit screw at home (world), type, role, home value and range."""

    name: str
    kind: str  # "R" or "P"
    actuated: bool
    screw: np.ndarray
    home: float
    low: float
    high: float


class ScrewModel:
    """The loops of a mechanism as products of exponentials.

    Parameters
    ----------
    joints : list of ScrewJoint
    chains : list of (start frame, end frame, [joint names]) in the order the frames are placed
    base : str
    """

    def __init__(self, joints: list[ScrewJoint], chains: list[tuple[str, str, list[str]]], base: str = "R0") -> None:
        self.joints = joints
        self.index = {j.name: i for i, j in enumerate(joints)}
        self.base = base
        self.defining: dict[str, tuple[str, list[int]]] = {}  # frame -> (start frame, joint indices)
        self.closing: list[tuple[str, list[int], str]] = []  # (start frame, joint indices, frame closed on)
        placed = {base}
        pending = list(chains)
        while pending:
            for k, (start, end, names) in enumerate(pending):
                if start in placed:
                    break
            else:
                raise ValueError("a chain starts at a frame no chain reaches")
            start, end, names = pending.pop(k)
            idx = [self.index[n] for n in names if n in self.index]  # fixed transforms carry no motion
            if end in placed:
                self.closing.append((start, idx, end))
            else:
                self.defining[end] = (start, idx)
                placed.add(end)
        self.n = len(joints)
        self.loops = len(self.closing)
        self.actuated = np.array([j.actuated for j in joints])
        self.home = np.array([j.home for j in joints])
        self.length = 1.0
        origins = [self._point(j) for j in joints if j.kind == "R"]
        if len(origins) > 1:
            spread = np.ptp(np.array(origins), axis=0)
            self.length = max(float(np.max(spread)), 1.0)

    @staticmethod
    def _point(j: ScrewJoint) -> np.ndarray:
        w, v = j.screw[:3], j.screw[3:]
        return np.cross(w, v)  # the point of the axis closest to the origin

    # ------------------------------------------------------------------ kinematics
    def _path(self, frame: str) -> list[int]:
        """Joint indices from the base to ``frame`` along the defining chains, in order."""
        if frame == self.base:
            return []
        start, idx = self.defining[frame]
        return self._path(start) + idx

    def _loop_paths(self) -> list[tuple[list[int], list[int]]]:
        if not hasattr(self, "_paths"):
            self._paths = [(self._path(start) + idx, self._path(end)) for start, idx, end in self.closing]
        return self._paths

    def _walk(self, q: np.ndarray) -> list[tuple[list[np.ndarray], list[np.ndarray]]]:
        """Per loop, the products ``P_0 = I, P_1, ..., P_m`` along its closing and its defining path."""
        exps = [_exp(j.screw, q[i] - self.home[i]) for i, j in enumerate(self.joints)]
        out = []
        for close, define in self._loop_paths():
            pair = []
            for path in (close, define):
                prods = [np.eye(4)]
                for i in path:
                    prods.append(prods[-1] @ exps[i])
                pair.append(prods)
            out.append(tuple(pair))
        return out

    def residual(self, q: np.ndarray, walk=None) -> np.ndarray:
        """Closure discrepancy per loop: (rotation vector, translation) of ``G_closing G_F^-1``."""
        out = []
        for close, define in walk or self._walk(q):
            e = close[-1] @ _inverse(define[-1])
            out += [Rotation.from_matrix(e[:3, :3]).as_rotvec(), e[:3, 3]]
        return np.concatenate(out) if out else np.zeros(0)

    def _columns(self, q: np.ndarray, geometry: bool, walk=None) -> np.ndarray:
        """Loop Jacobian: (6L, n) joint twists, or (6L, 6n) effects of moving each joint's line."""
        width = 6 * self.n if geometry else self.n
        jac = np.zeros((6 * self.loops, width))
        for loop, ((close, define), prods_pair) in enumerate(zip(self._loop_paths(), walk or self._walk(q))):
            rows = slice(6 * loop, 6 * loop + 6)
            for path, prods, sign in ((close, prods_pair[0], 1.0), (define, prods_pair[1], -1.0)):
                ads = [_adjoint(g) for g in prods]
                for k, i in enumerate(path):
                    if geometry:
                        jac[rows, 6 * i:6 * i + 6] += sign * (ads[k] - ads[k + 1])
                    else:
                        jac[rows, i] += sign * ads[k] @ self.joints[i].screw
        return jac

    def joint_jacobian(self, q: np.ndarray, walk=None) -> np.ndarray:
        return self._columns(q, geometry=False, walk=walk)

    def _scaled(self, jac: np.ndarray, geometry: bool) -> np.ndarray:
        """Dimensionless rows (translations over the length) and columns (prismatic, line shifts)."""
        out = jac.copy()
        for loop in range(self.loops):
            out[6 * loop + 3:6 * loop + 6] /= self.length
        if geometry:
            for i in range(self.n):
                out[:, 6 * i + 3:6 * i + 6] *= self.length
        else:
            for i, j in enumerate(self.joints):
                if j.kind == "P":
                    out[:, i] *= self.length
        return out

    def assemble(self, target: np.ndarray, steps: int = 6) -> np.ndarray | None:
        """All joints at actuated values ``target``, passive ones by continuation from home; None if lost."""
        act = np.nonzero(self.actuated)[0]
        pas = np.nonzero(~self.actuated)[0]
        q = self.home.copy()
        for s in range(1, steps + 1):
            q[act] = self.home[act] + (target - self.home[act]) * s / steps
            r = np.zeros(0)
            for _ in range(30):
                walk = self._walk(q)
                r = self.residual(q, walk)
                if r.size == 0 or pas.size == 0 or np.linalg.norm(r) < 1e-11 * self.length:
                    break
                dq = -np.linalg.lstsq(self.joint_jacobian(q, walk)[:, pas], r, rcond=None)[0]
                q[pas] += dq
                if np.max(np.abs(dq)) > 0.5:  # a wild step: not on this branch any more
                    return None
            if self.loops and np.linalg.norm(self.residual(q)) > 1e-9 * self.length:
                return None
        return q

    def sample(self, count: int, seed: int = 0, fraction: float = 1.0) -> list[np.ndarray]:
        """``count`` assembled configurations, actuated values uniform in ``fraction`` of their ranges about home."""
        rng = np.random.default_rng(seed)
        act = np.nonzero(self.actuated)[0]
        out = []
        for _ in range(20 * count):
            lo = np.array([self.joints[i].low for i in act])
            hi = np.array([self.joints[i].high for i in act])
            h = self.home[act]
            target = h + fraction * (rng.random(len(act)) * (hi - lo) + lo - h)
            q = self.assemble(target)
            if q is not None and all(j.low - 1e-9 <= v <= j.high + 1e-9 for j, v in zip(self.joints, q)):
                out.append(q)
            if len(out) == count:
                break
        return out

    # ------------------------------------------------------------------ theory
    @staticmethod
    def _rank(matrix: np.ndarray, rel: float = 1e-10) -> tuple[int, float]:
        """Numerical rank and the gap between the last kept and the first dropped singular value."""
        if matrix.size == 0:
            return 0, np.inf
        s = np.linalg.svd(matrix, compute_uv=False)
        if s[0] == 0.0:
            return 0, np.inf
        keep = int(np.sum(s > rel * s[0]))
        gap = s[keep - 1] / s[keep] if keep < len(s) and s[keep] > 0 else np.inf
        return keep, gap

    def theory(self, configurations: int = 10, seed: int = 0) -> dict:
        """Mobility, degree of over-constraint and first-order assembly conditions (with rank gaps)."""
        qs = self.sample(configurations, seed)
        if len(qs) < min(configurations, 3):
            raise RuntimeError(f"only {len(qs)} configurations assembled")
        ranks = [self._rank(self._scaled(self.joint_jacobian(q), False)) for q in qs]
        r = max(rank for rank, _ in ranks)
        pas = np.nonzero(~self.actuated)[0]
        rows = []
        for q in qs:
            if not self.loops:
                break
            b = self._scaled(self.joint_jacobian(q), False)[:, pas]
            left = null_space(b.T, rcond=1e-9) if pas.size else np.eye(6 * self.loops)
            rows.append(left.T @ self._scaled(self._columns(q, geometry=True), True))
        conditions, gap = self._rank(np.vstack(rows)) if rows else (0, np.inf)
        return {"mobility": self.n - r, "overconstraint": 6 * self.loops - r, "conditions": conditions,
                "condition_gap": gap, "loops": self.loops, "joints": self.n, "configurations": len(qs)}


def screw_model(skeleton) -> ScrewModel:
    """The screw model of a template's declarations: joint points, axes, roles, homes, ranges and chains.

    Reads the :class:`hyperstat.cad_plugin.skeleton.Skeleton`'s declarations as the author wrote them (world
    coordinates at home), not the model the solver builds from them.
    """
    joints = []
    for name, spec in skeleton._items.items():
        if not hasattr(spec, "type"):
            continue  # a fixed transform: no motion
        axis = np.asarray(spec.z_axis, float) / np.linalg.norm(spec.z_axis)
        point = np.asarray(spec.origin, float)
        screw = np.r_[axis, -np.cross(axis, point)] if spec.type == "R" else np.r_[np.zeros(3), axis]
        joints.append(ScrewJoint(name, spec.type, spec.role == "actuated", screw, float(spec.home),
                                 float(spec.range[0]), float(spec.range[1])))
    chains = [(start, end, list(names)) for _, start, end, names in skeleton._chains]
    return ScrewModel(joints, chains, skeleton.base)


def kutzbach(bodies: int, joints: int, freedoms: int | None = None) -> int:
    """Chebychev-Grubler-Kutzbach count in space: ``6 (bodies - 1) - 6 joints + sum of joint freedoms``."""
    return 6 * (bodies - 1) - 6 * joints + (joints if freedoms is None else freedoms)
