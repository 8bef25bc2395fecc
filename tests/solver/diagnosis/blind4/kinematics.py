"""Own kinematics of a hyperstat model file (JSON), written from docs/model-format.md only.

Units: mm, rad; gravity along -z of the base frame, 9.81 m/s^2 (forces in N, torques in N mm).

Nothing here imports hyperstat.  An element's frame is its placement in the frame reached before
it, perturbed by its defects (axis turned by the minimal rotation from z0 to (z0 + dn)/|.|, origin
shifted by (da, db, dc) in the previous frame, a turn G about its own z); a joint then moves
(R: rotation about z by q, P: translation along z by q).  Chains are evaluated in dependency order;
a chain that reaches an already-defined frame closes a loop (6 equations), solved for the passive
joints by Gauss-Newton with the joints' twists (least squares, so that an over-constrained machine
with admissible defects closes to second order).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

G_ACC = 9.81  # m/s^2; a mass in kg weighs m * 9.81 N


def rotvec_to_matrix(w):
    w = np.asarray(w, float)
    t = np.linalg.norm(w)
    if t < 1e-15:
        k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        return np.eye(3) + k
    a = w / t
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * (k @ k)


def matrix_to_rotvec(r):
    c = np.clip((np.trace(r) - 1) / 2, -1.0, 1.0)
    t = np.arccos(c)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if t < 1e-8:
        return v / 2
    if np.pi - t < 1e-6:
        # near pi: from the symmetric part
        m = (r + np.eye(3)) / 2
        i = int(np.argmax(np.diag(m)))
        a = m[:, i] / np.sqrt(max(m[i, i], 1e-300))
        return a * t
    return v * t / (2 * np.sin(t))


def transform(r=None, p=None):
    t = np.eye(4)
    if r is not None:
        t[:3, :3] = r
    if p is not None:
        t[:3, 3] = p
    return t


def rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def minimal_rotation(a, b):
    """Rotation taking unit vector a to unit vector b about a x b."""
    v = np.cross(a, b)
    s = np.linalg.norm(v)
    c = float(np.dot(a, b))
    if s < 1e-15:
        return np.eye(3)
    return rotvec_to_matrix(v / s * np.arctan2(s, c))


@dataclass
class Element:
    kind: str
    name: str
    chain: int
    r0: np.ndarray
    o0: np.ndarray
    jtype: str | None = None
    role: str | None = None
    rng: tuple | None = None
    home: float = 0.0
    defects: dict = field(default_factory=dict)  # component -> parameter name


class ModelKinematics:
    """Forward kinematics and loop closure of a model file."""

    def __init__(self, model: dict | str):
        if isinstance(model, str):
            with open(model) as f:
                model = json.load(f)
        self.model = model
        self.base = model["base"]
        self.output = model["output"]
        self.elements: list[Element] = []
        self.chains = []
        self.param_names: list[str] = []
        for ci, ch in enumerate(model["chains"]):
            idx = []
            for e in ch["elements"]:
                pl = e["placement"]
                z = np.array(pl["z_axis"], float)
                x = np.array(pl["x_axis"], float)
                r0 = np.column_stack([x, np.cross(z, x), z])
                el = Element(e["kind"], e["name"], ci, r0, np.array(pl["origin"], float))
                if e["kind"] == "joint":
                    el.jtype, el.role = e["type"], e["role"]
                    el.rng = tuple(e["range"])
                    el.home = float(e.get("home", 0.0))
                for d in e.get("defects", []) or []:
                    if isinstance(d, str):
                        comp, name = d, f"d{d}{e['name']}"
                    else:
                        comp, name = d["component"], d.get("name", f"d{d['component']}{e['name']}")
                    el.defects[comp] = name
                    self.param_names.append(name)
                idx.append(len(self.elements))
                self.elements.append(el)
            self.chains.append({"name": ch["name"], "start": ch["start"], "end": ch["end"], "elements": idx})
        # dependency order
        order, defined, pending = [], {self.base}, list(range(len(self.chains)))
        while pending:
            progressed = False
            for ci in list(pending):
                if self.chains[ci]["start"] in defined:
                    order.append(ci)
                    pending.remove(ci)
                    defined.add(self.chains[ci]["end"])
                    progressed = True
            if not progressed:
                raise ValueError("chains do not reach the base")
        self.order = order
        self.joint_ids = [i for i, e in enumerate(self.elements) if e.kind == "joint"]
        self.joint_names = [self.elements[i].name for i in self.joint_ids]
        self.jpos = {self.elements[i].name: k for k, i in enumerate(self.joint_ids)}
        self.actuated = [self.elements[i].name for i in self.joint_ids if self.elements[i].role == "actuated"]
        self.passive = [self.elements[i].name for i in self.joint_ids if self.elements[i].role != "actuated"]
        self.elem_by_name = {e.name: i for i, e in enumerate(self.elements)}
        # which chain defines each frame; which close loops
        self.defining, self.closing = {}, []
        for ci in order:
            end = self.chains[ci]["end"]
            if end in self.defining or end == self.base:
                self.closing.append(ci)
            else:
                self.defining[end] = ci
        self.home = np.array([self.elements[i].home for i in self.joint_ids])

    # ------------------------------------------------------------------ placements
    def placement(self, el: Element, defects: dict):
        r, o = el.r0, el.o0
        if el.defects:
            dn = np.array([defects.get(el.defects.get(c, ""), 0.0) for c in "IJK"])
            z0 = r[:, 2]
            if np.any(dn):
                n = z0 + dn
                n = n / np.linalg.norm(n)
                r = minimal_rotation(z0, n) @ r
            da = np.array([defects.get(el.defects.get(c, ""), 0.0) for c in "abc"])
            o = o + da
            g = defects.get(el.defects.get("G", ""), 0.0)
            if g:
                r = r @ rot_z(g)
        return transform(r, o)

    # ------------------------------------------------------------------ forward
    def placements(self, defects):
        """Every element's perturbed placement (a cache for `forward`)."""
        return {ei: (self.placement(el, defects) if el.kind != "frame" else transform(el.r0, el.o0))
                for ei, el in enumerate(self.elements)}

    def forward(self, q, defects=None, pre=None, post=None, base_pose=None, cache=None):
        """World poses.  q: all joint values (order of joint_names).

        pre[name](T_placement) -> T_placement' and post[name](q_j) -> 4x4 applied after the
        joint's motion (in its moving frame) model the geometric effects.
        Returns dict with 'L' (element frame before motion), 'P' (after motion) per element index,
        'frames' (name -> 4x4 as defined), 'ends' (chain index -> 4x4), 'anc' (joint indices
        upstream of each element's P frame and of each frame).
        """
        defects = defects or {}
        pre = pre or {}
        post = post or {}
        frames = {self.base: np.eye(4) if base_pose is None else base_pose}
        anc_frame = {self.base: []}
        L, P, anc = {}, {}, {}
        ends = {}
        ends_anc = {}
        for ci in self.order:
            ch = self.chains[ci]
            t = frames[ch["start"]]
            a = list(anc_frame[ch["start"]])
            for ei in ch["elements"]:
                el = self.elements[ei]
                if cache is not None:
                    d = cache[ei]
                else:
                    d = self.placement(el, defects) if el.kind != "frame" else transform(el.r0, el.o0)
                if el.name in pre:
                    d = pre[el.name](d)
                t = t @ d
                L[ei] = t
                if el.kind == "joint":
                    qj = q[self.jpos[el.name]]
                    m = transform(rot_z(qj)) if el.jtype == "R" else transform(None, [0, 0, qj])
                    t = t @ m
                    if el.name in post:
                        t = t @ post[el.name](qj)
                    a = a + [self.jpos[el.name]]
                P[ei] = t
                anc[ei] = a
            ends[ci], ends_anc[ci] = t, a
            if ch["end"] not in frames:
                frames[ch["end"]] = t
                anc_frame[ch["end"]] = a
        return {"L": L, "P": P, "frames": frames, "ends": ends, "ends_anc": ends_anc,
                "anc": anc, "anc_frame": anc_frame}

    def frame_of(self, fk, name):
        """Pose of a frame or an element (after its motion) by name."""
        if name in fk["frames"]:
            return fk["frames"][name], fk["anc_frame"][name]
        ei = self.elem_by_name[name]
        return fk["P"][ei], fk["anc"][ei]

    # ------------------------------------------------------------------ twists
    def joint_axes(self, fk):
        """World axis and origin of every joint (from its L frame)."""
        ax, org = np.zeros((len(self.joint_ids), 3)), np.zeros((len(self.joint_ids), 3))
        for k, ei in enumerate(self.joint_ids):
            ax[k] = fk["L"][ei][:3, 2]
            org[k] = fk["L"][ei][:3, 3]
        return ax, org

    def point_jacobian(self, fk, point, anc, axes=None):
        """6 x n_joints: linear velocity of `point` and angular velocity per joint rate."""
        ax, org = axes if axes is not None else self.joint_axes(fk)
        j = np.zeros((6, len(self.joint_ids)))
        for k in anc:
            if self.elements[self.joint_ids[k]].jtype == "R":
                j[:3, k] = np.cross(ax[k], point - org[k])
                j[3:, k] = ax[k]
            else:
                j[:3, k] = ax[k]
        return j

    def closure(self, fk, axes=None):
        """Loop residuals (6 per closing chain) and their Jacobian over all joints."""
        res, jac = [], []
        axes = axes if axes is not None else self.joint_axes(fk)
        for ci in self.closing:
            end = self.chains[ci]["end"]
            ta, aa = fk["ends"][ci], fk["ends_anc"][ci]
            tb, ab = fk["frames"][end], fk["anc_frame"][end]
            dp = ta[:3, 3] - tb[:3, 3]
            dr = matrix_to_rotvec(ta[:3, :3] @ tb[:3, :3].T)
            res.append(np.concatenate([dp, dr]))
            ja = self.point_jacobian(fk, ta[:3, 3], aa, axes)
            jb = self.point_jacobian(fk, ta[:3, 3], ab, axes)
            jac.append(ja - jb)
        if not res:
            return np.zeros(0), np.zeros((0, len(self.joint_ids)))
        return np.concatenate(res), np.vstack(jac)

    def assemble(self, q_act, defects=None, pre=None, post=None, q_start=None, tol=1e-10, iters=40,
                 base_pose=None):
        """Solve the passive joints for the actuated values (dict or array in `actuated` order).

        Returns (q_all, fk, residual_norm, passive_in_range)."""
        q = np.array(self.home if q_start is None else q_start, float)
        if isinstance(q_act, dict):
            for n, v in q_act.items():
                q[self.jpos[n]] = v
        else:
            for n, v in zip(self.actuated, q_act):
                q[self.jpos[n]] = v
        pidx = [self.jpos[n] for n in self.passive]
        fk = self.forward(q, defects, pre, post, base_pose)
        if not self.closing:
            return q, fk, 0.0, True
        scale = np.ones(6 * len(self.closing))
        for i in range(len(self.closing)):
            scale[6 * i + 3: 6 * i + 6] = 1000.0  # rotations at a 1 m lever
        rn = np.inf
        for _ in range(iters):
            r, j = self.closure(fk)
            rn = float(np.linalg.norm(r * scale))
            if rn < tol:
                break
            jp = j[:, pidx] * scale[:, None]
            step = np.linalg.lstsq(jp, -r * scale, rcond=None)[0]
            q[pidx] += step
            fk = self.forward(q, defects, pre, post, base_pose)
            if np.max(np.abs(step)) < 1e-13:
                r, _ = self.closure(fk)
                rn = float(np.linalg.norm(r * scale))
                break
        ok = all(self.elements[self.joint_ids[k]].rng[0] - 1e-9 <= q[k] <= self.elements[self.joint_ids[k]].rng[1] + 1e-9
                 for k in pidx)
        return q, fk, rn, ok

    def actuated_map(self, fk):
        """d(point twist)/d(actuated) with the passive joints following the closures:
        returns a function point, anc -> 6 x n_act Jacobian."""
        axes = self.joint_axes(fk)
        aidx = [self.jpos[n] for n in self.actuated]
        pidx = [self.jpos[n] for n in self.passive]
        if self.closing:
            _, j = self.closure(fk, axes)
            dqp = -np.linalg.lstsq(j[:, pidx], j[:, aidx], rcond=None)[0]
        else:
            dqp = np.zeros((0, len(aidx)))

        def jac(point, anc):
            jf = self.point_jacobian(fk, point, anc, axes)
            return jf[:, aidx] + jf[:, pidx] @ dqp
        return jac

    def gravity_loads(self, fk, point_masses):
        """Generalized gravity forces on the actuated joints (N mm or N), virtual work.

        point_masses: list of (mass kg, world point mm, anc joint list)."""
        jac = self.actuated_map(fk)
        tau = np.zeros(len(self.actuated))
        for m, p, anc in point_masses:
            w = np.array([0.0, 0.0, -m * G_ACC])
            tau += jac(p, anc)[:3].T @ w
        return tau


def target_point(t_out, offset):
    return t_out[:3, :3] @ np.asarray(offset, float) + t_out[:3, 3]
