"""Own kinematics of a hyperstat model file (docs/model-format.md), numpy only.

Units: mm, rad.  Every element's frame is placed in the previous frame by its placement
(origin, z axis, x axis); a joint then moves by Rz(q) (R) or Tz(q) (P).  The first chain
reaching a frame defines it; every other chain reaching it closes a loop (6 equations).
Loops are closed by Gauss-Newton on the passive joints.  Geometric defects (for the
visibility fit only) perturb a placement: I, J, K tilt the axis (rotation vector n0 x dn in
the previous frame), G turns about the axis, a, b, c shift the origin.
"""
from __future__ import annotations

import json
import numpy as np

__all__ = ["Model", "expm", "logm", "skew"]


def skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def expm(r):
    r = np.asarray(r, float)
    t = np.linalg.norm(r)
    if t < 1e-12:
        return np.eye(3) + skew(r)
    k = skew(r / t)
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k


def logm(R):
    c = np.clip((np.trace(R) - 1) / 2, -1, 1)
    t = np.arccos(c)
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if t < 1e-9:
        return v / 2
    if np.pi - t < 1e-6:
        # near pi: axis from the symmetric part
        w, V = np.linalg.eigh((R + R.T) / 2)
        ax = V[:, np.argmax(w)]
        return ax * t
    return v * t / (2 * np.sin(t))


def placement_matrix(p):
    z = np.asarray(p["z_axis"], float)
    x = np.asarray(p["x_axis"], float)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2] = x, y, z
    T[:3, 3] = p["origin"]
    return T


class Model:
    """A model file read for its geometry; `defect_names` lists every (element, component)."""

    def __init__(self, path):
        self.data = json.load(open(path))
        self.base = self.data["base"]
        self.output = self.data["output"]
        self.elements = []  # (chain index, element dict, D matrix)
        self.chains = []
        defined = {self.base}
        pending = list(self.data["chains"])
        order = []
        while pending:  # dependency order
            for c in list(pending):
                if c["start"] in defined:
                    order.append(c)
                    defined.add(c["end"])
                    pending.remove(c)
                    break
            else:
                raise ValueError("chains do not reach the base")
        self.chains = order
        self.joints = {}
        self.defects = []  # (element name, component)
        for c in order:
            for e in c["elements"]:
                e["_D"] = placement_matrix(e["placement"])
                if e["kind"] == "joint":
                    self.joints[e["name"]] = e
                for comp in e.get("defects", []) or []:
                    comp = comp["component"] if isinstance(comp, dict) else comp
                    self.defects.append((e["name"], comp))
        self.actuated = [n for n, e in self.joints.items() if e["role"] == "actuated"]
        self.passive = [n for n, e in self.joints.items() if e["role"] != "actuated"]
        self.has_loops = any(
            c["end"] in {d["end"] for d in order[:i]} or c["end"] == self.base for i, c in enumerate(order))
        self.home = {n: float(e["home"]) for n, e in self.joints.items()}
        self.range = {n: tuple(e["range"]) for n, e in self.joints.items()}
        self.types = {n: e["type"] for n, e in self.joints.items()}

    # ------------------------------------------------------------------
    def _elem_D(self, e, dvec):
        D = e["_D"]
        if not dvec:
            return D
        mine = dvec.get(e["name"])
        if not mine:
            return D
        D = D.copy()
        n0 = D[:3, 2]
        r = np.zeros(3)
        dn = np.array([mine.get("I", 0.0), mine.get("J", 0.0), mine.get("K", 0.0)])
        r += np.cross(n0, dn)
        r += mine.get("G", 0.0) * n0
        D[:3, :3] = expm(r) @ D[:3, :3]
        D[:3, 3] += [mine.get("a", 0.0), mine.get("b", 0.0), mine.get("c", 0.0)]
        return D

    def frames(self, q, dvec=None):
        """Frames of every chain end; returns (defined frames, list of closure residuals 6-vectors)."""
        F = {self.base: np.eye(4)}
        closures = []
        for c in self.chains:
            T = F[c["start"]].copy()
            for e in c["elements"]:
                T = T @ self._elem_D(e, dvec)
                if e["kind"] == "joint":
                    v = q[e["name"]]
                    M = np.eye(4)
                    if e["type"] == "R":
                        M[:3, :3] = expm([0, 0, v])
                    else:
                        M[2, 3] = v
                    T = T @ M
            if c["end"] in F:
                Tf = F[c["end"]]
                dp = T[:3, 3] - Tf[:3, 3]
                dr = logm(T[:3, :3] @ Tf[:3, :3].T)
                closures.append(np.concatenate([dp, dr * 100.0]))
            else:
                F[c["end"]] = T
        return F, closures

    def closure(self, q, dvec=None):
        _, cl = self.frames(q, dvec)
        return np.concatenate(cl) if cl else np.zeros(0)

    def assemble(self, qa, guess=None, dvec=None, tol=1e-10, iters=40):
        """Close the loops for actuated values qa (dict); returns full q dict or None."""
        q = dict(self.home if guess is None else guess)
        q.update(qa)
        if not self.has_loops or not self.passive:
            return q
        h = 1e-7
        for _ in range(iters):
            c = self.closure(q, dvec)
            if np.max(np.abs(c)) < tol:
                return q
            J = np.zeros((len(c), len(self.passive)))
            for k, n in enumerate(self.passive):
                qq = dict(q)
                qq[n] += h
                J[:, k] = (self.closure(qq, dvec) - c) / h
            step = np.linalg.lstsq(J, -c, rcond=1e-10)[0]
            if np.max(np.abs(step)) > 0.3:
                step *= 0.3 / np.max(np.abs(step))
            for k, n in enumerate(self.passive):
                q[n] += step[k]
        c = self.closure(q, dvec)
        return q if np.max(np.abs(c)) < 1e-7 else None

    def output_pose(self, q, dvec=None):
        F, _ = self.frames(q, dvec)
        return F[self.output]

    def in_range(self, q, margin=0.02):
        for n in self.passive:
            lo, hi = self.range[n]
            if not (lo + margin <= q[n] <= hi - margin):
                return False
        return True
