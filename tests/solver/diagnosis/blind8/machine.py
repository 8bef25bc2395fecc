"""The virtual machines of the tenth blind generator (directory ``blind8``): model files, forward
kinematics with the effects put in, gravity loads.  Units: mm, rad, kg, N (prismatic loads), N mm
(revolute loads), degC.

Source-blind: written from ``docs/model-format.md`` and ``docs/diagnosis.md`` only.  The loop closure
of the parallel machines is the ninth generator's ``blind7/kin.py`` (generator code, not code under
test), imported; the serial forward kinematics here is this file's own (it carries the effects that act
inside a chain, e.g. a bowed guide), checked against ``kin.py`` and against an own modified-DH product
in the self-check.  Nothing here imports hyperstat.
"""
from __future__ import annotations

import json
import os

import numpy as np

from tests.solver.diagnosis.blind7.kin import Model, defect_transform, placement_matrix, rotvec_to_R

HERE = os.path.dirname(os.path.abspath(__file__))
G = 9.81  # m/s^2, gravity along -z of the base frame
GVEC = np.array([0.0, 0.0, -G])


def rot_about_line(point, axis, angle):
    """4x4 rigid rotation by ``angle`` about the line through ``point`` along ``axis`` (base frame)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    R = rotvec_to_R(a * angle)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(point, float) - R @ np.asarray(point, float)
    return T


class Machine:
    """A model file read for generation: ``kin.Model`` plus serial FK, masses and gravity."""

    def __init__(self, path, moving_mass=None):
        self.path = path
        with open(path) as f:
            self.data = json.load(f)
        self.kin = Model(path)
        self.actuated = list(self.kin.actuated)
        self.parallel = self.kin.closing
        meta = self.data.get("metadata", {})
        self.masses = meta.get("masses")
        self.moving_mass = meta.get("moving_mass", moving_mass)
        self.types = {n: self.kin.joints[n].type for n in self.actuated}
        self.ranges = {n: tuple(self.kin.joints[n].range) for n in self.actuated}
        self.home = {n: self.kin.joints[n].home for n in self.actuated}
        if not self.parallel:
            (_, _, _, els), = [c for c in self.kin.chains]
            self.elements = els
            self._com_local = None
            if self.masses:
                F0 = self.serial_frames({n: self.home[n] for n in self.actuated})[1]
                self._com_local = {
                    j: np.linalg.solve(F0[j], np.append(np.asarray(v["com"], float), 1.0))
                    for j, v in self.masses.items()}
        self._last = None

    # -- serial chains -------------------------------------------------------------------
    def serial_frames(self, q, post=None, defects=None):
        """Own serial FK.  ``post``: {joint: 4x4 local transform applied after the joint's motion}
        (a guide's bow); ``defects``: {(element, component): value} of the true machine's geometry.
        Returns (output pose, {joint: frame after its motion})."""
        T = np.eye(4)
        jf = {}
        for e in self.elements:
            T0 = e.T0
            if defects:
                for comp in e.defects:
                    eps = defects.get((e.name, comp))
                    if eps:
                        T0 = defect_transform(T0, comp, eps)
            T = T @ T0
            if e.kind == "joint":
                v = q[e.name]
                if e.type == "R":
                    c, s = np.cos(v), np.sin(v)
                    Rz = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
                    T = T @ Rz
                else:
                    Tz = np.eye(4)
                    Tz[2, 3] = v
                    T = T @ Tz
                if post and e.name in post:
                    T = T @ post[e.name]
                jf[e.name] = T
        return T, jf

    # -- any machine -----------------------------------------------------------------------
    def pose(self, qa, post=None, init=None, defects=None, maxit=60):
        """Output pose (4x4, base frame) for actuated values qa; parallel: loops closed (from
        ``init``, the passive values of a nearby solution, else by continuation from home).
        Returns (T, full joint dict or None, closure residual)."""
        if not self.parallel:
            T, _ = self.serial_frames(qa, post, defects)
            return T, None, 0.0
        if init is None:
            q, r = self.kin.solve_path(qa, defects)
        else:
            q, r = self.kin.solve(qa, defects, init=init, maxit=maxit)
        return self.kin.output_pose(q, defects), q, r

    def passive_vector(self, q):
        return np.array([q[n] for n in self.kin.passive])

    def output_jacobian(self, q, defects=()):
        """Derivatives of the output pose (list of 4x4) with respect to the actuated joints and the
        given defects, the passive joints following the closures (least squares)."""
        names = list(self.actuated) + list(defects)
        if not self.parallel:
            _, To, _, dTo = self.kin.derivatives(q, names)
            return To, dTo
        pas = list(self.kin.passive)
        r0, To, dr, dTo = self.kin.derivatives(q, names + pas)
        n = len(names)
        A = dr[:, n:]
        B = dr[:, :n]
        X = -np.linalg.lstsq(A, B, rcond=1e-10)[0]  # dpassive / dvar
        out = []
        for k in range(n):
            D = dTo[k].copy()
            for i in range(len(pas)):
                D = D + dTo[n + i] * X[i, k]
            out.append(D)
        return To, out

    def gravity(self, qa, q_full=None, payload=0.0):
        """Generalized gravity forces tau_j = -dV/dq_j (N mm revolute, N prismatic) of the declared
        masses (serial: link masses; parallel: moving mass at the output origin) and the payload at
        the output origin, and the base moment M = sum c x m g (N mm).  Returns (tau dict, M)."""
        if not self.parallel:
            T, jf = self.serial_frames(qa)
            bodies = []
            if self.masses:
                for j, v in self.masses.items():
                    c = (jf[j] @ self._com_local[j])[:3]
                    bodies.append((j, float(v["mass"]), c))
            order = [e.name for e in self.elements if e.kind == "joint"]
            tau = {}
            for j in self.actuated:
                o, z = jf[j][:3, 3], jf[j][:3, 2]
                idx = order.index(j)
                t = 0.0
                items = [(b, m, c) for b, m, c in bodies if order.index(b) >= idx]
                items.append((None, payload, T[:3, 3]))
                for _, m, c in items:
                    f = m * GVEC
                    if self.types[j] == "R":
                        t += z @ np.cross(c - o, f)
                    else:
                        t += z @ f
                tau[j] = float(t)
            M = sum(np.cross(c, m * GVEC) for _, m, c in bodies) + np.cross(T[:3, 3], payload * GVEC)
            return tau, M
        m = float(self.moving_mass or 0.0) + payload
        To, dTo = self.output_jacobian(q_full)
        # V = m g z  ->  tau = -dV/dq = -m g dz/dq
        tau = {j: float(-m * G * dTo[k][2, 3]) for k, j in enumerate(self.actuated)}
        M = np.cross(To[:3, 3], m * GVEC)
        return tau, M


def potential(machine, qa, payload=0.0):
    """Potential energy (N mm) of the declared masses and payload: for the self-check of gravity."""
    if not machine.parallel:
        T, jf = machine.serial_frames(qa)
        V = payload * G * T[2, 3]
        for j, v in (machine.masses or {}).items():
            V += float(v["mass"]) * G * (jf[j] @ machine._com_local[j])[2]
        return V
    T, _, _ = machine.pose(qa)
    return (float(machine.moving_mass or 0.0) + payload) * G * T[2, 3]


def write_variant(src, dst, masses=None, moving_mass=None, drop_masses=False, screw_lead=None):
    """A copy of a model file with metadata changed (masses added or removed)."""
    with open(src) as f:
        d = json.load(f)
    meta = d.setdefault("metadata", {})
    if drop_masses:
        meta.pop("masses", None)
    if masses is not None:
        meta["masses"] = masses
    if moving_mass is not None:
        meta["moving_mass"] = moving_mass
        meta["com"] = [0.0, 0.0, 0.0]
    if screw_lead is not None:
        meta["screw_lead"] = screw_lead
    tmp = dst + ".tmp"
    with open(tmp, "w") as f:
        json.dump(d, f, indent=1)
    os.replace(tmp, dst)
    return dst


def mdh_product(rows, tool_z, q):
    """Own modified-DH (Craig) product: T = prod Rx(alpha) Tx(a) Rz(theta + q) Tz(d), then the tool."""
    T = np.eye(4)
    for (alpha, a, theta, d), v in zip(rows, q):
        ca, sa = np.cos(alpha), np.sin(alpha)
        ct, st = np.cos(theta + v), np.sin(theta + v)
        Rx = np.array([[1, 0, 0, a], [0, ca, -sa, 0], [0, sa, ca, 0], [0, 0, 0, 1.0]])
        Rz = np.array([[ct, -st, 0, 0], [st, ct, 0, 0], [0, 0, 1, d], [0, 0, 0, 1.0]])
        T = T @ Rx @ Rz
    Tt = np.eye(4)
    Tt[2, 3] = tool_z
    return T @ Tt


__all__ = ["Machine", "rot_about_line", "potential", "write_variant", "mdh_product", "placement_matrix"]
