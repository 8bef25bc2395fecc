"""An independent re-computation of worst cases: its own kinematics, play model, programme and search.

Units: mm and rad.

Nothing of hyperstat's solver is used here except the mechanism's *data* (the placements, joint types
and defect names of the model, the template's declared clearances and workspace): the frames are
built from the documented parameterisation (``docs/model-format.md``: an axis perturbed by
``(dI, dJ, dK)`` in the previous frame and renormalised, the frame carried by the minimal rotation,
the origin shifted by ``(da, db, dc)``, ``G`` a turn about the frame's own z axis), the loops are
closed by this module's own Newton iterations, the Jacobians are central differences of this module's
forward kinematics, the plays of a joint are rigid displacements of its supports written out here, the
largest violation is a linear programme in a different form (the passive velocities as free
variables, no left null space), and the worst cases are searched on dense grids with the dead
centres solved by bisection and a final local refinement by zooming grids.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from scipy.optimize import linprog

__all__ = ["OwnModel"]


def _minrot(n0: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Rotation taking the unit vector n0 to the unit vector n about n0 x n (Rodrigues), batched (..., 3, 3)."""
    v = np.cross(n0, n)
    s = np.linalg.norm(v, axis=-1)[..., None, None]
    c = np.sum(n0 * n, axis=-1)[..., None, None]
    k = np.zeros(v.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.where(s > 1e-300, (1 - c) / np.where(s > 1e-300, s * s, 1.0), 0.5)
    return np.eye(3) + k + f * (k @ k)


def _rot_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(np.shape(a) + (4, 4))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = c, -s, s, c
    out[..., 2, 2] = out[..., 3, 3] = 1.0
    return out


def _trans_z(d: np.ndarray) -> np.ndarray:
    out = np.zeros(np.shape(d) + (4, 4))
    out[..., :, :] = np.eye(4)
    out[..., 2, 3] = d
    return out


def _rotvec(m: np.ndarray) -> np.ndarray:
    """Rotation vector of small rotations (..., 3, 3) (the skew part, enough for closure residuals near 0)."""
    w = 0.5 * np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1)
    s = np.linalg.norm(w, axis=-1, keepdims=True)
    ang = np.arcsin(np.clip(s, 0, 1))
    return np.where(s > 1e-300, w * ang / np.where(s > 1e-300, s, 1.0), w)


