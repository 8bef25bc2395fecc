"""Kinematics of a mechanism read from a hyperstat model file (own parser, own solver).

Written from docs/model-format.md and paper 1 (Guyon et al. 2022), eq. (2), (7), (9): every
element's frame is placed in the frame reached just before it by its placement (origin,
z axis, x axis; y = z x x); a joint then moves about (R) or along (P) its z axis; the first
chain that reaches a frame defines it, every other chain that reaches it closes a loop (six
equations).  Nothing is imported from hyperstat.

On top of the rigid model this module carries what the blind generator needs to make a *real*
parallel machine:

* static perturbations of any element's placement (``pert``: a small rigid displacement of its
  frame L, expressed in L), used for the machine's geometric errors;
* configuration-dependent displacements after a joint's motion (``post``: callables of the
  joint values), used for bowed guides and joint clearances;
* elastic twists (``elastic``: six compliances per element, applied after its motion): the
  loop closes with the least elastic energy when the geometry alone cannot close it.

Residual rows of a closure: rotation vector of ``R_b R_a^T`` then ``p_b - p_a`` (world frame),
``a`` the frame as defined, ``b`` the same frame reached through the closing chain.
Units: mm, rad.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from . import geom


@dataclass
class Element:
    name: str
    kind: str            # joint, fixed, frame
    type: str | None     # R, P
    role: str | None     # actuated, passive
    D: np.ndarray
    range: tuple | None
    home: float | None
    chain: int
    index: int


@dataclass
class Chain:
    name: str
    start: str
    end: str
    elements: list = field(default_factory=list)
    closes: bool = False


class Mechanism:
    """A mechanism of the model-file format."""

    def __init__(self, model: dict):
        if isinstance(model, str):
            with open(model) as fh:
                model = json.load(fh)
        self.model = model
        self.name = model["name"]
        self.base = model["base"]
        self.output = model["output"]
        self.metadata = model.get("metadata", {})
        # dependency order: a chain can be placed once its start frame is defined
        pending = list(model["chains"])
        defined = {self.base}
        ordered = []
        while pending:
            for c in pending:
                if c["start"] in defined:
                    ordered.append(c)
                    pending.remove(c)
                    defined.add(c["end"])
                    break
            else:
                raise ValueError("chains do not reach the base")
        self.chains: list[Chain] = []
        self.elements: dict[str, Element] = {}
        seen = {self.base}
        for ci, c in enumerate(ordered):
            ch = Chain(c["name"], c["start"], c["end"])
            ch.closes = c["end"] in seen
            seen.add(c["end"])
            for ei, e in enumerate(c["elements"]):
                p = e["placement"]
                el = Element(e["name"], e["kind"], e.get("type"), e.get("role"),
                             geom.placement_matrix(p["origin"], p["z_axis"], p["x_axis"]),
                             tuple(e["range"]) if "range" in e else None, e.get("home"), ci, ei)
                ch.elements.append(el)
                self.elements[el.name] = el
            self.chains.append(ch)
        self.joints = [e.name for ch in self.chains for e in ch.elements if e.kind == "joint"]
        self.actuated = [j for j in self.joints if self.elements[j].role == "actuated"]
        self.passive = [j for j in self.joints if self.elements[j].role != "actuated"]
        self.home = {j: float(self.elements[j].home if self.elements[j].home is not None else 0.0)
                     for j in self.joints}
        self.closures = [c for c in self.chains if c.closes]

    # ------------------------------------------------------------------ forward pass
    def evaluate(self, q, pert=None, post=None, elastic_e=None):
        """World frames of every element for joint values q (dict name -> value).

        Returns a dict with 'frames' (frame name -> 4x4, as defined), 'L' / 'P' (element name
        -> world transform before / after its motion), 'ends' (closing chain index -> 4x4 of
        the end reached through it), and the ancestry of each frame (list of element names
        whose motion, perturbation or elasticity moves it)."""
        pert = pert or {}
        post = post or {}
        elastic_e = elastic_e or {}
        frames = {self.base: np.eye(4)}
        anc = {self.base: []}
        L, P, ends, end_anc = {}, {}, {}, {}
        for ci, ch in enumerate(self.chains):
            t = frames[ch.start].copy()
            a = list(anc[ch.start])
            for el in ch.elements:
                d = el.D
                if el.name in pert:
                    d = d @ pert[el.name]
                t = t @ d
                L[el.name] = t.copy()
                if el.kind == "joint":
                    v = q[el.name]
                    t = t @ (geom.rot_z(v) if el.type == "R" else geom.trans(0.0, 0.0, v))
                if el.name in post:
                    t = t @ post[el.name](q)
                if el.name in elastic_e:
                    e = elastic_e[el.name]
                    t = t @ geom.small_transform(e[:3], e[3:])
                P[el.name] = t.copy()
                a.append(el.name)
            if ch.closes:
                ends[ci] = t
                end_anc[ci] = a
            else:
                frames[ch.end] = t
                anc[ch.end] = a
        return {"frames": frames, "anc": anc, "L": L, "P": P, "ends": ends, "end_anc": end_anc}

    def closure_residual(self, st):
        r = []
        for ci, ch in enumerate(self.chains):
            if ch.closes:
                r.append(geom.pose_error(st["frames"][ch.end], st["ends"][ci]))
        return np.concatenate(r) if r else np.zeros(0)

    # ------------------------------------------------------------------ derivatives
    def variable_screws(self, st, variables):
        """World screws of variables: (owners, U (n,3), O (n,3), rotational (n,)).

        A variable is ('q', joint), ('pert', element, i) (i = 0..5, rotation then translation
        in the element's frame L) or ('el', element, i) (elastic twist in the frame after the
        motion)."""
        n = len(variables)
        u = np.zeros((n, 3))
        o = np.zeros((n, 3))
        rot = np.zeros(n, dtype=bool)
        owners = []
        for k, v in enumerate(variables):
            if v[0] == "q":
                t = st["L"][v[1]]
                u[k] = t[:3, 2]
                rot[k] = self.elements[v[1]].type == "R"
            else:
                t = st["L"][v[1]] if v[0] == "pert" else st["P"][v[1]]
                u[k] = t[:3, v[2] % 3]
                rot[k] = v[2] < 3
            o[k] = t[:3, 3]
            owners.append(v[1])
        return owners, u, o, rot

    @staticmethod
    def _effects(u, o, rot, p, mask):
        """6 x n effect of the variables' unit motions on a frame at point p (masked)."""
        out = np.zeros((6, len(rot)))
        lin = np.where(rot[:, None], np.cross(u, p[None, :] - o), u)
        out[:3] = np.where(rot[:, None], u, 0.0).T
        out[3:] = lin.T
        out[:, ~mask] = 0.0
        return out

    def closure_jacobian(self, st, variables, screws=None):
        owners, u, o, rot = screws or self.variable_screws(st, variables)
        rows = []
        for ci, ch in enumerate(self.chains):
            if not ch.closes:
                continue
            ab = set(st["end_anc"][ci])
            aa = set(st["anc"][ch.end])
            mb = np.array([w in ab for w in owners], dtype=bool)
            ma = np.array([w in aa for w in owners], dtype=bool)
            rows.append(self._effects(u, o, rot, st["ends"][ci][:3, 3], mb)
                        - self._effects(u, o, rot, st["frames"][ch.end][:3, 3], ma))
        return np.vstack(rows) if rows else np.zeros((0, len(variables)))

    def frame_jacobian(self, st, frame, variables, point=None, screws=None):
        """6 x n: (rotation, velocity of `point` (world, default the frame's origin))."""
        p = st["frames"][frame][:3, 3] if point is None else np.asarray(point, dtype=float)
        owners, u, o, rot = screws or self.variable_screws(st, variables)
        aa = set(st["anc"][frame])
        mask = np.array([w in aa for w in owners], dtype=bool)
        return self._effects(u, o, rot, p, mask)

    def point_motion(self, st, frame, point, dq_dqa_rows, actuated_vars, passive_vars):
        """d(point)/d(actuated) with the passive joints following (3 x n_a)."""
        ja = self.frame_jacobian(st, frame, actuated_vars, point)[3:]
        jp = self.frame_jacobian(st, frame, passive_vars, point)[3:]
        return ja + jp @ dq_dqa_rows

    def passive_sensitivity(self, st):
        """dq_p / dq_a at a closed configuration (implicit function theorem, least squares)."""
        av = [("q", j) for j in self.actuated]
        pv = [("q", j) for j in self.passive]
        ba = self.closure_jacobian(st, av)
        bp = self.closure_jacobian(st, pv)
        return -np.linalg.lstsq(bp, ba, rcond=1e-10)[0], av, pv

    # ------------------------------------------------------------------ solvers
    def solve(self, q_init, free=None, pert=None, post=None, elastic=None, goal=None,
              iterations=40, tol=1e-11):
        """Close the loops.

        q_init: full joint dict (start values; the joints not in `free` keep their values).
        free: joints solved for (default: the passive joints).
        elastic: dict element -> 6 compliances (rad/(N mm) x3, mm/N x3): the loops close with
        the least elastic energy sum e_i^2 / (2 c_i) (KKT, Gauss-Newton).
        goal: (frame, 4x4 goal, mask of 6 booleans): extra rows pose_error(goal, frame) = 0
        on the masked components (inverse kinematics).
        Returns (q, elastic twists, residual norm)."""
        q = dict(q_init)
        free = list(self.passive if free is None else free)
        fvars = [("q", j) for j in free]
        evars, wdiag = [], []
        if elastic:
            for name, comp in elastic.items():
                for i in range(6):
                    evars.append(("el", name, i))
                    wdiag.append(1.0 / comp[i])
        e = np.zeros(len(evars))
        w = np.array(wdiag)

        def elastic_dict(evec):
            out = {}
            for k, v in enumerate(evars):
                out.setdefault(v[1], np.zeros(6))[v[2]] = evec[k]
            return out

        res = np.inf
        for _ in range(iterations):
            st = self.evaluate(q, pert, post, elastic_dict(e))
            f = self.closure_residual(st)
            jq = self.closure_jacobian(st, fvars)
            je = self.closure_jacobian(st, evars) if evars else None
            if goal is not None:
                frame, tg, mask = goal
                g = geom.pose_error(tg, st["frames"][frame])[mask]
                gq = self.frame_jacobian(st, frame, fvars)[mask]
                f = np.concatenate([f, g])
                jq = np.vstack([jq, gq])
                if je is not None:
                    je = np.vstack([je, self.frame_jacobian(st, frame, evars)[mask]])
            res = float(np.linalg.norm(f))
            if je is None:
                if res < tol:
                    break
                dq = -np.linalg.lstsq(jq, f, rcond=1e-10)[0]
            else:
                # KKT: min 1/2 (e+de)^T W (e+de)  s.t.  f + jq dq + je de = 0
                u, s, vt = np.linalg.svd(jq)
                rank = int(np.sum(s > s[0] * 1e-10)) if s.size else 0
                n_left = u[:, rank:]
                c = n_left.T @ je
                rhs = -n_left.T @ f
                if c.shape[0]:
                    winv = 1.0 / w
                    m = (c * winv) @ c.T
                    lam = np.linalg.lstsq(m, rhs + c @ e, rcond=1e-14)[0]
                    de = -e + winv * (c.T @ lam)
                else:
                    de = -e
                dq = -np.linalg.lstsq(jq, f + je @ de, rcond=1e-10)[0]
                e = e + de
                if res < tol and np.max(np.abs(dq)) < 1e-12 and np.max(np.abs(de)) < 1e-14:
                    break
            for j, d in zip(free, dq):
                q[j] += d
            if np.max(np.abs(dq)) < 1e-13 and je is None:
                break
        st = self.evaluate(q, pert, post, elastic_dict(e))
        f = self.closure_residual(st)
        return q, elastic_dict(e), float(np.linalg.norm(f)), st

    # ------------------------------------------------------------------ analysis helpers
    def in_range(self, q, margin=0.0):
        for j in self.joints:
            lo, hi = self.elements[j].range
            if not (lo + margin <= q[j] <= hi - margin):
                return False
        return True

    def passive_conditioning(self, st):
        """Smallest singular value of the closure Jacobian in the passive joints (scaled)."""
        jq = self.closure_jacobian(st, [("q", j) for j in self.passive])
        if jq.size == 0:
            return np.inf
        s = np.linalg.svd(jq, compute_uv=False)
        rank = int(np.sum(s > s[0] * 1e-9))
        return s[rank - 1] / s[0]

    def admissible_basis(self, configs, elements=None):
        """Own stationarity analysis (paper 1, section 3): the placement perturbations that
        every configuration's passive joints can absorb.  Returns (variables, basis) with the
        basis columns spanning the admissible subspace of the perturbation vector."""
        if elements is None:
            elements = [e.name for ch in self.chains for e in ch.elements if e.kind in ("joint", "fixed")]
        pvars = [("pert", n, i) for n in elements for i in range(6)]
        rows = []
        for q in configs:
            st = self.evaluate(q)
            jp = self.closure_jacobian(st, [("q", j) for j in self.passive])
            ja = self.closure_jacobian(st, pvars)
            if jp.shape[0] == 0:
                break
            u, s, vt = np.linalg.svd(jp)
            rank = int(np.sum(s > s[0] * 1e-10))
            rows.append(u[:, rank:].T @ ja)
        stack = np.vstack(rows) if rows else np.zeros((0, len(pvars)))
        if stack.shape[0] == 0:
            return pvars, np.eye(len(pvars))
        # scale: angles by 1000 mm so both kinds weigh alike
        scale = np.array([1000.0 if v[2] < 3 else 1.0 for v in pvars])
        u, s, vt = np.linalg.svd(stack / scale, full_matrices=True)
        rank = int(np.sum(s > s[0] * 1e-9))
        basis = (vt[rank:].T) / scale[:, None]
        return pvars, basis
