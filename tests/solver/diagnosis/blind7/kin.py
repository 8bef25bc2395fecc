"""Own reading of a hyperstat model file (``*.skel.json``) and its kinematics (numpy only).

Units: mm, rad.  Written for the ninth blind generator (directory ``blind7``) from
``docs/model-format.md`` only: an element's frame is its placement (origin, z axis, x axis in
the previous frame), then for a joint the motion (``R``: a rotation ``q`` about z, ``P``: a
translation ``q`` along z).  The first chain reaching a frame defines it, every other chain
reaching it closes a loop; closures are solved by damped Gauss-Newton on the passive joints
(position + 100 mm x rotation residual).  Small placement defects (axis tilts, origin shifts,
turn about z) are spanned for the rigid visibility fit, in the spirit of the file's
``I J K a b c G`` components (the span, not hyperstat's exact parameterisation).
"""
from __future__ import annotations

import json

import numpy as np

ROT_LEVER = 100.0  # mm: rotation part of a closure residual


def rotz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0, 0.0], [s, c, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


def motion(T, typ, v):
    """T @ Rz(v) (revolute) or T @ Tz(v) (prismatic), without building the matrix."""
    out = T.copy()
    if typ == "R":
        c, s = np.cos(v), np.sin(v)
        out[:, 0] = c * T[:, 0] + s * T[:, 1]
        out[:, 1] = -s * T[:, 0] + c * T[:, 1]
    else:
        out[:, 3] = T[:, 3] + v * T[:, 2]
    return out


def transz(d):
    T = np.eye(4)
    T[2, 3] = d
    return T


def rotvec_to_R(v):
    v = np.asarray(v, float)
    th = np.linalg.norm(v)
    if th < 1e-15:
        return np.eye(3)
    k = v / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def R_to_rotvec(R):
    """Rotation vector of a rotation matrix (scipy, robust near pi)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_matrix(R).as_rotvec()


def placement_matrix(pl):
    o = np.asarray(pl["origin"], float)
    z = np.asarray(pl["z_axis"], float)
    x = np.asarray(pl["x_axis"], float)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, o
    return T


class Element:
    def __init__(self, d):
        self.kind = d["kind"]
        self.name = d["name"]
        self.type = d.get("type")
        self.role = d.get("role")
        self.range = d.get("range")
        self.home = d.get("home")
        self.T0 = placement_matrix(d["placement"])
        self.defects = []
        for c in d.get("defects", []):
            self.defects.append(c["component"] if isinstance(c, dict) else c)


def defect_transform(T0, comp, eps):
    """Placement T0 perturbed by eps along one defect component (previous frame)."""
    T = T0.copy()
    if comp in "IJK":
        e = np.zeros(3)
        e["IJK".index(comp)] = 1.0
        n0 = T0[:3, 2]
        w = np.cross(n0, e) * eps  # minimal rotation taking n0 towards n0 + eps e
        T[:3, :3] = rotvec_to_R(w) @ T0[:3, :3]
    elif comp in "abc":
        T[:3, 3] = T0[:3, 3] + eps * np.eye(3)["abc".index(comp)]
    elif comp == "G":
        T = T0 @ rotz(eps)
    return T


class Model:
    def __init__(self, path):
        with open(path) as f:
            self.data = json.load(f)
        d = self.data
        self.base = d["base"]
        self.output = d["output"]
        self.chains = []
        for c in d["chains"]:
            self.chains.append((c["name"], c["start"], c["end"], [Element(e) for e in c["elements"]]))
        self.joints = {}
        for _, _, _, els in self.chains:
            for e in els:
                if e.kind == "joint":
                    self.joints[e.name] = e
        self.actuated = [n for n, e in self.joints.items() if e.role == "actuated"]
        self.passive = [n for n, e in self.joints.items() if e.role != "actuated"]
        self.defect_list = []  # (element name, component)
        for _, _, _, els in self.chains:
            for e in els:
                for comp in e.defects:
                    self.defect_list.append((e.name, comp))
        # chains in dependency order: defining chains and closing chains
        defined = {self.base}
        self.order = []
        pending = list(range(len(self.chains)))
        while pending:
            progressed = False
            for i in list(pending):
                name, start, end, els = self.chains[i]
                if start in defined:
                    closes = end in defined
                    self.order.append((i, closes))
                    defined.add(end)
                    pending.remove(i)
                    progressed = True
            if not progressed:
                raise ValueError("chains do not reach the base")
        self.closing = any(c for _, c in self.order)
        self._last_passive = np.array([self.joints[n].home for n in self.passive], float)

    # -- forward pass -------------------------------------------------------------------
    def frames(self, q, defects=None):
        """Every frame's pose (4x4) for joint values q (dict name -> value).

        Returns (frames, closure residual vector, joint frames dict)."""
        defects = defects or {}
        F = {self.base: np.eye(4)}
        jf = {}
        res = []
        for i, closes in self.order:
            name, start, end, els = self.chains[i]
            T = F[start].copy()
            for e in els:
                T0 = e.T0
                if defects:
                    for comp in e.defects:
                        eps = defects.get((e.name, comp))
                        if eps:
                            T0 = defect_transform(T0, comp, eps)
                T = T @ T0
                if e.kind == "joint":
                    T = motion(T, e.type, q[e.name])
                    jf[e.name] = T
                elif e.kind == "fixed":
                    jf[e.name] = T
            if closes:
                Td = F[end]
                dp = T[:3, 3] - Td[:3, 3]
                dR = Td[:3, :3].T @ T[:3, :3]
                w = 0.5 * np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
                res.append(np.concatenate([dp, ROT_LEVER * (Td[:3, :3] @ w)]))
            else:
                F[end] = T
        r = np.concatenate(res) if res else np.zeros(0)
        return F, r, jf

    @staticmethod
    def _closure(T, Td):
        dp = T[:3, 3] - Td[:3, 3]
        dR = Td[:3, :3].T @ T[:3, :3]
        w = 0.5 * np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
        return np.concatenate([dp, ROT_LEVER * (Td[:3, :3] @ w)])

    def derivatives(self, q, variables, h=1e-7):
        """Forward differences of (closure residual, output pose) for each variable, a passive or
        actuated joint name or a defect (element name, component), recomputing only the chain
        that holds it and moving what hangs from its end rigidly (the other chains unchanged).

        Returns (r0 (m,), To (4, 4), dr (m, n), dTo list of 4x4 derivatives)."""
        F = {self.base: np.eye(4)}
        ends, pre, rest = {}, {}, {}
        where = {}
        for i, closes in self.order:
            name, start, end, els = self.chains[i]
            T = F[start]
            prefix = []
            for k, e in enumerate(els):
                prefix.append(T)
                T = T @ e.T0
                if e.kind == "joint":
                    T = motion(T, e.type, q[e.name])
                where[e.name] = (i, k)
            ends[i] = T
            pre[i] = prefix
            # rest[i][k]: product of the elements after element k (from k+1 to the end)
            R_ = [None] * len(els)
            acc = np.eye(4)
            for k in range(len(els) - 1, -1, -1):
                R_[k] = acc
                e = els[k]
                loc = e.T0
                if e.kind == "joint":
                    loc = motion(loc, e.type, q[e.name])
                acc = loc @ acc
            rest[i] = R_
            if not closes:
                F[end] = T
        # frames downstream of each defining chain's end
        def downstream(frame):
            out = {frame}
            changed = True
            while changed:
                changed = False
                for i, closes in self.order:
                    _, st, en, _ = self.chains[i]
                    if not closes and st in out and en not in out:
                        out.add(en)
                        changed = True
            return out

        def assemble(Fm, endsm):
            res = []
            for i, closes in self.order:
                if closes:
                    res.append(self._closure(endsm[i], Fm[self.chains[i][2]]))
            r = np.concatenate(res) if res else np.zeros(0)
            return r, Fm[self.output]
        r0, To = assemble(F, ends)
        dr = np.zeros((r0.size, len(variables)))
        dTo = []
        down_cache = {}
        for col, var in enumerate(variables):
            if isinstance(var, tuple):
                ename, comp = var
                i, k = where[ename]
                e = self.chains[i][3][k]
                loc = defect_transform(e.T0, comp, h)
                if e.kind == "joint":
                    loc = motion(loc, e.type, q[e.name])
            else:
                i, k = where[var]
                e = self.chains[i][3][k]
                loc = motion(e.T0, e.type, q[var] + h)
            new_end = pre[i][k] @ loc @ rest[i][k]
            _, st, en, _ = self.chains[i]
            closes = dict(self.order)[i]
            Fm = dict(F)
            endsm = dict(ends)
            if closes:
                endsm[i] = new_end
            else:
                D = new_end @ np.linalg.inv(ends[i])
                if en not in down_cache:
                    down_cache[en] = downstream(en)
                dn = down_cache[en]
                for fr in dn:
                    Fm[fr] = D @ F[fr]
                for j, cl in self.order:
                    if cl and self.chains[j][1] in dn:
                        endsm[j] = D @ ends[j]
                endsm[i] = new_end
            r, T2 = assemble(Fm, endsm)
            dr[:, col] = (r - r0) / h
            dTo.append((T2 - To) / h)
        return r0, To, dr, dTo

    def solve(self, qa, defects=None, init=None, tol=1e-10, maxit=60):
        """Close the loops for actuated values qa (dict). Returns (q dict, residual norm)."""
        x = np.array(self._last_passive if init is None else init, float)
        names = self.passive
        q = dict(qa)

        def resid(xv):
            for n, v in zip(names, xv):
                q[n] = v
            return self.frames(q, defects)[1]

        if not self.closing:
            for n, v in zip(names, x):
                q[n] = v
            return q, 0.0
        r = resid(x)
        lam = 1e-6
        for _ in range(maxit):
            nr = np.linalg.norm(r)
            if nr < tol:
                break
            for n, v in zip(names, x):
                q[n] = v
            J = self.derivatives(q, names)[2]
            A = J.T @ J
            g = J.T @ r
            step = -np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-12), g)
            xn = x + step
            rn = resid(xn)
            if np.linalg.norm(rn) < nr:
                x, r = xn, rn
                lam = max(lam / 10, 1e-12)
            else:
                lam *= 10
                if lam > 1e6:
                    break
        for n, v in zip(names, x):
            q[n] = v
        return q, float(np.linalg.norm(r))

    def solve_path(self, qa, defects=None, steps=3):
        """Close the loops by continuation from home (robust branch choice)."""
        home_a = np.array([self.joints[n].home for n in self.actuated], float)
        target = np.array([qa[n] for n in self.actuated], float)
        init = np.array([self.joints[n].home for n in self.passive], float)
        q, r = None, np.inf
        for s in range(1, steps + 1):
            a = home_a + (target - home_a) * s / steps
            q, r = self.solve(dict(zip(self.actuated, a)), defects, init=init)
            init = np.array([q[n] for n in self.passive])
        return q, r

    def output_pose(self, q, defects=None):
        F, _, _ = self.frames(q, defects)
        return F[self.output]

    def passive_inside(self, q, margin):
        for n in self.passive:
            lo, hi = self.joints[n].range
            if not (lo + margin <= q[n] <= hi - margin):
                return False
        return True

    def body_frame(self, q, joint, defects=None):
        return self.frames(q, defects)[2][joint]
