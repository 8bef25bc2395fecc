"""Own kinematics for the blind closure set (does NOT import hyperstat).

Reads the documented model format (docs/model-format.md) and evaluates it:
element frame D(xi) = (R, o) with o = o0 + (da, db, dc),
n = (n0 + (dI, dJ, dK)) / |n0 + (dI, dJ, dK)|,  R = Rot(n, G) Rmin(n0 -> n) R0,
R0 = [x0, y0 = z0 x x0, z0] (columns), then a joint moves its frame by Rz(q) (R) or Tz(q) (P).
Loop closures are solved by damped Gauss-Newton (min-norm least squares) on the passive joints,
followed by continuation in the actuated values.  Units: mm, rad.
"""
import json
import math

import numpy as np


def rot_axis(n, a):
    n = np.asarray(n, float)
    n = n / np.linalg.norm(n)
    K = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


def rmin(n0, n):
    """Minimal rotation taking unit n0 to unit n."""
    n0 = np.asarray(n0, float)
    n = np.asarray(n, float)
    c = float(np.dot(n0, n))
    v = np.cross(n0, n)
    s = np.linalg.norm(v)
    if s < 1e-300:
        return np.eye(3)
    return rot_axis(v / s, math.atan2(s, c))


def rotvec(rv):
    rv = np.asarray(rv, float)
    a = np.linalg.norm(rv)
    if a < 1e-300:
        return np.eye(3)
    return rot_axis(rv / a, a)


def log_so3(R):
    c = max(-1.0, min(1.0, (np.trace(R) - 1) / 2))
    a = math.acos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if a < 1e-12:
        return 0.5 * w
    return a / (2 * math.sin(a)) * w


def hom(R, o):
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = o
    return T


def placement_R(pl):
    z = np.asarray(pl["z_axis"], float)
    x = np.asarray(pl["x_axis"], float)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


def placement_from_T(T):
    return {"origin": [float(v) for v in T[:3, 3]],
            "z_axis": [float(v) for v in T[:3, 2]],
            "x_axis": [float(v) for v in T[:3, 0]]}


def element_matrix(el, defects):
    """D(xi) of one element (4x4) with the defect values (dict name -> value)."""
    pl = el["placement"]
    R0 = placement_R(pl)
    o0 = np.asarray(pl["origin"], float)
    d = {"I": 0.0, "J": 0.0, "K": 0.0, "a": 0.0, "b": 0.0, "c": 0.0, "G": 0.0}
    for comp, name in defect_names(el):
        d[comp] = float(defects.get(name, 0.0))
    n0 = R0[:, 2]
    n = n0 + np.array([d["I"], d["J"], d["K"]])
    n = n / np.linalg.norm(n)
    R = rot_axis(n, d["G"]) @ rmin(n0, n) @ R0
    o = o0 + np.array([d["a"], d["b"], d["c"]])
    return hom(R, o)


def defect_names(el):
    out = []
    for dd in el.get("defects", []) or []:
        if isinstance(dd, dict):
            out.append((dd["component"], dd.get("name") or default_name(dd["component"], el)))
        else:
            out.append((dd, default_name(dd, el)))
    return out


def default_name(comp, el):
    # only used if a model gives bare letters; our models always name their defects
    pre = "d" + comp if comp in "IJKG" else "d" + comp
    return pre + el["name"]


def placement_to_defects(R0, o0, R, o):
    """Inverse of element_matrix for one element: (dI,dJ,dK,da,db,dc,G)."""
    n0 = R0[:, 2]
    n = R[:, 2]
    dn = n - n0
    Rm = rmin(n0, n)
    Rres = R @ (Rm @ R0).T  # = Rot(n, G)
    x1 = (Rm @ R0)[:, 0]
    x2 = R[:, 0]
    G = math.atan2(float(np.dot(np.cross(x1, x2), n)), float(np.dot(x1, x2)))
    chk = rot_axis(n, G)
    assert np.abs(chk - Rres).max() < 1e-10, "placement_to_defects: residual rotation not about n"
    return dn, o - o0, G


