"""Own kinematics of the seventh blind generator (numpy only; shares no code with hyperstat).

Units: mm and rad.  Reads the *geometry* of a hyperstat model file (``*.skel.json``, format
described in docs/model-format.md: chains of elements, each element's placement an origin, a
z axis and an x axis, a joint moving about / along its z axis) and assembles it with its own
Newton solver on the loop closures.  Written from the format's description only.
"""
from __future__ import annotations

import json

import numpy as np


def rot_vec(w):
    """Rotation matrix of a rotation vector (Rodrigues)."""
    w = np.asarray(w, float)
    th = np.linalg.norm(w)
    if th < 1e-15:
        k = np.zeros((3, 3))
        k[0, 1], k[0, 2], k[1, 2] = -w[2], w[1], -w[0]
        k[1, 0], k[2, 0], k[2, 1] = w[2], -w[1], w[0]
        return np.eye(3) + k
    a = w / th
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(th) * k + (1 - np.cos(th)) * k @ k


def log_rot(r):
    """Rotation vector of a rotation matrix."""
    c = np.clip((np.trace(r) - 1) / 2, -1.0, 1.0)
    th = np.arccos(c)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if th < 1e-9:
        return v / 2
    if np.pi - th < 1e-6:
        # near a half turn: axis from the symmetric part
        b = (r + np.eye(3)) / 2
        ax = b[:, np.argmax(np.diag(b))]
        ax = ax / np.linalg.norm(ax)
        return th * ax
    return th / (2 * np.sin(th)) * v


def hom(r, t):
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = t
    return m


def placement(pl):
    z = np.asarray(pl["z_axis"], float)
    x = np.asarray(pl["x_axis"], float)
    y = np.cross(z, x)
    return hom(np.column_stack([x, y, z]), pl["origin"])


def motion(kind, q):
    if kind == "R":
        c, s = np.cos(q), np.sin(q)
        return hom(np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]), np.zeros(3))
    return hom(np.eye(3), [0, 0, q])


def small(d):
    """Homogeneous transform of a 6-vector (rotation vector, translation)."""
    return hom(rot_vec(d[:3]), d[3:])


class Model:
    """A mechanism read from a hyperstat model file: its chains, actuated and passive joints."""

    def __init__(self, path):
        with open(path) as f:
            m = json.load(f)
        self.name = m["name"]
        self.base = m["base"]
        self.output = m["output"]
        self.metadata = m.get("metadata", {})
        self.chains = []
        self.actuated, self.passive, self.kinds, self.ranges, self.home = [], [], {}, {}, {}
        self.elements = []  # names of elements that carry a placement defect (joints, fixed)
        for c in m["chains"]:
            els = []
            for e in c["elements"]:
                el = {"kind": e["kind"], "name": e["name"], "T": placement(e["placement"])}
                if e["kind"] == "joint":
                    el["type"] = e["type"]
                    el["role"] = e["role"]
                    self.kinds[e["name"]] = e["type"]
                    self.ranges[e["name"]] = tuple(e["range"])
                    self.home[e["name"]] = float(e["home"])
                    (self.actuated if e["role"] == "actuated" else self.passive).append(e["name"])
                if e["kind"] in ("joint", "fixed"):
                    self.elements.append(e["name"])
                els.append(el)
            self.chains.append({"start": c["start"], "end": c["end"], "elements": els})
        self.pidx = {n: i for i, n in enumerate(self.passive)}
        self.eidx = {n: i for i, n in enumerate(self.elements)}

    # ------------------------------------------------------------------ assembly
    def frames(self, qa, qp, defects=None, extra=None):
        """Frames reached by the chains and the closure residuals (6 per closing chain).

        qa: dict actuated name -> value; qp: passive vector; defects: (n_elements, 6) array of
        placement perturbations (rotation vector, translation, applied after the placement);
        extra: dict actuated name -> 4x4 transform applied after the joint's motion (a bowed guide).
        """
        fr = {self.base: np.eye(4)}
        res = []
        for c in self.chains:
            t = fr[c["start"]].copy()
            for el in c["elements"]:
                t = t @ el["T"]
                if defects is not None and el["name"] in self.eidx:
                    d = defects[self.eidx[el["name"]]]
                    if np.any(d):
                        t = t @ small(d)
                if el["kind"] == "joint":
                    q = qa[el["name"]] if el["role"] == "actuated" else qp[self.pidx[el["name"]]]
                    t = t @ motion(el["type"], q)
                    if extra is not None and el["name"] in extra:
                        t = t @ extra[el["name"]]
            if c["end"] in fr:
                a = fr[c["end"]]
                res.append(np.concatenate([t[:3, 3] - a[:3, 3], log_rot(a[:3, :3].T @ t[:3, :3])]))
            else:
                fr[c["end"]] = t
        return fr, (np.concatenate(res) if res else np.zeros(0))

    def solve(self, qa, qp0=None, defects=None, extra=None, tol=1e-11, iters=40):
        """Passive joints closing every loop (Gauss-Newton, finite-difference Jacobian)."""
        qp = np.array([self.home[n] for n in self.passive]) if qp0 is None else np.array(qp0, float)
        if not self.passive:
            fr, r = self.frames(qa, qp, defects, extra)
            return qp, fr, 0.0
        h = 1e-7
        for _ in range(iters):
            fr, r = self.frames(qa, qp, defects, extra)
            if np.linalg.norm(r) < tol:
                break
            j = np.empty((r.size, qp.size))
            for k in range(qp.size):
                d = qp.copy()
                d[k] += h
                j[:, k] = (self.frames(qa, d, defects, extra)[1] - r) / h
            step = np.linalg.lstsq(j, -r, rcond=1e-10)[0]
            qp = qp + step
        fr, r = self.frames(qa, qp, defects, extra)
        return qp, fr, float(np.linalg.norm(r))

    def in_range(self, qp, margin=0.0):
        for n, v in zip(self.passive, qp):
            lo, hi = self.ranges[n]
            if not (lo + margin <= v <= hi - margin):
                return False
        return True

    # ------------------------------------------------------------------ linearised rigid fit
    def geometry_jacobian(self, qa, qp, points_local, h=1e-6):
        """d(output points)/d(element defects) and d(closure)/d(passive, defects) at an assembly.

        Returns (P_theta, P_q, C_theta, C_q): points stacked (3 per point), base frame.
        """
        ne = len(self.elements) * 6
        def pts(fr):
            t = fr[self.output]
            return np.concatenate([t[:3, :3] @ p + t[:3, 3] for p in points_local])
        fr0, c0 = self.frames(qa, qp)
        p0 = pts(fr0)
        pth = np.empty((p0.size, ne))
        cth = np.empty((c0.size, ne))
        zero = np.zeros((len(self.elements), 6))
        for k in range(ne):
            d = zero.copy()
            d.flat[k] = h
            fr, c = self.frames(qa, qp, defects=d)
            pth[:, k] = (pts(fr) - p0) / h
            cth[:, k] = (c - c0) / h
        pq = np.empty((p0.size, len(self.passive)))
        cq = np.empty((c0.size, len(self.passive)))
        for k in range(len(self.passive)):
            d = np.array(qp, float)
            d[k] += h
            fr, c = self.frames(qa, d)
            pq[:, k] = (pts(fr) - p0) / h
            cq[:, k] = (c - c0) / h
        return pth, pq, cth, cq
