"""Independent kinematics for the blind closure set 2 (mm, rad).

Written from docs/model-format.md and docs/controller-format.md only; imports no hyperstat code.

Element matrix (model-format.md, "Elements" and "Defects"):
    D = Trans(origin + (da, db, dc)) * Rmin(n0 -> n) * R0 * Rz(dG),
    n = (n0 + (dI, dJ, dK)) / |n0 + (dI, dJ, dK)|,  n0 = nominal z axis in the previous frame,
    R0 = [x_axis, y_axis, z_axis] (columns), Rmin the minimal rotation taking n0 to n.
A joint then moves its frame by Rz(q) (R, rad) or Tz(q) (P, mm).  A chain is the product of its
elements from its start frame.  The first chain reaching a frame defines it; every later chain
reaching it closes a loop (6 scalar equations: rotation log and position difference).
"""
from __future__ import annotations

import json
import math

import numpy as np

COMPONENTS = ("I", "J", "K", "a", "b", "c", "G")


# ---------------------------------------------------------------- small rigid-body helpers
def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def rot_axis_angle(axis, angle):
    axis = unit(axis)
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    C = 1.0 - c
    return np.array([[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
                     [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
                     [z * x * C - y * s, z * y * C + x * s, c + z * z * C]])


def rotvec_to_R(rv):
    rv = np.asarray(rv, dtype=float)
    th = np.linalg.norm(rv)
    if th < 1e-300:
        return np.eye(3)
    return rot_axis_angle(rv / th, th)


def R_to_rotvec(R):
    c = (np.trace(R) - 1.0) / 2.0
    c = min(1.0, max(-1.0, c))
    th = math.acos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-7:
        return 0.5 * w
    if th > math.pi - 1e-6:
        # near pi: axis from the symmetric part
        A = (R + np.eye(3)) / 2.0
        i = int(np.argmax(np.diag(A)))
        ax = A[:, i] / math.sqrt(max(A[i, i], 1e-300))
        return ax * th
    return w * th / (2.0 * math.sin(th))


def Rmin(n0, n):
    """Minimal rotation taking unit n0 onto unit n."""
    n0 = unit(n0)
    n = unit(n)
    ax = np.cross(n0, n)
    s = np.linalg.norm(ax)
    c = float(np.dot(n0, n))
    if s < 1e-300:
        if c > 0:
            return np.eye(3)
        raise ValueError("axis reversed")
    return rot_axis_angle(ax / s, math.atan2(s, c))


def Hmat(R, p):
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def Rz(q):
    c, s = math.cos(q), math.sin(q)
    T = np.eye(4)
    T[0, 0] = c
    T[0, 1] = -s
    T[1, 0] = s
    T[1, 1] = c
    return T


def Tz(q):
    T = np.eye(4)
    T[2, 3] = q
    return T


def inv_h(T):
    R = T[:3, :3]
    p = T[:3, 3]
    return Hmat(R.T, -R.T @ p)


def placement_matrix(pl, dv=None):
    """D of an element: placement dict plus defect values by component letter."""
    dv = dv or {}
    z0 = np.asarray(pl["z_axis"], float)
    x0 = np.asarray(pl["x_axis"], float)
    y0 = np.cross(z0, x0)
    R0 = np.column_stack([x0, y0, z0])
    dn = np.array([dv.get("I", 0.0), dv.get("J", 0.0), dv.get("K", 0.0)])
    n = unit(z0 + dn)
    R = Rmin(z0, n) @ R0
    G = dv.get("G", 0.0)
    if G:
        R = R @ Rz(G)[:3, :3]
    o = np.asarray(pl["origin"], float) + np.array([dv.get("a", 0.0), dv.get("b", 0.0), dv.get("c", 0.0)])
    return Hmat(R, o)


def defect_entries(el):
    """[(component, public name)] of an element (default name d<comp><element name>)."""
    out = []
    for d in el.get("defects", []) or []:
        if isinstance(d, str):
            out.append((d, "d%s%s" % (d, el["name"])))
        else:
            out.append((d["component"], d.get("name", "d%s%s" % (d["component"], el["name"]))))
    return out


# ---------------------------------------------------------------- the mechanism
class Mechanism:
    """A model file (dict) with defect values (by public name) applied."""

    def __init__(self, model: dict, defects: dict | None = None):
        self.model = model
        defects = defects or {}
        self.base = model["base"]
        self.output = model["output"]
        self.chains = []
        self.joints = []  # (name, type, role, range, home)
        known = set()
        for ch in model["chains"]:
            els = []
            for el in ch["elements"]:
                if el["kind"] == "frame":
                    D = placement_matrix(el["placement"])
                else:
                    dv = {}
                    for comp, name in defect_entries(el):
                        known.add(name)
                        v = float(defects.get(name, 0.0))
                        dv[comp] = dv.get(comp, 0.0) + v
                    D = placement_matrix(el["placement"], dv)
                jt = None
                if el["kind"] == "joint":
                    jt = el["type"]
                    self.joints.append((el["name"], el["type"], el["role"], tuple(el["range"]), float(el["home"])))
                els.append((D, jt, el["name"]))
            self.chains.append((ch["start"], ch["end"], els))
        unknown = set(defects) - known
        if unknown:
            raise KeyError("defects not in the model: %s" % sorted(unknown))
        self.jindex = {j[0]: i for i, j in enumerate(self.joints)}
        self.actuated = [j[0] for j in self.joints if j[2] == "actuated"]
        self.passive = [j[0] for j in self.joints if j[2] != "actuated"]
        self.a_idx = np.array([self.jindex[n] for n in self.actuated], dtype=int)
        self.p_idx = np.array([self.jindex[n] for n in self.passive], dtype=int)
        self.home = np.array([j[4] for j in self.joints])
        self.jtype = [j[1] for j in self.joints]
        self.L = length_scale(model)
        # scale of each passive column: rad 1, mm 1/L
        self.p_scale = np.array([1.0 if self.jtype[i] == "R" else 1.0 / self.L for i in self.p_idx])
        self.nloops = 0
        defined = {self.base}
        for s, e, _ in self.chains:
            if e in defined:
                self.nloops += 1
            defined.add(e)

    def frames(self, q):
        F = {self.base: np.eye(4)}
        closures = []
        for start, end, els in self.chains:
            T = F[start].copy()
            for D, jt, name in els:
                T = T @ D
                if jt == "R":
                    T = T @ Rz(q[self.jindex[name]])
                elif jt == "P":
                    T = T @ Tz(q[self.jindex[name]])
            if end in F:
                closures.append((F[end], T))
            else:
                F[end] = T
        return F, closures

    def residual(self, q):
        """Closure residual: per loop rotation log (rad, times L) and position difference (mm)."""
        _, cl = self.frames(q)
        out = []
        for A, B in cl:
            dR = A[:3, :3].T @ B[:3, :3]
            out.append(R_to_rotvec(dR) * self.L)
            out.append(B[:3, 3] - A[:3, 3])
        return np.concatenate(out) if out else np.zeros(0)

    def closure_error(self, q):
        """(max position error mm, max rotation error rad) over the loops."""
        _, cl = self.frames(q)
        pe, re = 0.0, 0.0
        for A, B in cl:
            pe = max(pe, float(np.linalg.norm(B[:3, 3] - A[:3, 3])))
            re = max(re, float(np.linalg.norm(R_to_rotvec(A[:3, :3].T @ B[:3, :3]))))
        return pe, re

    def jac_p(self, q, r0=None, h=1e-7):
        if r0 is None:
            r0 = self.residual(q)
        J = np.empty((r0.size, self.p_idx.size))
        for k, i in enumerate(self.p_idx):
            step = h if self.jtype[i] == "R" else h * self.L
            qq = q.copy()
            qq[i] += step
            J[:, k] = (self.residual(qq) - r0) / step
        return J

    def condition(self, q):
        """sigma_min / sigma_max of the passive closure Jacobian (columns in rad or mm/L)."""
        if self.p_idx.size == 0 or self.nloops == 0:
            return 1.0
        J = self.jac_p(q) / self.p_scale[None, :]
        s = np.linalg.svd(J, compute_uv=False)
        return float(s[self.p_idx.size - 1] / s[0])

    def newton(self, q, tol=1e-12, maxit=25):
        q = q.copy()
        r = self.residual(q)
        it = 0
        first = None
        while np.max(np.abs(r)) > tol and it < maxit:
            J = self.jac_p(q, r)
            dq = -np.linalg.lstsq(J, r, rcond=None)[0]
            if first is None:
                first = float(np.max(np.abs(dq * self.p_scale)))
            q[self.p_idx] += dq
            r_new = self.residual(q)
            it += 1
            if np.max(np.abs(r_new)) > 0.999 * np.max(np.abs(r)) and np.max(np.abs(dq)) < 1e-14:
                r = r_new
                break
            r = r_new
        return q, float(np.max(np.abs(r))) if r.size else 0.0, it, (first or 0.0)

    def assemble_home(self):
        """Close the loops at the nominal home values (Newton from them)."""
        q, res, it, _ = self.newton(self.home.copy())
        return q, res

    def follow(self, q0, qa1, step=0.04, cond_min=0.0, jump=0.05, tol=1e-12, accept=1e-9):
        """Continuation from the assembled q0 to actuated values qa1 along a straight segment.

        Returns (q, info) with info: ok, min_cond, max_residual, reason."""
        q = q0.copy()
        qa0 = q0[self.a_idx].copy()
        qa1 = np.asarray(qa1, float)
        d = qa1 - qa0
        scale = np.array([1.0 if self.jtype[i] == "R" else 1.0 / self.L for i in self.a_idx])
        n = max(1, int(math.ceil(np.max(np.abs(d) * scale) / step))) if d.size else 1
        info = {"ok": True, "min_cond": 1.0, "max_residual": 0.0, "reason": ""}
        prev_dp = None
        if self.nloops == 0:
            q[self.a_idx] = qa1
            return q, info
        for k in range(1, n + 1):
            qa = qa0 + d * (k / n)
            qp_start = q[self.p_idx].copy()
            trial = q.copy()
            trial[self.a_idx] = qa
            if prev_dp is not None:
                trial[self.p_idx] += prev_dp  # secant predictor
            trial, res, it, first = self.newton(trial, tol=tol)
            if res > accept:
                info.update(ok=False, reason="Newton did not close the loops (residual %.3g) at step %d/%d" % (res, k, n))
                return trial, info
            move = np.max(np.abs((trial[self.p_idx] - qp_start) * self.p_scale))
            if move > jump + 4 * step:
                info.update(ok=False, reason="passive joints jumped by %.3g at step %d/%d" % (move, k, n))
                return trial, info
            if cond_min > 0.0:
                c = self.condition(trial)
                info["min_cond"] = min(info["min_cond"], c)
                if c < cond_min:
                    info.update(ok=False, reason="near a singularity (condition %.3g) at step %d/%d" % (c, k, n))
                    return trial, info
            prev_dp = trial[self.p_idx] - qp_start
            q = trial
            info["max_residual"] = max(info["max_residual"], res)
        return q, info

    def tool_point(self, q, target):
        F, _ = self.frames(q)
        T = F[self.output]
        return T[:3, :3] @ np.asarray(target, float) + T[:3, 3]

    def output_pose(self, q):
        F, _ = self.frames(q)
        return F[self.output]


def length_scale(model) -> float:
    """Mean distance of the element origins (nominal) from the base origin's neighbours: our own scale."""
    d = []
    for ch in model["chains"]:
        for el in ch["elements"]:
            o = np.asarray(el["placement"]["origin"], float)
            n = float(np.linalg.norm(o))
            if n > 1e-9:
                d.append(n)
    return float(np.mean(d)) if d else 1.0


def kabsch(P, Q):
    """Rigid (R, t) minimising |R P_i + t - Q_i|^2."""
    P = np.asarray(P, float)
    Q = np.asarray(Q, float)
    cp, cq = P.mean(0), Q.mean(0)
    H = (P - cp).T @ (Q - cq)
    U, S, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, float(np.sign(np.linalg.det(Vt.T @ U.T)))])
    R = Vt.T @ D @ U.T
    return R, cq - R @ cp


def load_json(path):
    with open(path) as f:
        return json.load(f)
