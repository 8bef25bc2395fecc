"""Straight moves in LinuxCNC's world coordinates: do the joints stay inside their ranges all the way?

Units: world coordinates in mm and degrees (LinuxCNC's), joints in mm and rad.

LinuxCNC moves a ``G1`` along a straight line in world coordinates (``X Y Z`` and the rotary
axes, :func:`hyperstat.solver.export.linuxcnc_kins.world_layout`) and checks the joint limits of
its end points only.  On a parallel machine, or a serial one near the edge of its workspace, the
line between two reachable poses can leave the joint ranges in between: the leg strokes (or joint
angles) run past a limit part-way.  :func:`check_straight_move` follows the line as the
controller does (the inverse kinematics from the previous point, every 2 mm and 1 degree)
and reports where the first joint leaves its range, and by how much each one does.

Examples
--------
>>> from hyperstat.solver.kinematics.robot_import import parse_dh_table, dh_to_mechanism
>>> t = parse_dh_table({"format": "hyperstat-dh", "version": 1, "name": "r3", "convention": "dh",
...                     "units": {"length": "mm", "angle": "deg"},
...                     "joints": [{"type": "R", "a": 100, "alpha": 0, "d": 0, "theta": 0, "min": -90, "max": 90},
...                                {"type": "R", "a": 100, "alpha": 0, "d": 0, "theta": 0, "min": 10, "max": 170},
...                                {"type": "P", "a": 0, "alpha": 0, "d": 0, "theta": 0, "min": -50, "max": 50}]})
>>> m = dh_to_mechanism(t)
>>> r = check_straight_move(m, None, [150.0, 50.0, 0.0], [50.0, 150.0, 0.0])
>>> r["inside"], r["joint"]
(True, None)
"""

from __future__ import annotations

import math

import numpy as np

from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.closure import Kinematics, batched_lstsq
from hyperstat.solver.kinematics.frames import so3_log

__all__ = ["world_inverse", "check_straight_move", "STEP_MM", "STEP_DEG"]

#: spacing of the points checked along a line (mm of the position, degrees of the rotary axes)
STEP_MM = 2.0
STEP_DEG = 1.0


def _rotation(a: float, b: float, c: float) -> np.ndarray:
    """``Rz(C) Ry(B) Rx(A)`` (angles in rad), LinuxCNC's orientation of ``X Y Z A B C``."""
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    return np.array([[cc * cb, cc * sb * sa - sc * ca, cc * sb * ca + sc * sa],
                     [sc * cb, sc * sb * sa + cc * ca, sc * sb * ca - cc * sa],
                     [-sb, cb * sa, cb * ca]])


def world_inverse(kin: Kinematics, xi: np.ndarray, layout: dict, world: np.ndarray, q_start: np.ndarray,
                  max_iter: int = 40) -> tuple[np.ndarray, float]:
    """All joints (n_q,) at world coordinates ``world`` (mm, degrees), by Gauss-Newton from ``q_start``.

    The unknowns are the actuated joints (the wrist joints of ``tcp`` mode are world
    coordinates themselves); the passive joints follow by assembly from the previous
    configuration, so the solution stays on the branch of ``q_start``.  Returns the
    configuration and the remaining error (mm; rotations counted at the length scale).
    """
    m = kin.mechanism
    act = np.asarray(m.actuated)
    world = np.asarray(world, dtype=float)
    q = np.asarray(q_start, dtype=float).copy()
    free = np.ones(len(act), dtype=bool)
    for k, (j, _letter) in enumerate(layout["wrist"]):
        q[j] = math.radians(world[3 + k])
        free[list(act).index(j)] = False
    want_r = _rotation(*np.radians(world[3:6])) if layout["mode"] == "pose" else None
    lc = kin.length_scale
    lin = np.array([m.joints[i].type == "P" for i in act])
    err = np.inf
    for _ in range(max_iter):
        res = kin.solve(q[act][None, :], xi, start=q[None, :])
        if not res.converged[0]:
            return q, np.inf
        q = res.q[0]
        st = kin.evaluate(q[None, :], xi, jacobians=True)
        pose = st.output_pose[0]
        rows = [world[:3] - pose[:3, 3]]
        if want_r is not None:
            rows.insert(0, so3_log((want_r @ pose[:3, :3].T)[None])[0] * lc)
        e = np.concatenate(rows)
        err = float(np.linalg.norm(e))
        if err < 1e-10 * max(1.0, lc):
            break
        passive = m.passive
        if len(passive) and len(m.closures):
            b = kin.scaled_rows(st.closure_q[:, :, passive])
            dp = batched_lstsq(b, kin.scaled_rows(st.closure_q[:, :, act]))
            k_a = (st.output_q[:, :, act] - st.output_q[:, :, passive] @ dp)[0]
        else:
            k_a = st.output_q[0][:, act]
        jac = k_a.copy()
        jac[:3] *= lc
        jac = jac if want_r is not None else jac[3:]
        step = np.zeros(len(act))
        step[free] = np.linalg.lstsq(jac[:, free], e, rcond=None)[0]
        size = np.max(np.abs(step) / np.where(lin, 0.3 * lc, 0.3), initial=0.0)
        q[act] += step / max(size, 1.0)
    return q, err