def _displacement(v: np.ndarray, w: np.ndarray, centre: float) -> np.ndarray:
    """Rigid displacement (..., 4, 4): rotation vector w about the point (0, 0, centre), then translation v."""
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    k = np.zeros(w.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
    k[..., 1, 0], k[..., 2, 0], k[..., 2, 1] = w[..., 2], -w[..., 1], w[..., 0]
    safe = np.where(th > 1e-300, th, 1.0)
    r = np.eye(3) + np.where(th > 1e-300, np.sin(safe) / safe, 1.0) * k + \
        np.where(th > 1e-300, (1 - np.cos(safe)) / safe ** 2, 0.5) * (k @ k)
    c = np.array([0.0, 0.0, centre])
    out = np.zeros(w.shape[:-1] + (4, 4))
    out[..., :3, :3] = r
    out[..., :3, 3] = v + c - r @ c
    out[..., 3, 3] = 1.0
    return out


class OwnModel:
    """Forward kinematics, loop closure, plays and the largest absorbed violation of a mechanism, from its data.

    Parameters
    ----------
    mechanism
        A hyperstat ``Mechanism``: only its data are read (chains, elements, placements, defects, roles).
    clearances : dict
        Joint name -> resolved clearance (``radial_mm``, ``axial_mm``, ``tilt_rad``, ``span_mm``,
        ``twist_rad``, ``side``, ``centre_mm``), as the template declares them.
    """

    def __init__(self, mechanism, clearances: dict) -> None:
        self.m = mechanism
        self.joints = [j.name for ch in mechanism.chains for j in ch.elements if j.kind == "joint"]
        self.index = {n: i for i, n in enumerate(self.joints)}
        self.types = {j.name: j.type for ch in mechanism.chains for j in ch.elements if j.kind == "joint"}
        self.passive = [i for i, n in enumerate(self.joints) if self._joint(n).role == "passive"]
        self.actuated = [i for i, n in enumerate(self.joints) if self._joint(n).role == "actuated"]
        self.clear = clearances
        self.defect_of = {d.name: (el.name, d.component) for ch in mechanism.chains for el in ch.elements
                          for d in getattr(el, "defects", ())}
        # the loop order: chains whose start is defined, as the data say
        defined, order, closing = {mechanism.base}, [], []
        left = list(range(len(mechanism.chains)))
        while left:
            for ci in left:
                ch = mechanism.chains[ci]
                if ch.start in defined:
                    (closing if ch.end in defined else order).append(ci)
                    defined.add(ch.end)
                    left.remove(ci)
                    break
        self.order, self.closing = order, closing
        self.param_col = {d.name: i for i, d in enumerate(d for ch in mechanism.chains for el in ch.elements
                                                         for d in getattr(el, "defects", ()))}
        self.element_cols = {el.name: np.array([next((self.param_col[d.name] for d in getattr(el, "defects", ())
                                                      if d.component == c), -1) for c in "IJKabcG"])
                             for ch in mechanism.chains for el in ch.elements}
        comps = ("v1", "v2", "v3", "w1", "w2", "w3")
        self.play_col = {(n, c): 6 * i + j for i, n in enumerate(self.joints) for j, c in enumerate(comps)}
        self.play_joint_cols = {n: 6 * i + np.arange(6) for i, n in enumerate(self.joints)}
        # the play variables: per joint v1, v2, v3, w1, w2, w3 (in units of the play; zero-size ones dropped)
        self.plays = []
        for n in self.joints:
            c = clearances[n]
            tilt = c["tilt_rad"] if math.isfinite(c["tilt_rad"]) else 0.0
            sizes = {"v1": c["radial_mm"], "v2": c["radial_mm"], "v3": c["axial_mm"], "w1": tilt, "w2": tilt,
                     "w3": c["twist_rad"] if self.types[n] == "P" else 0.0}
            for comp, size in sizes.items():
                if size > 0:
                    self.plays.append((n, comp, size))

    def _joint(self, name):
        return next(el for ch in self.m.chains for el in ch.elements if el.name == name)

    # ----------------------------------------------------------------------------------------- kinematics
    def frames(self, q: np.ndarray, defects: list | None = None, plays: list | None = None) -> dict:
        """Absolute frames (K, 4, 4) of every chain end, batched over configurations ``q`` (K, n_q).

        ``defects[k]``: {parameter name: value} of configuration k; ``plays[k]``: {(joint, comp): value in units of
        the play}.
        """
        k = len(q)
        dvals = self._table(defects, k, self.param_col)
        pvals = self._table(plays, k, self.play_col)
        ends: dict = {self.m.base: np.broadcast_to(np.eye(4), (k, 4, 4)).copy()}
        closing_ends = {}
        for ci in self.order + self.closing:
            ch = self.m.chains[ci]
            t = ends[ch.start].copy()
            for el in ch.elements:
                if el.kind == "frame":
                    t = t @ _placement(el.placement)
                    continue
                cols = self.element_cols[el.name]
                vals = np.where(cols >= 0, dvals[:, np.maximum(cols, 0)], 0.0)
                t = t @ _element(el.placement, vals)
                if el.kind == "joint":
                    qi = q[:, self.index[el.name]]
                    motion = _rot_z(qi) if el.type == "R" else _trans_z(qi)
                    c = self.clear[el.name]
                    disp = self._play(el.name, pvals, c)
                    t = (t @ disp @ motion) if c["side"] == "fixed" else (t @ motion @ disp)
            if ci in self.closing:
                closing_ends[ci] = t
            else:
                ends[ch.end] = t
        return ends, closing_ends

    @staticmethod
    def _table(entries, k: int, col: dict) -> np.ndarray:
        """A list of {key: value} (or None) -> a (K, n) array by ``col``."""
        out = np.zeros((k, len(col)))
        for row, entry in enumerate(entries or ()):
            for key, value in entry.items():
                out[row, col[key]] = value
        return out

    def _play(self, joint: str, pvals: np.ndarray, c: dict) -> np.ndarray:
        y = pvals[:, self.play_joint_cols[joint]]
        tilt = c["tilt_rad"] if math.isfinite(c["tilt_rad"]) else 0.0
        scale = np.array([c["radial_mm"], c["radial_mm"], c["axial_mm"], tilt, tilt, c["twist_rad"]])
        return _per_distinct_row(lambda yy: _displacement(yy[:, :3] * scale[:3], yy[:, 3:] * scale[3:],
                                                          c["centre_mm"]), y)

    def residual(self, q: np.ndarray, defects=None, plays=None) -> np.ndarray:
        """Closure residuals (K, 6 L): rotation (times 1000 mm) and position, per closing chain."""
        ends, closing = self.frames(q, defects, plays)
        out = []
        for ci in self.closing:
            ref = ends[self.m.chains[ci].end]
            t = closing[ci]
            out.append(1000.0 * _rotvec(t[:, :3, :3] @ np.swapaxes(ref[:, :3, :3], 1, 2)))
            out.append(t[:, :3, 3] - ref[:, :3, 3])
        return np.concatenate(out, axis=1) if out else np.zeros((len(q), 0))

    def output(self, q: np.ndarray, defects=None) -> np.ndarray:
        """Output frames (K, 4, 4)."""
        return self.frames(q, defects)[0][self.m.output]

    def assemble(self, q: np.ndarray, defects=None, iterations: int = 30) -> tuple[np.ndarray, np.ndarray]:
        """Close the loops by Newton steps on the passive joints (central-difference Jacobian), batched."""
        q = np.array(q, dtype=float, copy=True)
        h = 1e-7
        k, n_p = len(q), len(self.passive)
        defects = defects or [{}] * k
        for _ in range(iterations):
            r = self.residual(q, defects)
            if np.max(np.abs(r)) < 1e-11:
                break
            probes = np.repeat(q[:, None], 2 * n_p, axis=1)  # (K, 2 n_p, n_q): +h and -h on each passive joint
            for j, i in enumerate(self.passive):
                probes[:, 2 * j, i] += h
                probes[:, 2 * j + 1, i] -= h
            rr = self.residual(probes.reshape(-1, q.shape[1]), [d for d in defects for _ in range(2 * n_p)])
            rr = rr.reshape(k, n_p, 2, -1)
            jac = ((rr[:, :, 0] - rr[:, :, 1]) / (2 * h)).transpose(0, 2, 1)
            q[:, self.passive] -= (np.linalg.pinv(jac, rcond=1e-12) @ r[..., None])[..., 0]
        return q, np.max(np.abs(self.residual(q, defects)), axis=1)

    def track(self, q_start: np.ndarray, targets: np.ndarray, steps: int = 12) -> tuple[np.ndarray, np.ndarray]:
        """Assembled configurations at actuated values ``targets`` (K, n_a), each reached from ``q_start`` in steps."""
        q = np.repeat(np.asarray(q_start, float)[None], len(targets), axis=0)
        a0 = q[:, self.actuated].copy()
        ok = np.ones(len(q), dtype=bool)
        for s in range(1, steps + 1):
            q[:, self.actuated] = a0 + (targets - a0) * s / steps
            q, res = self.assemble(q, iterations=12)
            ok &= res < 1e-8
        return q, ok

    def _probes(self, qs: np.ndarray, directions: list, h: float, h_play: float | None = None):
        """Central-difference probes at each of ``qs``: the passive joints, the plays (when ``h_play``), the directions.

        Returns (configurations (M, n), defects [{parameter: value}], plays [{(joint, component): value}]),
        in pairs +step, -step.
        """
        probes_q, probes_d, probes_p = [], [], []

        def add(q, defects=None, plays=None):
            probes_q.append(q)
            probes_d.append(defects or {})
            probes_p.append(plays or {})

        for q in qs:
            for i in self.passive:
                for sgn in (1, -1):
                    qq = q.copy()
                    qq[i] += sgn * h
                    add(qq)
            for key in (self.plays if h_play is not None else ()):
                for sgn in (1, -1):
                    add(q, plays={(key[0], key[1]): sgn * h_play})
            for direction in directions:
                for sgn in (1, -1):
                    add(q, defects={n: sgn * h * c for n, c in direction.items()})
        return np.array(probes_q), probes_d, probes_p

    def task_jacobian(self, q: np.ndarray, directions: list, h: float = 1e-6) -> np.ndarray:
        """Output position per unit of each direction, the passive joints following (K, 3, n), mm per unit.

        First order by the implicit function theorem on this module's central differences:
        ``dp/dxi - dp/dq_p (dr/dq_p)^+ dr/dxi``.
        """
        k, n_p = len(q), len(self.passive)
        probes, defects, _ = self._probes(q, directions, h)
        r = self.residual(probes, defects)
        p = self.output(probes, defects)[:, :3, 3]
        n_c = n_p + len(directions)
        dr = ((r[0::2] - r[1::2]) / (2 * h)).reshape(k, n_c, -1)
        dp = ((p[0::2] - p[1::2]) / (2 * h)).reshape(k, n_c, 3)
        follow = np.linalg.pinv(np.swapaxes(dr[:, :n_p], 1, 2), rcond=1e-12) @ np.swapaxes(dr[:, n_p:], 1, 2)
        return np.swapaxes(dp[:, n_p:], 1, 2) - np.swapaxes(dp[:, :n_p], 1, 2) @ follow

    # ----------------------------------------------------------------------------------------- assemblability
    def violations(self, qs: np.ndarray, directions: list) -> np.ndarray:
        """Largest violation along each of ``directions`` ({parameter: coefficient}) absorbed at each of ``qs``.

        First order: ``max t`` subject to ``J_p dq_p + J_y y + J_t t = 0``, every support's radial
        displacement ``(v1 + s w2, v2 - s w1)`` (``s = +-1``, units of the play) in the regular octagon
        inscribed in the unit disc, ``|y| <= 1``; ``J`` by central differences of this module's closure
        residual.  Returns (K, len(directions)).
        """
        h, h_play = 1e-6, 1e-3
        qs = np.atleast_2d(qs)
        # a play of 1e-3 of the clearance: nanometres, far above the round-off
        probes_q, probes_d, probes_p = self._probes(qs, directions, h, h_play)
        r = self.residual(probes_q, probes_d, probes_p)
        n_p, n_y, n_d = len(self.passive), len(self.plays), len(directions)
        steps = np.r_[np.full(n_p, h), np.full(n_y, h_play), np.full(n_d, h)]
        jac = ((r[0::2] - r[1::2]).reshape(len(qs), n_p + n_y + n_d, -1) / (2 * steps[None, :, None])).transpose(0, 2, 1)
        pos = {(n, c): j for j, (n, c, _) in enumerate(self.plays)}
        rows = []
        for n in self.joints:
            if (n, "v1") not in pos:
                continue
            pads = (-1.0, 1.0) if (n, "w1") in pos else (0.0,)
            for s in pads:
                for phi in np.arange(4) * np.pi / 4:
                    row = np.zeros(n_y)
                    row[pos[(n, "v1")]] += math.cos(phi)
                    row[pos[(n, "v2")]] += math.sin(phi)
                    if s:
                        row[pos[(n, "w2")]] += s * math.cos(phi)
                        row[pos[(n, "w1")]] -= s * math.sin(phi)
                    rows.append(row)
        rows = np.array(rows).reshape(-1, n_y)
        a_ub = np.concatenate([np.zeros((2 * len(rows), n_p)), np.vstack([rows, -rows]), np.zeros((2 * len(rows), 1))],
                              axis=1)
        cost = np.zeros(n_p + n_y + 1)
        cost[-1] = -1.0
        out = np.full((len(qs), n_d), np.nan)
        for k in range(len(qs)):
            for j in range(n_d):
                a_eq = np.concatenate([jac[k, :, :n_p + n_y], jac[k, :, n_p + n_y + j:n_p + n_y + j + 1]], axis=1)
                # an orthonormal basis of the rows: the solver's feasibility tolerance is absolute per row
                q_rows, r_rows = np.linalg.qr(a_eq.T)
                keep = np.abs(np.diag(r_rows)) > 1e-10 * np.max(np.abs(np.diag(r_rows)))
                res = linprog(cost, A_eq=q_rows[:, keep].T, b_eq=np.zeros(int(keep.sum())), A_ub=a_ub,
                              b_ub=np.full(len(a_ub), math.cos(math.pi / 8)),
                              bounds=[(None, None)] * n_p + [(-1, 1)] * n_y + [(0, 100.0)], method="highs-ds",
                              options={"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10})
                if res.success:
                    out[k, j] = res.x[-1]
        return out

    def violation(self, q: np.ndarray, direction: dict) -> float:
        """:meth:`violations` at one configuration along one direction."""
        return float(self.violations(q[None], [direction])[0, 0])

    # ----------------------------------------------------------------------------------------- search
    def velocities(self, q: np.ndarray, axes: np.ndarray) -> np.ndarray:
        """Passive joint velocities per unit of the actuated joint ``axes[k]`` (index into the actuated list), (K, n_p)."""
        h = 1e-6
        both = np.repeat(q, 2, axis=0)
        cols = np.array(self.actuated)[np.repeat(axes, 2)]
        both[np.arange(len(both)), cols] += np.tile([h, -h], len(q))
        both, _ = self.assemble(both)
        return (both[0::2][:, self.passive] - both[1::2][:, self.passive]) / (2 * h)

    def dead_centres(self, q_start: np.ndarray, lines: list) -> list:
        """Where a passive joint's velocity changes sign along actuated lines (batched bisection, 36 halvings).

        ``lines``: ``(base actuated values, axis, s_grid)``, the actuated value ``axis`` running over the
        grid.  Returns ``(line index, s, configuration)`` per sign change.
        """
        targets, owner = [], []
        for li, (base, axis, grid) in enumerate(lines):
            for s_ in grid:
                a = np.array(base, float)
                a[axis] = s_
                targets.append(a)
                owner.append((li, s_))
        q, ok = self.track(q_start, np.array(targets))
        axes = np.array([lines[li][1] for li, _ in owner])
        vel = self.velocities(q, axes)
        tiny = 1e-7 * np.max(np.abs(vel), axis=0)  # a velocity identically zero along a line changes no sign
        brackets = []  # (line, joint, s_left, s_right, q_left, q_right, v_left)
        for k in range(len(q) - 1):
            if owner[k][0] != owner[k + 1][0] or not (ok[k] and ok[k + 1]):
                continue
            change = (vel[k] * vel[k + 1] < 0) & (np.abs(vel[k]) > tiny) & (np.abs(vel[k + 1]) > tiny)
            for p in np.nonzero(change)[0]:
                brackets.append([owner[k][0], p, owner[k][1], owner[k + 1][1], q[k], q[k + 1], vel[k, p]])
        for _ in range(36):
            if not brackets:
                break
            mids = []
            for li, p, s0, s1, q0, q1, v0 in brackets:
                qq = 0.5 * (q0 + q1)
                base, axis, _ = lines[li]
                a = np.array(base, float)
                a[axis] = 0.5 * (s0 + s1)
                qq[self.actuated] = a
                mids.append(qq)
            mids, _ = self.assemble(np.array(mids))
            v = self.velocities(mids, np.array([lines[b[0]][1] for b in brackets]))
            for j, br in enumerate(brackets):
                vm = v[j, br[1]]
                s_mid = 0.5 * (br[2] + br[3])
                if vm * br[6] > 0:
                    br[2], br[4], br[6] = s_mid, mids[j], vm
                else:
                    br[3], br[5] = s_mid, mids[j]
        return [(br[0], 0.5 * (br[2] + br[3]), 0.5 * (br[4] + br[5])) for br in brackets]

    def zoom(self, q_near: np.ndarray, free: list, lo: np.ndarray, hi: np.ndarray, directions: list,
             points: int = 5, levels: int = 14) -> np.ndarray:
        """Smallest violation (per direction) over the actuated joints ``free`` near ``q_near``, by zooming grids.

        A ``points``-per-axis grid around the best point so far, within ``[lo, hi]``; the window halves when the
        best point is inside it and moves (same size) when it is on its rim.  Returns the minima (len(directions)).
        """
        free = list(free)
        centre = q_near[np.array(self.actuated)[free]].astype(float)
        half = 0.125 * (hi - lo)
        best_q = np.repeat(q_near[None], len(directions), axis=0)
        best_t = self.violations(q_near[None], directions)[0]
        centres = np.repeat(centre[None], len(directions), axis=0)
        halves = np.repeat(half[None], len(directions), axis=0)
        offsets = np.array(list(itertools.product(np.linspace(-1, 1, points), repeat=len(free))))
        for _ in range(levels):
            for j in range(len(directions)):
                pts = np.clip(centres[j] + offsets * halves[j], lo, hi)
                targets = np.repeat(best_q[j][None], len(pts), axis=0)[:, self.actuated]
                targets[:, free] = pts
                qq, ok = self.track(best_q[j], targets, steps=2)
                if not ok.any():
                    halves[j] *= 0.5
                    continue
                t = self.violations(qq[ok], [directions[j]])[:, 0]
                i = int(np.nanargmin(t))
                on_rim = np.any(np.abs(offsets[ok][i]) == 1.0)
                if t[i] < best_t[j]:
                    best_t[j], best_q[j] = t[i], qq[ok][i]
                    centres[j] = pts[ok][i]
                if not on_rim or t[i] >= best_t[j]:
                    halves[j] *= 0.5
        return best_t


def _placement(p) -> np.ndarray:
    z, x = np.asarray(p.z_axis, float), np.asarray(p.x_axis, float)
    t = np.eye(4)
    t[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    t[:3, 3] = p.origin
    return t


def _per_distinct_row(build, vals: np.ndarray) -> np.ndarray:
    """``build(vals)`` with the rows of ``vals`` (K, n) that are all zero computed once: the same values, row by row.

    The probes of a central difference perturb one parameter at a time, so most rows of a batch are zero for any
    one element or joint.
    """
    moved = np.any(vals != 0.0, axis=1)
    n_moved = int(np.count_nonzero(moved))
    if n_moved > len(vals) // 2:
        return build(vals)
    rows = build(np.concatenate([np.zeros((1, vals.shape[1])), vals[moved]]))
    out = np.empty((len(vals),) + rows.shape[1:])
    out[:] = rows[0]
    out[moved] = rows[1:]
    return out


def _element(p, vals: np.ndarray) -> np.ndarray:
    """The geometric matrix D (K, 4, 4) of a placement with defects ``vals`` (K, 7) = (I, J, K, a, b, c, G)."""
    return _per_distinct_row(lambda v: _element_rows(p, v), vals)


def _element_rows(p, vals: np.ndarray) -> np.ndarray:
    base = _placement(p)
    n0 = base[:3, 2]
    n = n0 + vals[:, :3]
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    out = np.zeros((len(vals), 4, 4))
    out[:, :3, :3] = _minrot(np.broadcast_to(n0, n.shape), n) @ base[:3, :3] @ _rot_z(vals[:, 6])[:, :3, :3]
    out[:, :3, 3] = base[:3, 3] + vals[:, 3:6]
    out[:, 3, 3] = 1.0
    return out