class Mechanism:
    """A model file (dict) with defect values, evaluated by our own code."""

    def __init__(self, model, defects=None):
        self.model = model
        self.defects = dict(defects or {})
        self.base = model["base"]
        self.output = model["output"]
        self.joints = []  # (name, type, role, range, home)
        self.chains = []
        for ch in model["chains"]:
            els = []
            for el in ch["elements"]:
                D = element_matrix(el, self.defects) if el["kind"] != "frame" else hom(
                    placement_R(el["placement"]), el["placement"]["origin"])
                if el["kind"] == "joint":
                    self.joints.append((el["name"], el["type"], el["role"], el["range"], el["home"]))
                    els.append(("joint", D, el["name"], el["type"]))
                else:
                    els.append(("static", D, el["name"], None))
            self.chains.append((ch["start"], ch["end"], els))
        self.jindex = {j[0]: i for i, j in enumerate(self.joints)}
        self.act = [i for i, j in enumerate(self.joints) if j[2] == "actuated"]
        self.pas = [i for i, j in enumerate(self.joints) if j[2] != "actuated"]
        self.home = np.array([j[4] for j in self.joints], float)
        # length scale for mixing residuals
        self.L = 100.0
        self.accept = 1e-9

    def frames(self, q):
        """Returns (dict frame -> 4x4, closure residual vector)."""
        F = {self.base: np.eye(4)}
        res = []
        for start, end, els in self.chains:
            T = F[start].copy()
            for kind, D, name, jt in els:
                T = T @ D
                if kind == "joint":
                    v = q[self.jindex[name]]
                    if jt == "R":
                        c, s = math.cos(v), math.sin(v)
                        T = T @ np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
                    else:
                        M = np.eye(4)
                        M[2, 3] = v
                        T = T @ M
            if end in F:
                A = F[end]
                dp = T[:3, 3] - A[:3, 3]
                # full rotation-matrix difference (a skew-part residual vanishes at a half turn)
                res.append(dp)
                res.append((T[:3, :3] - A[:3, :3]).ravel() * self.L)
            else:
                F[end] = T
        r = np.concatenate(res) if res else np.zeros(0)
        return F, r

    def residual(self, q):
        return self.frames(q)[1]

    def solve(self, q0, tol=1e-11, maxit=60, maxstep=0.2, accept=None):
        """Newton on the passive joints from q0 (actuated fixed). Returns (q, |r|, ok);
        stops at |r| < tol or when the step vanishes (least squares); ok: |r| < accept."""
        accept = self.accept if accept is None else accept
        q = np.array(q0, float)
        if not self.pas:
            return q, 0.0, True
        r = self.residual(q)
        nr = np.linalg.norm(r)
        h = 1e-7
        for _ in range(maxit):
            if nr < tol:
                return q, nr, True
            J = np.empty((len(r), len(self.pas)))
            for k, i in enumerate(self.pas):
                qq = q.copy()
                qq[i] += h
                J[:, k] = (self.residual(qq) - r) / h
            dx = np.linalg.lstsq(J, -r, rcond=1e-12)[0]
            m = np.abs(dx).max()
            if m > maxstep:
                dx *= maxstep / m
            lam = 1.0
            while True:
                qn = q.copy()
                qn[self.pas] += lam * dx
                rn = self.residual(qn)
                if np.linalg.norm(rn) < nr or lam < 1e-4:
                    break
                lam *= 0.5
            small = np.abs(qn - q).max() < 1e-14
            q, r, nr = qn, rn, np.linalg.norm(rn)
            if small:
                break
        return q, nr, nr < accept

    def passive_jacobian_sv(self, q):
        r = self.residual(q)
        if not self.pas:
            return 1.0
        h = 1e-7
        J = np.empty((len(r), len(self.pas)))
        for k, i in enumerate(self.pas):
            qq = q.copy()
            qq[i] += h
            J[:, k] = (self.residual(qq) - r) / h
        s = np.linalg.svd(J, compute_uv=False)
        return float(s[-1] / s[0])

    def step_sizes(self):
        return np.array([0.02 if self.joints[i][1] == "R" else 1.0 for i in self.act])

    def continue_to(self, q, qa_target, jump=0.3):
        """Continuation from the assembled q to actuated values qa_target.
        Returns (q, max residual, max passive jump per step, ok)."""
        q = np.array(q, float)
        qa0 = q[self.act].copy()
        qa1 = np.asarray(qa_target, float)
        n = int(max(1, math.ceil(np.max(np.abs(qa1 - qa0) / self.step_sizes()))))
        worst_r, worst_j = 0.0, 0.0
        t_prev = 0.0
        qprev_full = q.copy()
        k = 1
        sub = 1.0 / n
        t = 0.0
        while t < 1.0 - 1e-15:
            tn = min(1.0, t + sub)
            qt = qprev_full.copy()
            qt[self.act] = qa0 + tn * (qa1 - qa0)
            qs, nr, ok = self.solve(qt)
            jmp = np.abs(qs[self.pas] - qprev_full[self.pas]).max() if self.pas else 0.0
            if (not ok or jmp > jump) and sub > 1e-4 / n:
                sub *= 0.5
                continue
            if not ok:
                return qs, nr, jmp, False
            worst_r = max(worst_r, nr)
            worst_j = max(worst_j, jmp)
            qprev_full = qs
            t = tn
        return qprev_full, worst_r, worst_j, True

    def follow(self, qa_list, q_start=None):
        """From home (assembled), through every actuated vector in order."""
        q = self.home.copy() if q_start is None else np.array(q_start, float)
        q, nr, ok = self.solve(q)
        if not ok:
            raise RuntimeError("home does not assemble (residual %.3g)" % nr)
        out = []
        for qa in qa_list:
            q, wr, wj, ok = self.continue_to(q, qa)
            if not ok:
                raise RuntimeError("continuation failed at %s" % (qa,))
            out.append(q.copy())
        return out

    def tool(self, q, target):
        F, r = self.frames(q)
        T = F[self.output]
        return T[:3, :3] @ np.asarray(target, float) + T[:3, 3], T, r


def load(path):
    with open(path) as f:
        return json.load(f)


def kabsch(P, Q):
    """Best rigid (R, t) with R P_i + t ~ Q_i; returns (R, t, rms)."""
    P = np.asarray(P, float)
    Q = np.asarray(Q, float)
    cp, cq = P.mean(0), Q.mean(0)
    H = (P - cp).T @ (Q - cq)
    U, S, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    D = np.diag([1, 1, d])
    R = Vt.T @ D @ U.T
    t = cq - R @ cp
    E = (P @ R.T + t) - Q
    return R, t, float(np.sqrt((E ** 2).sum(1).mean()))