def _follow(kin: Kinematics, xi: np.ndarray, layout: dict, world: np.ndarray, q: np.ndarray,
            max_iter: int = 12) -> tuple[np.ndarray, float]:
    """One point of a line: Gauss-Newton on every joint at once (closure residuals and output constraints), from
    the previous point's configuration, as the generated LinuxCNC component does each servo cycle.  Returns the
    configuration and the remaining error (mm; rotations at the length scale)."""
    m = kin.mechanism
    q = q.copy()
    free = np.ones(len(m.joints), dtype=bool)
    for k, (j, _letter) in enumerate(layout["wrist"]):
        q[j] = math.radians(world[3 + k])
        free[j] = False
    want_r = _rotation(*np.radians(world[3:6])) if layout["mode"] == "pose" else None
    lc = kin.length_scale
    lin = np.array([j.type == "P" for j in m.joints])
    err = np.inf
    for _ in range(max_iter):
        st = kin.evaluate(q[None, :], xi, jacobians=True)
        pose = st.output_pose[0]
        out_e = world[:3] - pose[:3, 3]
        out_j = st.output_q[0][3:]
        if want_r is not None:
            out_e = np.concatenate([so3_log((want_r @ pose[:3, :3].T)[None])[0] * lc, out_e])
            out_j = np.vstack([st.output_q[0][:3] * lc, out_j])
        e = np.concatenate([-kin.scaled_rows(st.residual[0][:, None])[:, 0], out_e])
        jac = np.vstack([kin.scaled_rows(st.closure_q)[0], out_j])
        err = float(np.linalg.norm(e))
        if err < 1e-9 * max(1.0, lc):
            break
        step = np.zeros(len(q))
        step[free] = np.linalg.lstsq(jac[:, free], e, rcond=None)[0]
        size = np.max(np.abs(step) / np.where(lin, 0.3 * lc, 0.3), initial=0.0)
        q += step / max(size, 1.0)
    return q, err


def check_straight_move(mechanism, xi: np.ndarray | None, start: np.ndarray, end: np.ndarray,
                        q_start: np.ndarray | None = None, layout: dict | None = None,
                        region: dict | None = None) -> dict:
    """Follow the straight line from ``start`` to ``end`` (world coordinates, mm and degrees) and report
    whether every actuated joint stays inside its range.

    Parameters
    ----------
    mechanism : Mechanism
    xi : ndarray or None
        Defects (the identified geometry of a controller file), rad / mm.
    start, end : array_like
        World coordinates of the move's end points (the layout's letters, mm and degrees).
    q_start : ndarray, optional
        Configuration at ``start`` (default: solved from home).
    layout : dict, optional
        :func:`~hyperstat.solver.export.linuxcnc_kins.world_layout` of the mechanism.
    region : dict, optional
        The joint-space region a calibration's poses covered (a controller file's
        ``calibration.region``: ``low`` and ``high`` per actuated joint, rad / mm): the result then
        also says where the move leaves it (the identified model is extrapolated beyond).

    Returns
    -------
    dict
        ``inside`` (bool), ``samples``, and when a joint leaves its range: ``fraction`` (0..1 of
        the line where the first one does), ``world`` (there), ``joint`` (its name), ``value`` and
        ``limit`` (rad or mm); ``excess``: per actuated joint, the largest excursion beyond its
        range along the line (0 when inside; rad or mm).  With ``region``: ``calibrated`` holds
        ``inside`` (bool), and where the move first leaves the region ``fraction``, ``world``,
        ``joint``, ``value`` and the region's ``low`` and ``high`` for that joint, and ``beyond``:
        per actuated joint the largest excursion beyond the region (rad or mm).

    Raises
    ------
    DataError
        If an end point is not reachable inside the joint ranges, or the line cannot be followed
        (the inverse kinematics fails part-way: a singularity or the edge of the workspace).
    """
    from hyperstat.solver.export.linuxcnc_kins import world_layout

    m = mechanism
    kin = Kinematics(m)
    xi = np.zeros(len(m.parameters)) if xi is None else np.asarray(xi, dtype=float)
    layout = layout or world_layout(m)
    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    n = len(layout["coordinates"])
    if start.shape != (n,) or end.shape != (n,):
        raise DataError(f"a move of '{m.name}' has {n} world coordinates ({' '.join(layout['coordinates'])}).")
    act = np.asarray(m.actuated)
    lo, hi = m.ranges[act].T
    tol = 1e-6
    q0 = m.home.copy() if q_start is None else np.asarray(q_start, dtype=float)
    ends = []
    for label, w in (("start", start), ("end", end)):
        q, err = world_inverse(kin, xi, layout, w, q0 if label == "start" else ends[0])
        qa = q[act]
        if not err < 1e-6 or np.any(qa < lo - tol) or np.any(qa > hi + tol):
            raise DataError(f"the {label} point {' '.join(f'{a}{v:g}' for a, v in zip(layout['coordinates'], w))} "
                            f"of the move is not reachable inside the joint ranges of '{m.name}'.")
        ends.append(q)
    dist = float(np.linalg.norm(end[:3] - start[:3]))
    turn = float(np.max(np.abs(end[3:] - start[3:]), initial=0.0))
    count = max(50, math.ceil(dist / STEP_MM), math.ceil(turn / STEP_DEG))
    excess = np.zeros(len(act))
    first = None
    q = ends[0]
    if region is not None:
        r_lo, r_hi = np.asarray(region["low"], dtype=float), np.asarray(region["high"], dtype=float)
        beyond = np.maximum(np.maximum(r_lo - q[act], q[act] - r_hi), 0.0)
        left = None
        if np.any(beyond > tol):
            j = int(np.argmax(beyond))
            left = {"fraction": 0.0, "world": start.tolist(), "joint": m.joints[act[j]].name,
                    "value": float(q[act][j]), "low": float(r_lo[j]), "high": float(r_hi[j])}
    for k in range(1, count + 1):
        s = k / count
        w = start + s * (end - start)
        q_prev = q
        q, err = _follow(kin, xi, layout, w, q)
        if not err < 1e-6:
            # an identified over-constrained machine closes its loops only in the least-squares sense (second-order
            # strain, about 1e-4 mm on the Tripteor): Gauss-Newton on closure and output together then stops at that
            # floor; the passive joints assembled by least squares from the previous point, the output exact
            q, err = world_inverse(kin, xi, layout, w, q_prev)
        if not err < 1e-6:
            raise DataError(f"the straight line of the move cannot be followed at {100 * s:.3g} % of its length "
                            f"(the inverse kinematics fails there: a singularity or the edge of the workspace).")
        qa = q[act]
        out = np.maximum(lo - qa, qa - hi)
        excess = np.maximum(excess, out)
        if first is None and np.any(out > tol):
            j = int(np.argmax(out))
            first = {"fraction": s, "world": w.tolist(), "joint": m.joints[act[j]].name, "value": float(qa[j]),
                     "limit": float(lo[j] if qa[j] < lo[j] else hi[j])}
        if region is not None:
            past = np.maximum(r_lo - qa, qa - r_hi)
            beyond = np.maximum(beyond, past)
            if left is None and np.any(past > tol):
                j = int(np.argmax(past))
                left = {"fraction": s, "world": w.tolist(), "joint": m.joints[act[j]].name, "value": float(qa[j]),
                        "low": float(r_lo[j]), "high": float(r_hi[j])}
    result = {"inside": first is None, "samples": count, "excess": {m.joints[i].name: float(max(e, 0.0))
                                                                     for i, e in zip(act, excess)},
              "fraction": None, "world": None, "joint": None, "value": None, "limit": None}
    if first:
        result.update(first)
    if region is not None:
        result["calibrated"] = {"inside": left is None, **(left or {"fraction": None, "world": None, "joint": None,
                                                                   "value": None, "low": None, "high": None}),
                                "beyond": {m.joints[i].name: float(max(e, 0.0)) for i, e in zip(act, beyond)}}
    return result
