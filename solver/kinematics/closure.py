"""Forward model, loop-closure residuals, screw Jacobians and assembly.

Units: lengths in mm, angles in rad.

For a configuration ``q`` (all joint variables) and a defect vector ``xi`` the
frames of every chain are products of ``D`` and ``M`` matrices (paper 1, eq. 2).
A loop closure (eqs. 7, 9) compares the frame reached by a closing chain with the
same frame reached by its defining chain; its residual is the 6-vector

    r = (log(R_closing R_reference^T), p_closing - p_reference)    [rad, mm]

written in the base frame.  Jacobians are assembled from the unit screws of the
joints and of the defects (paper 2, eq. 7): a column is the twist ``(omega, v)`` of
the parameter, turned into ``(omega, v + omega x p)``, the angular velocity and the
velocity of the frame origin ``p``.  Everything is vectorised over configurations.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from hyperstat.solver.errors import AssemblyError
from hyperstat.solver.kinematics.continuation import (
    BranchCertificate,
    ContinuationOptions,
    batched_lstsq,
    continue_nearest,
    continue_path,
)
from hyperstat.solver.kinematics.fastfk import FramePlan
from hyperstat.solver.kinematics.frames import (
    cross,
    make_transform,
    minimal_rotation,
    minimal_rotation_velocity,
    apply_motion,
    so3_log,
)
from hyperstat.solver.kinematics.model import ConfigurationFrame, Joint, Mechanism

__all__ = ["Kinematics", "KinematicState", "AssemblyResult", "batched_lstsq"]

_COMP_INDEX = {"I": 0, "J": 1, "K": 2, "a": 0, "b": 1, "c": 2}
#: geometries (defect vectors) whose batched plan is kept
PLAN_CACHE = 8
#: configurations from which a defect vector is evaluated on a plan of its own (:meth:`Kinematics._worth_a_plan`)
PLAN_BATCH = 512


@dataclass
class KinematicState:
    """Frames, residuals and Jacobians at a batch of configurations.

    Shapes use ``K`` configurations, ``m = 6 * n_closures`` residual rows,
    ``n_xi`` defect parameters and ``n_q`` joints.

    Attributes
    ----------
    residual : ndarray, (K, m)
        Closure residuals ``(rotation [rad], position [mm])`` per closure.
    closure_xi : ndarray, (K, m, n_xi) or None
        ``dr/dxi`` (the stationarity matrix ``A_s`` of eq. 3).
    closure_q : ndarray, (K, m, n_q) or None
        ``dr/dq`` for all joints (passive columns give ``B_s``).
    output_pose : ndarray, (K, 4, 4)
        Output frame in the base frame.
    output_xi, output_q : ndarray, (K, 6, n) or None
        Angular velocity and origin velocity of the output frame per unit parameter.
    frames : dict
        Frame name -> (K, 4, 4) absolute transform (defining chain).
    element_frames : dict
        ``(chain, element)`` -> (K, 4, 4) absolute ``L`` frame of every element.
    defect_twists : ndarray, (K, n_xi, 6) or None
        Spatial twist ``(omega, v)`` of every defect parameter (``v``: velocity of the
        point at the base origin); it moves every frame downstream of its element.
    """

    residual: np.ndarray
    closure_xi: np.ndarray | None
    closure_q: np.ndarray | None
    output_pose: np.ndarray
    output_xi: np.ndarray | None
    output_q: np.ndarray | None
    frames: dict
    element_frames: dict
    defect_twists: np.ndarray | None = None


@dataclass
class AssemblyResult:
    """Outcome of :meth:`Kinematics.assemble`.

    Attributes
    ----------
    q : ndarray, (K, n_q)
        Configurations with solved passive joints.
    residual : ndarray, (K,)
        Closure residual norm after solving, rotations scaled by the length scale (mm).
    converged : ndarray of bool, (K,)
        Whether the residual fell below the tolerance (and, for :meth:`Kinematics.solve`,
        whether the configuration is certified on the branch of its start).
    certificate : BranchCertificate or None
        Per-configuration branch certificate of :meth:`Kinematics.solve`
        (:mod:`hyperstat.solver.kinematics.continuation`); ``None`` for a plain
        :meth:`Kinematics.assemble`.
    """

    q: np.ndarray
    residual: np.ndarray
    converged: np.ndarray
    certificate: BranchCertificate | None = None
    #: the output poses (K, 4, 4) at ``q`` that :meth:`Kinematics.assemble` evaluated with ``residual``: the same
    #: values ``evaluate(q, xi, jacobians=False).output_pose`` gives, a copy (``None`` elsewhere): no frame is kept
    output_pose: np.ndarray | None = None


class _LazyElementFrames(Mapping):
    """``element_frames`` of a state computed by the batched path: filled on first access.

    The batched path (:mod:`hyperstat.solver.kinematics.fastfk`) does not keep the ``L`` frame of every
    element; the few callers that want them (pictures, hypotheses, the length scale)
    get them from the element-by-element pass, run once on demand.
    """

    def __init__(self, kin: "Kinematics", q: np.ndarray, xi: np.ndarray) -> None:
        self._args = (kin, q, xi)
        self._frames: dict | None = None

    def _get(self) -> dict:
        if self._frames is None:
            kin, q, xi = self._args
            self._frames = kin._walk(q, xi)[3]  # noqa: SLF001 - same class family
        return self._frames

    def __getitem__(self, key):
        return self._get()[key]

    def __iter__(self):
        return iter(self._get())

    def __len__(self) -> int:
        return len(self._get())


class Kinematics:
    """Vectorised forward model of a :class:`~hyperstat.solver.kinematics.model.Mechanism`.

    Parameters
    ----------
    mechanism : Mechanism
        The model to evaluate.
    """

    def __init__(self, mechanism: Mechanism) -> None:
        self.mechanism = mechanism
        m = mechanism
        self.n_q = len(m.joints)
        self.n_xi = len(m.parameters)
        self._order = m.topology["order"]
        # Per element: nominal matrix, axis, and the parameter indices by component.
        self._elements: dict[tuple[int, int], dict] = {}
        for ci, chain in enumerate(m.chains):
            for ei, el in enumerate(chain.elements):
                d0 = el.placement.matrix()
                info = {
                    "D0": d0,
                    "R0": d0[:3, :3].copy(),
                    "p0": d0[:3, 3].copy(),
                    "n0": d0[:3, 2].copy(),
                    "params": {},
                    "joint": m.joint_index[el.name] if isinstance(el, Joint) else None,
                    "type": el.type if isinstance(el, Joint) else None,
                }
                self._elements[(ci, ei)] = info
        for pi, p in enumerate(m.parameters):
            self._elements[(p.chain, p.index)]["params"][p.component] = pi
        self._param_element = [(p.chain, p.index) for p in m.parameters]
        self._joint_element = [None] * self.n_q
        for key, info in self._elements.items():
            if info["joint"] is not None:
                self._joint_element[info["joint"]] = key
        # Signed membership of elements in closure loops and the output path.
        keys = list(self._elements)
        self._key_index = {k: i for i, k in enumerate(keys)}
        n_el = len(keys)
        self._closure_sign = np.zeros((len(m.closures), n_el))
        for k, cl in enumerate(m.closures):
            for e in cl.path:
                self._closure_sign[k, self._key_index[e]] += 1.0
            for e in cl.reference_path:
                self._closure_sign[k, self._key_index[e]] -= 1.0
        self._output_member = np.zeros(n_el)
        for e in m.path_to(m.output):
            self._output_member[self._key_index[e]] = 1.0
        self._param_el_idx = np.array([self._key_index[k] for k in self._param_element], dtype=int)
        self._joint_el_idx = np.array([self._key_index[k] for k in self._joint_element], dtype=int)
        self._plans: dict = {}
        #: elements that carry defects: the plan returns their parent frames for the defect twists
        self._tapped = list(dict.fromkeys(self._param_element))
        self._plans_lock = threading.Lock()  # accuracy maps evaluate blocks in threads
        #: use :class:`hyperstat.solver.kinematics.fastfk.FramePlan` for frames and joint Jacobians when the
        #: defects are the same for every configuration (False: element-by-element path)
        self.use_plan = True
        self.length_scale = self._characteristic_length()

    # ------------------------------------------------------------------ helpers
    def _characteristic_length(self) -> float:
        state = self.evaluate(self.mechanism.home[None, :], jacobians=False)
        pts = [f[0, :3, 3] for f in state.frames.values()]
        pts += [t[0, :3, 3] for t in state.element_frames.values()]
        pts = np.array(pts)
        rms = float(np.sqrt(np.mean(np.sum((pts - pts.mean(axis=0)) ** 2, axis=1)))) if len(pts) > 1 else 0.0
        return max(rms, 1.0)

    def _broadcast(self, q: np.ndarray, xi: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """``q`` as (K, n_q); ``xi`` as (1, n_xi) when it is the same for every configuration."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        k = q.shape[0]
        if xi is None:
            xi = np.zeros((1, self.n_xi))
        else:
            xi = np.asarray(xi, dtype=float)
            if xi.ndim == 1:
                xi = xi[None, :]
            elif xi.shape[0] not in (1, k):
                raise ValueError(f"xi must have 1 or {k} rows (one per configuration), got {xi.shape[0]}.")
        return q, xi

    def element_matrices(self, xi: np.ndarray | None = None, keys=None) -> dict:
        """Matrix ``D(xi)`` of every element for one defect vector (rad / mm), shape (4, 4).

        Parameters
        ----------
        xi : ndarray, (n_xi,), optional
            Defects; the nominal geometry if omitted.
        keys : iterable of (chain, element), optional
            Only these elements (default: all).

        Returns
        -------
        dict
            ``(chain, element)`` -> (4, 4) array.
        """
        _, xi2 = self._broadcast(np.zeros((1, self.n_q)), xi)
        if xi2.shape[0] != 1:
            raise ValueError("element_matrices takes one defect vector.")
        elements = self._elements if keys is None else {key: self._elements[key] for key in keys}
        return {key: self._element_matrix(info, xi2)[0][0] for key, info in elements.items()}

    def plan(self, xi: np.ndarray | None = None) -> FramePlan:
        """The lean batched forward model (:class:`hyperstat.solver.kinematics.fastfk.FramePlan`) for one geometry.

        Plans are cached for the last few defect vectors, so repeated evaluations at the
        same geometry (assembly iterations, sampling) compile once.
        """
        key = None if xi is None or not np.any(xi) else np.asarray(xi, dtype=float).tobytes()
        with self._plans_lock:
            plan = self._plans.get(key)
            if plan is None:
                plan = FramePlan(self.mechanism, self.element_matrices(None if key is None else np.asarray(xi, float)),
                                 tapped=self._tapped)
                if len(self._plans) >= PLAN_CACHE:
                    self._plans.pop(next(iter(self._plans)))
                self._plans[key] = plan
        return plan

    def _worth_a_plan(self, xi: np.ndarray, k: int) -> bool:
        """Whether to evaluate ``k`` configurations at geometry ``xi`` on its plan rather than element by element.

        The nominal geometry and batches of :data:`PLAN_BATCH` configurations or more go on a plan; a
        defect vector at fewer configurations (an optimiser's trial, a fit's iterate, a simulated
        machine) element by element, where building its plan would cost two to three evaluations (the
        Tripteor at one configuration: 1.4 ms against 0.35 ms).  The choice depends on the call alone,
        never on what was evaluated before, so a result does not depend on the history of the process
        (the two paths agree to round-off, not bit for bit).
        """
        return k >= PLAN_BATCH or not np.any(xi)

    def _all_element_matrices(self, xi: np.ndarray) -> tuple[dict, dict]:
        """``D(xi)`` of every element that carries defects, all at once: key -> (K, 4, 4), and their extras.

        The same arithmetic as :meth:`_element_matrix`, element by element, vectorised over the
        elements (one minimal rotation of shape (K, E, 3, 3) instead of E calls): the element-by-element
        pass with one defect vector per row (Monte Carlo, simulated calibrations) spent most of its
        time in the per-element calls.
        """
        layout = getattr(self, "_defect_layout", None)
        if layout is None:
            keys = [key for key, info in self._elements.items() if info["params"]]
            pad = self.n_xi  # index of a zero column appended to xi
            n_idx = np.full((len(keys), 3), pad)
            p_idx = np.full((len(keys), 3), pad)
            g_idx = np.full(len(keys), pad)
            for e, key in enumerate(keys):
                for comp, pi in self._elements[key]["params"].items():
                    if comp in "IJK":
                        n_idx[e, _COMP_INDEX[comp]] = pi
                    elif comp in "abc":
                        p_idx[e, _COMP_INDEX[comp]] = pi
                    else:
                        g_idx[e] = pi
            n0 = np.array([self._elements[key]["n0"] for key in keys]).reshape(-1, 3)
            r0 = np.array([self._elements[key]["R0"] for key in keys]).reshape(-1, 3, 3)
            p0 = np.array([self._elements[key]["p0"] for key in keys]).reshape(-1, 3)
            layout = self._defect_layout = (keys, n_idx, p_idx, g_idx, n0, r0, p0)
        keys, n_idx, p_idx, g_idx, n0, r0, p0 = layout
        if not keys:
            return {}, {}
        k = xi.shape[0]
        xp = np.concatenate([xi, np.zeros((k, 1))], axis=1)
        raw = n0 + xp[:, n_idx]  # (K, E, 3)
        norm = np.linalg.norm(raw, axis=2, keepdims=True)
        b = raw / norm
        rot = minimal_rotation(np.broadcast_to(n0, b.shape), b) @ r0
        gamma = xp[:, g_idx]  # (K, E)
        turned = np.any(gamma != 0, axis=0)
        if np.any(turned):
            c, s_ = np.cos(gamma[:, turned]), np.sin(gamma[:, turned])
            rz = np.zeros(c.shape + (3, 3))
            rz[..., 0, 0] = c
            rz[..., 0, 1] = -s_
            rz[..., 1, 0] = s_
            rz[..., 1, 1] = c
            rz[..., 2, 2] = 1.0
            rot[:, turned] = rot[:, turned] @ rz
        d = make_transform(rot, p0 + xp[:, p_idx])
        mats = {key: d[:, e] for e, key in enumerate(keys)}
        extras = {key: {"b": b[:, e], "norm": norm[:, e]} for e, key in enumerate(keys)}
        return mats, extras

    def _element_matrix(self, info: dict, xi: np.ndarray) -> tuple[np.ndarray, dict]:
        """``D(xi)`` for one element, shape (K, 4, 4), plus intermediate values."""
        k = xi.shape[0]
        params = info["params"]
        extra = {}
        if not params:
            return np.broadcast_to(info["D0"], (k, 4, 4)), extra
        dn = np.zeros((k, 3))
        dp = np.zeros((k, 3))
        gamma = np.zeros(k)
        for comp, pi in params.items():
            if comp in "IJK":
                dn[:, _COMP_INDEX[comp]] = xi[:, pi]
            elif comp in "abc":
                dp[:, _COMP_INDEX[comp]] = xi[:, pi]
            else:
                gamma = xi[:, pi]
        n0 = info["n0"]
        raw = n0 + dn
        norm = np.linalg.norm(raw, axis=1, keepdims=True)
        b = raw / norm
        rmin = minimal_rotation(np.broadcast_to(n0, b.shape), b)
        rot = rmin @ info["R0"]
        if np.any(gamma != 0):
            c, s = np.cos(gamma), np.sin(gamma)
            rz = np.zeros((k, 3, 3))
            rz[:, 0, 0] = c
            rz[:, 0, 1] = -s
            rz[:, 1, 0] = s
            rz[:, 1, 1] = c
            rz[:, 2, 2] = 1.0
            rot = rot @ rz
        extra.update(b=b, norm=norm)
        return make_transform(rot, info["p0"] + dp), extra

    # ------------------------------------------------------------------ evaluation
    def _walk(self, q: np.ndarray, xi: np.ndarray, elements: tuple | None = None) -> tuple[dict, dict, dict, dict, dict]:
        """Element-by-element forward pass: frames, closing ends, parents, L frames, extras.

        ``elements``: :meth:`_all_element_matrices` of ``xi`` computed before (an assembly's iterations keep their
        defects), or ``None`` to compute them here.
        """
        m = self.mechanism
        k = q.shape[0]
        frames: dict[str, np.ndarray] = {m.base: np.broadcast_to(np.eye(4), (k, 4, 4))}
        closing_end: dict[int, np.ndarray] = {}
        parents: dict[tuple[int, int], np.ndarray] = {}
        lframes: dict[tuple[int, int], np.ndarray] = {}
        extras: dict[tuple[int, int], dict] = {}
        mats, mat_extras = self._all_element_matrices(xi) if elements is None else elements
        for ci in self._order:
            chain = m.chains[ci]
            t = frames[chain.start]
            for ei, el in enumerate(chain.elements):
                info = self._elements[(ci, ei)]
                if (ci, ei) in mats:
                    d, extra = mats[(ci, ei)], mat_extras[(ci, ei)]
                else:
                    d, extra = np.broadcast_to(info["D0"], (xi.shape[0], 4, 4)), {}
                parents[(ci, ei)] = t
                if d.shape[0] == 1 and t.shape[0] == k:
                    # one geometry: a single (4K, 4) x (4, 4) product instead of K small ones
                    lf = (np.reshape(t, (4 * k, 4)) @ d[0]).reshape(k, 4, 4)
                else:
                    lf = t @ d
                lframes[(ci, ei)] = lf
                extras[(ci, ei)] = extra
                if info["joint"] is not None:
                    t = apply_motion(lf, info["type"], q[:, info["joint"]])
                else:
                    t = lf
            if chain.end in frames:
                closing_end[ci] = t
            else:
                frames[chain.end] = t
        return frames, closing_end, parents, lframes, extras

    def forward(
        self,
        q: np.ndarray,
        xi: np.ndarray | None = None,
        jacobian: bool = False,
        threads: int | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Output pose (and its joint Jacobian) at many configurations, one geometry.

        The lean path of :mod:`hyperstat.solver.kinematics.fastfk`; no closure is solved: ``q`` holds every
        joint (for a parallel mechanism, assembled configurations).

        Parameters
        ----------
        q : ndarray, (K, n_q) or (n_q,)
            Joint values (rad / mm).
        xi : ndarray, (n_xi,), optional
            Defects (rad / mm), the same for all configurations; nominal if omitted.
        jacobian : bool
            Also return ``dX/dq``: angular velocity and velocity of the output origin in
            the base frame per unit joint velocity (paper 2, eq. 7).
        threads : int, optional
            Worker threads (default: the number of CPUs).

        Returns
        -------
        pose : ndarray, (K, 4, 4)
            Output frame in the base frame.
        jac : ndarray, (K, 6, n_q) or None
            Rows ``(omega, v)``.
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        plan = self.plan(None if xi is None else np.asarray(xi, dtype=float))
        out = self.mechanism.output
        run = plan.run(q, threads=threads, frames=[out], jacobian_at=out if jacobian else None)
        return run.frames[out], run.jacobian

    def _defect_directions(self, plan: FramePlan, xi: np.ndarray) -> tuple:
        """Per defect, its screw in the frame its element starts from, at one geometry (cached on the plan).

        Returns ``(slot, omega, trans, offset)``: the tap slot of each defect's element (``plan.tapped``),
        the angular velocity ``(n_xi, 3)`` and the translation direction ``(n_xi, 3)`` per unit defect in
        the parent frame, and the origin of each tapped element's ``L`` frame in its parent frame
        ``(E, 3)``; the spatial twist is ``(R omega, p_L x R omega + R trans)`` with ``R`` the parent
        rotation and ``p_L`` the ``L`` origin in the base frame (as the element-by-element pass builds it).
        """
        cached = getattr(plan, "_defect_directions", None)
        if cached is not None:
            return cached
        slot_of = {key: i for i, key in enumerate(plan.tapped)}
        slot = np.array([slot_of[key] for key in self._param_element], dtype=int)
        omega = np.zeros((self.n_xi, 3))
        trans = np.zeros((self.n_xi, 3))
        offset = np.zeros((len(plan.tapped), 3))
        xi2 = np.asarray(xi, dtype=float).reshape(1, -1)
        for key, e in slot_of.items():
            info = self._elements[key]
            params = info["params"]
            d, extra = self._element_matrix(info, xi2)
            offset[e] = d[0, :3, 3]
            orient = [(c, params[c]) for c in "IJK" if c in params]
            if orient:
                b, norm = extra["b"], extra["norm"]
                proj = (np.eye(3)[None] - b[:, :, None] * b[:, None, :]) / norm[:, :, None]
                db = np.stack([proj[:, :, _COMP_INDEX[c]] for c, _ in orient], axis=1)
                w_par = minimal_rotation_velocity(np.broadcast_to(info["n0"], b.shape), b, db)[0]
                for j, (_, pi) in enumerate(orient):
                    omega[pi] = w_par[j]
            for c in "abc":
                if c in params:
                    trans[params[c], _COMP_INDEX[c]] = 1.0
            if "G" in params:
                omega[params["G"]] = d[0, :3, 2]
        plan._defect_directions = (slot, omega, trans, offset)  # noqa: SLF001 - per-geometry constants
        return plan._defect_directions

    def _plan_defect_twists(self, plan: FramePlan, xi: np.ndarray, parents: np.ndarray) -> np.ndarray:
        """Spatial twists ``(K, n_xi, 6)`` of the defects from the plan's parent frames (one geometry)."""
        slot, omega, trans, offset = self._defect_directions(plan, xi)
        k = parents.shape[0]
        tw = np.empty((k, self.n_xi, 6))
        if self.n_xi == 0:
            return tw
        rot = parents[:, :, :, :3]  # (K, E, 3, 3)
        origin = np.einsum("keij,ej->kei", rot, offset) + parents[:, :, :, 3]  # L origins (K, E, 3)
        rp = rot[:, slot]  # (K, n_xi, 3, 3)
        w = np.einsum("kpij,pj->kpi", rp, omega)
        tw[:, :, :3] = w
        tw[:, :, 3:] = cross(origin[:, slot], w) + np.einsum("kpij,pj->kpi", rp, trans)
        return tw

    def _joint_twists(self, lframes: dict, k: int) -> np.ndarray:
        """Spatial twist (K, n_q, 6) of every joint from its ``L`` frame (element-by-element path)."""
        tw_q = np.zeros((k, self.n_q, 6))
        for ji, key in enumerate(self._joint_element):
            lf = lframes[key]
            z = lf[:, :3, 2]
            if self._elements[key]["type"] == "R":
                tw_q[:, ji, :3] = z
                tw_q[:, ji, 3:] = cross(lf[:, :3, 3], z)
            else:
                tw_q[:, ji, 3:] = z
        return tw_q

    def evaluate(
        self, q: np.ndarray, xi: np.ndarray | None = None, jacobians: bool | str = True, _elements: tuple | None = None
    ) -> KinematicState:
        """Frames, closure residuals and (optionally) Jacobians at configurations ``q``.

        Parameters
        ----------
        q : ndarray, (K, n_q) or (n_q,)
            Joint values (rad / mm), all joints.
        xi : ndarray, (n_xi,) or (K, n_xi), optional
            Defect values (rad / mm); zero (nominal geometry) if omitted.
        jacobians : bool or "joints" or "actuation"
            Also compute ``dr/dxi``, ``dr/dq`` and the output Jacobians; ``"joints"``
            computes only ``dr/dq`` (what assembly needs); ``"actuation"`` ``dr/dq`` and the output's
            ``dX/dq`` (what solving the actuators for a pose needs), not the defects' columns (the same
            numbers as ``True`` gives for them).
        _elements : tuple, optional
            Internal: the element matrices of ``xi`` (one defect vector per configuration) computed before,
            used where the element-by-element pass runs (:meth:`assemble`'s iterations keep their defects).

        Returns
        -------
        KinematicState
        """
        m = self.mechanism
        q, xi = self._broadcast(q, xi)
        k = q.shape[0]
        fast_rows = None
        fast_full = None
        planned = self.use_plan and xi.shape[0] == 1 and self._worth_a_plan(xi[0], k)
        only_actuation = jacobians == "actuation"
        if planned and jacobians in (False, "joints"):
            # one geometry for all configurations: the lean batched path (hyperstat.solver.kinematics.fastfk)
            run = self.plan(xi[0]).run(q, closure_rows=jacobians == "joints")
            frames, closing_end, fast_rows = run.frames, run.closing, run.closure_q
            lframes = _LazyElementFrames(self, q, xi)
        elif planned:
            # every Jacobian at one geometry: the joint twists and the parents of the defect elements from the
            # lean batched path, the defect screws in their parent frames computed once per geometry
            plan = self.plan(xi[0])
            run = plan.run(q, joint_twists=True, parents=True)
            frames, closing_end = run.frames, run.closing
            fast_full = (run.joint_twists, None if only_actuation else self._plan_defect_twists(plan, xi[0], run.parents))
            lframes = _LazyElementFrames(self, q, xi)
        else:
            frames, closing_end, parents, lframes, extras = self._walk(q, xi, _elements)

        closures = m.closures
        residual = np.zeros((k, 6 * len(closures)))
        for c, cl in enumerate(closures):
            ref = frames[cl.frame]
            other = closing_end[cl.chain]
            rot_err = so3_log(other[:, :3, :3] @ np.swapaxes(ref[:, :3, :3], 1, 2))
            residual[:, 6 * c : 6 * c + 3] = rot_err
            residual[:, 6 * c + 3 : 6 * c + 6] = other[:, :3, 3] - ref[:, :3, 3]
        out_pose = frames[m.output]
        if not jacobians:
            return KinematicState(residual, None, None, out_pose, None, None, frames, lframes)

        # Spatial twists (omega, v) of every defect parameter and every joint.
        only_joints = jacobians == "joints"
        tw_xi = None if only_actuation else np.zeros((k, self.n_xi, 6)) if fast_full is None else fast_full[1]
        for key, info in ([] if only_joints or only_actuation or fast_full is not None else self._elements.items()):
            params = info["params"]
            if not params:
                continue
            parent = parents[key]
            lf = lframes[key]
            origin = lf[:, :3, 3]
            rp = parent[:, :3, :3]
            orient = [(c, params[c]) for c in "IJK" if c in params]
            if orient:
                w_par = extras[key].get("w_par")  # computed before per simulated machine (_with_tilt_velocities)
                if w_par is None:
                    w_par = _tilt_velocities(info["n0"], extras[key]["b"], extras[key]["norm"], orient)
                w_par = np.broadcast_to(w_par, (rp.shape[0],) + w_par.shape[1:])
                w = np.einsum("kij,knj->kni", rp, w_par)
                for j, (_, pi) in enumerate(orient):
                    tw_xi[:, pi, :3] = w[:, j]
                    tw_xi[:, pi, 3:] = cross(origin, w[:, j])
            for c in "abc":
                if c in params:
                    tw_xi[:, params[c], 3:] = rp[:, :, _COMP_INDEX[c]]
            if "G" in params:
                w = lf[:, :3, 2]
                tw_xi[:, params["G"], :3] = w
                tw_xi[:, params["G"], 3:] = cross(origin, w)
        if fast_rows is not None:  # jacobians == "joints" on the batched path
            return KinematicState(residual, None, fast_rows, out_pose, None, None, frames, lframes, None)
        tw_q = self._joint_twists(lframes, k) if fast_full is None else fast_full[0]

        def rows(tw: np.ndarray, weights: np.ndarray, p: np.ndarray) -> np.ndarray:
            # tw (K, n, 6), weights (L, n), p (K, L, 3) -> (K, 6L, n): for each loop the
            # signed twists moved to the loop's frame origin, (omega, v + omega x p);
            # v - [p]x omega as one stacked (3, 3) x (3, n) product per loop
            # (elementwise: the two products of each row of [p]x, as the stacked product computed them)
            n_loops, n = weights.shape
            tw_t = np.ascontiguousarray(tw.transpose(0, 2, 1))  # (K, 6, n)
            runs = _member_runs(weights)
            if runs is not None:  # each loop's members only (issue 39): the same numbers, zeros elsewhere
                out = np.zeros((k, n_loops, 6, n))
                for loop, spans in enumerate(runs):
                    for a, b in spans:
                        _loop_rows(tw_t[:, :, a:b], p[:, loop], weights[loop, a:b], out[:, loop, :, a:b])
                return out.reshape(k, 6 * n_loops, n)
            w0, w1, w2 = (tw_t[:, None, i] for i in range(3))  # (K, 1, n)
            px, py, pz = (p[..., i, None] for i in range(3))  # (K, L, 1)
            out = np.empty((k, n_loops, 6, n))
            out[:, :, :3] = tw_t[:, None, :3]
            np.subtract(tw_t[:, None, 3], py * w2 - pz * w1, out=out[:, :, 3])
            np.subtract(tw_t[:, None, 4], pz * w0 - px * w2, out=out[:, :, 4])
            np.subtract(tw_t[:, None, 5], px * w1 - py * w0, out=out[:, :, 5])
            out *= weights[None, :, None, :]
            return out.reshape(k, 6 * n_loops, n)

        if closures:
            points = np.stack([frames[cl.frame][:, :3, 3] for cl in closures], axis=1)  # (K, L, 3)
        else:
            points = np.zeros((k, 0, 3))
        bq = rows(tw_q, self._closure_sign[:, self._joint_el_idx], points)
        if only_joints:
            return KinematicState(residual, None, bq, out_pose, None, None, frames, lframes, None)
        if only_actuation:
            o_q = rows(tw_q, self._output_member[None, self._joint_el_idx], out_pose[:, None, :3, 3])
            return KinematicState(residual, None, bq, out_pose, None, o_q, frames, lframes, None)
        # closure rows of the defects and output rows of defects and joints: the output is one
        # more "loop" (weights: membership of the output path, point: the output origin)
        n_rows = 6 * len(closures)
        both = rows(tw_xi, np.vstack([self._closure_sign[:, self._param_el_idx],
                                      self._output_member[None, self._param_el_idx]]),
                    np.concatenate([points, out_pose[:, None, :3, 3]], axis=1))
        a, o_xi = both[:, :n_rows], both[:, n_rows:]
        o_q = rows(tw_q, self._output_member[None, self._joint_el_idx], out_pose[:, None, :3, 3])
        return KinematicState(residual, a, bq, out_pose, o_xi, o_q, frames, lframes, tw_xi)

    # ------------------------------------------------------------------ assembly
    def scaled(self, residual: np.ndarray) -> np.ndarray:
        """Residual with rotation rows multiplied by the length scale (all in mm)."""
        r = residual.copy()
        for c in range(r.shape[-1] // 6):
            r[..., 6 * c : 6 * c + 3] *= self.length_scale
        return r

    def residual_norm(self, residual: np.ndarray) -> np.ndarray:
        """Norm of the scaled residual per configuration (mm)."""
        return np.linalg.norm(self.scaled(residual), axis=-1)

    def assemble(
        self,
        q: np.ndarray,
        xi: np.ndarray | None = None,
        tol: float = 1e-9,
        max_iter: int = 40,
        max_step: float = 0.3,
        _elements: tuple | None = None,
        _inverse: np.ndarray | None = None,
    ) -> AssemblyResult:
        """Solve the passive joints by Gauss-Newton (least squares when over-constrained).

        Parameters
        ----------
        q : ndarray, (K, n_q)
            Actuated values to hold and initial guesses of the passive joints.
        xi : ndarray, optional
            Defects (rad / mm).
        tol : float
            Convergence tolerance on the scaled residual step, relative to the length scale.
        max_iter : int
            Maximum Gauss-Newton iterations.
        max_step : float
            Largest revolute step per iteration (rad); prismatic steps are scaled alike
            by the length scale.
        _elements : tuple, optional
            Internal: the element matrices of ``xi`` (one defect vector per configuration,
            :meth:`_all_element_matrices`) computed before, when the same machines are assembled again.
        _inverse : ndarray, (K, n_p, n_r), optional
            Internal: an approximate inverse of each row's passive closure map (rotation rows scaled by the
            length scale, as the iterations scale them), e.g. the nominal machine's at a nearby configuration.
            The rows then take chord steps with it (the residual only: no Jacobian, no solve) while they contract
            by :data:`CHORD_RATE` at least, and stop when the step is below ``tol`` and the error the chord
            leaves (the step times its contraction) is below :data:`CHORD_LEFT`: the same fixed point (the residual's
            zero), to the round-off.  A row whose chord does not contract goes on by Gauss-Newton.  Square passive
            maps only (an over-constrained map's least-squares point depends on its own Jacobian): otherwise ignored.

        Returns
        -------
        AssemblyResult
        """
        q = np.atleast_2d(np.array(q, dtype=float))
        passive = self.mechanism.passive
        if len(self.mechanism.closures) == 0 or len(passive) == 0:
            st = self.evaluate(q, xi, jacobians=False)
            res = self.residual_norm(st.residual)
            return AssemblyResult(q, res, res <= tol * self.length_scale, output_pose=np.array(st.output_pose))
        types = np.array([self.mechanism.joints[i].type for i in passive])
        step_cap = np.where(types == "R", max_step, max_step * self.length_scale)
        active = np.ones(q.shape[0], dtype=bool)
        prev = np.full(q.shape[0], np.inf)
        # one defect vector per configuration (simulated machines): the element matrices depend on the defects
        # only, so they are computed once for every iteration (the same arithmetic row by row: the same bits)
        every = None
        if xi is not None and np.ndim(xi) == 2 and len(xi) == len(q) > 1:
            xi = np.asarray(xi, dtype=float)
            every = self._all_element_matrices(xi) if _elements is None else _elements
        chord = _inverse is not None and 6 * len(self.mechanism.closures) == len(passive)
        # the rows taking chord steps with ``_inverse`` (the others Gauss-Newton), and each row's last step
        by_chord = np.full(q.shape[0], chord)
        last = np.full(q.shape[0], np.inf)
        for _ in range(max_iter):
            idx = np.nonzero(active)[0]
            if idx.size == 0:
                break
            if not chord:
                r, dq = self._gauss_newton_steps(q, xi, every, idx)
            else:
                r, dq = self._chord_steps(q, xi, every, idx, by_chord[idx], _inverse)
            ratio = np.max(np.abs(dq) / step_cap, axis=1, keepdims=True)
            dq = dq / np.maximum(ratio, 1.0)
            q[np.ix_(idx, passive)] += dq
            stepn = np.max(np.abs(dq) / step_cap * max_step, axis=1)
            rn = np.linalg.norm(r, axis=1)
            stalled = (rn >= prev[idx] * 0.999999) & (stepn < 1e-6)
            converged = stepn < tol
            if chord:
                # a Gauss-Newton step leaves an error of the order of its square, a chord step the step times its
                # contraction (this step over the last one; one, unknown, at the first): a chord row stops when that
                # error, too, is at the round-off; a chord that does not contract hands its row to Gauss-Newton
                known = np.isfinite(last[idx])
                rate = np.where(known, stepn / np.where(known, last[idx], 1.0), 1.0)
                on = by_chord[idx]
                converged &= ~on | (stepn * np.minimum(rate, 1.0) < CHORD_LEFT)
                by_chord[idx[on & known & (rate > CHORD_RATE)]] = False
                last[idx] = stepn
            done = converged | (rn < 1e-13 * self.length_scale) | stalled
            prev[idx] = rn
            active[idx[done]] = False
        st = self.evaluate(q, xi, jacobians=False, _elements=every)
        res = self.residual_norm(st.residual)
        return AssemblyResult(q, res, res <= 1e-7 * self.length_scale, output_pose=np.array(st.output_pose))

    def _gauss_newton_steps(self, q: np.ndarray, xi, every, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The scaled residuals and the Gauss-Newton steps of the passive joints at the rows ``idx`` of ``q``
        (:meth:`assemble`'s iteration)."""
        passive = self.mechanism.passive
        st = self.evaluate(q[idx], None if xi is None else (xi if np.ndim(xi) == 1 else xi[idx]), "joints",
                           _elements=_element_rows(every, idx, len(q)))
        r = self.scaled(st.residual)
        # a copy of the passive columns (the same values as ``closure_q[:, :, passive]``, gathered at half the cost of
        # the advanced index on the last axis), scaled in place as scaled_rows scales its copy
        b = np.take(st.closure_q, passive, axis=2)
        for c in range(b.shape[-2] // 6):
            b[..., 6 * c : 6 * c + 3, :] *= self.length_scale
        return r, -batched_lstsq(b, r[..., None])[..., 0]

    def _chord_steps(self, q: np.ndarray, xi, every, idx: np.ndarray, on: np.ndarray,
                     inverse: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The scaled residuals and the steps at the rows ``idx`` of ``q``: chord steps with ``inverse`` where ``on``
        (the residual only), Gauss-Newton steps elsewhere (:meth:`assemble` with ``_inverse``)."""
        if not on.all():
            r = np.empty((idx.size, 6 * len(self.mechanism.closures)))
            dq = np.empty((idx.size, len(self.mechanism.passive)))
            if (~on).any():
                r[~on], dq[~on] = self._gauss_newton_steps(q, xi, every, idx[~on])
            if on.any():
                r[on], dq[on] = self._chord_steps(q, xi, every, idx[on], on[on], inverse)
            return r, dq
        st = self.evaluate(q[idx], None if xi is None else (xi if np.ndim(xi) == 1 else xi[idx]), False,
                           _elements=_element_rows(every, idx, len(q)))
        r = self.scaled(st.residual)
        return r, -np.einsum("kpr,kr->kp", inverse[idx], r)

    def scaled_rows(self, jac: np.ndarray) -> np.ndarray:
        """Jacobian with rotation rows multiplied by the length scale."""
        j = jac.copy()
        for c in range(j.shape[-2] // 6):
            j[..., 6 * c : 6 * c + 3, :] *= self.length_scale
        return j

    @property
    def joint_scale(self) -> np.ndarray:
        """Column scale of joint variables: 1 for revolute (rad), the length scale for prismatic (mm)."""
        return np.array([1.0 if j.type == "R" else self.length_scale for j in self.mechanism.joints])

    @property
    def parameter_scale(self) -> np.ndarray:
        """Column scale of defects: 1 for angles (rad), the length scale for positions (mm)."""
        return np.array([self.length_scale if p.unit == "mm" else 1.0 for p in self.mechanism.parameters])

    def dimensionless(self, jac: np.ndarray, column_scale: np.ndarray | None = None) -> np.ndarray:
        """Jacobian with position rows divided and length columns multiplied by the length scale.

        Rows come in blocks of six (rotation, position); the result relates
        dimensionless quantities (rad, and mm per length scale), so that singular
        values of mixed angle / length matrices are comparable.
        """
        j = np.array(jac, dtype=float, copy=True)
        for c in range(j.shape[-2] // 6):
            j[..., 6 * c + 3 : 6 * c + 6, :] /= self.length_scale
        if column_scale is not None:
            j = j * column_scale
        return j

    def check_home(self) -> None:
        """Raise :class:`AssemblyError` if the nominal home configuration does not close."""
        st = self.evaluate(self.mechanism.home[None, :], jacobians=False)
        for c, cl in enumerate(self.mechanism.closures):
            r = st.residual[0, 6 * c : 6 * c + 6]
            rot, pos = np.linalg.norm(r[:3]), np.linalg.norm(r[3:])
            if rot * self.length_scale + pos > 1e-6 * self.length_scale:
                raise AssemblyError(
                    f"the nominal mechanism '{self.mechanism.name}' does not close at its home configuration: "
                    f"loop '{cl.label(self.mechanism)}' misses by {pos:.4g} mm and {rot:.4g} rad."
                )

    def solve(
        self,
        q_actuated: np.ndarray,
        xi: np.ndarray | None = None,
        start: np.ndarray | None = None,
        steps: int = 6,
        options: ContinuationOptions | None = None,
    ) -> AssemblyResult:
        """Assemble at actuated values on the branch of ``start`` (default: home).

        Predictor-corrector continuation (:func:`hyperstat.solver.kinematics.continuation.continue_path`;
        more than 8 targets from one start are taken each from the nearest configuration already
        certified, :func:`~hyperstat.solver.kinematics.continuation.continue_nearest`):
        tangent predictor ``dq_p = -B_p^+ B_a dq_a`` (implicit function theorem on the
        closure, paper 1, eqs. 3, 7, 9), Newton corrector, adaptive steps, and a branch
        certificate per configuration.  **Guarantee**: a configuration with
        ``converged`` true was reached by steps each shorter than a quarter of the
        estimated distance ``2 sigma_min(B_p) / gamma`` to any other solution, with a
        contracting corrector and ``B_p`` well conditioned, so it lies on the branch of
        ``start`` (the estimates are from the computed path, see the module of
        :func:`~hyperstat.solver.kinematics.continuation.continue_path`).  A configuration
        that cannot be certified has ``converged`` false, the reason in
        ``result.certificate.reason``, and ``q`` from a plain least-squares assembly at the
        target from the last certified point (which may be on another branch: do not
        use it as a certified configuration).

        Parameters
        ----------
        q_actuated : ndarray, (K, n_actuated)
            Target actuated values (rad / mm).
        xi : ndarray, optional
            Defects (rad / mm), (n_xi,) or (K, n_xi).
        start : ndarray, (n_q,) or (K, n_q), optional
            Assembled start configuration(s).
        steps : int
            The first step is ``1/steps`` of the path; later steps adapt.
        options : ContinuationOptions, optional
            Step control and certificate thresholds.

        Returns
        -------
        AssemblyResult
            With ``certificate``.
        """
        qa = np.atleast_2d(np.asarray(q_actuated, dtype=float))
        opt = options or ContinuationOptions(initial_steps=max(int(steps), 1))
        q0 = self.mechanism.home if start is None else np.asarray(start, dtype=float)
        if len(qa) > 8 and np.ndim(q0) == 1 and (xi is None or np.ndim(xi) == 1):
            # many targets from one start: each from the nearest configuration already certified
            # (a chain of certified paths back to the start; shorter paths, fewer steps)
            q, cert = continue_nearest(self, qa, xi, q0, options)
        else:
            q, cert = continue_path(self, q0, qa, xi, opt)
        act = self.mechanism.actuated
        lost = ~cert.certified
        if np.any(lost):  # best effort at the target, flagged as not converged
            qq = q[lost].copy()
            qq[:, act] = qa[lost]
            xl = None if xi is None else (xi if np.ndim(xi) == 1 or len(qa) == 1 else np.asarray(xi)[lost])
            q[lost] = self.assemble(qq, xl).q
        ok = np.nonzero(cert.certified)[0]
        if ok.size and len(self.mechanism.closures) and len(self.mechanism.passive):
            # one last Gauss-Newton update polishes the end points (they were converged to 1e-12 of the
            # length scale) down to round-off; it moves them by less than that
            pas = self.mechanism.passive
            xo = None if xi is None else (xi if np.ndim(xi) == 1 or len(qa) == 1 else np.asarray(xi)[ok])
            sto = self.evaluate(q[ok], xo, "joints")
            dq = -batched_lstsq(self.scaled_rows(sto.closure_q[:, :, pas]), self.scaled(sto.residual)[..., None])[..., 0]
            small = np.max(np.abs(dq) / self.joint_scale[pas], axis=1) < 1e-9
            q[np.ix_(ok[small], pas)] += dq[small]
        st = self.evaluate(q, xi, jacobians=False)
        res = self.residual_norm(st.residual)
        converged = (res <= 1e-7 * self.length_scale) & cert.certified
        return AssemblyResult(q, res, converged, cert)


def _tilt_velocities(n0: np.ndarray, b: np.ndarray, norm: np.ndarray, orient: list) -> np.ndarray:
    """Angular velocity (K, n, 3) in the parent frame per unit of each axis-tilt defect ``orient`` of an element whose
    tilted axis is ``b`` (K, 3) of length ``norm`` (K, 1) before normalising (the element-by-element Jacobians)."""
    proj = (np.eye(3)[None] - b[:, :, None] * b[:, None, :]) / norm[:, :, None]
    db = np.stack([proj[:, :, _COMP_INDEX[c]] for c, _ in orient], axis=1)  # (K, n, 3)
    return minimal_rotation_velocity(np.broadcast_to(n0, b.shape), b, db)


def _with_tilt_velocities(kin: Kinematics, elements: tuple) -> tuple:
    """:meth:`Kinematics._all_element_matrices`' output with each tilted element's ``w_par``
    (:func:`_tilt_velocities`) among its extras: what :meth:`Kinematics.evaluate` with Jacobians computes from them
    row by row, computed once for these rows (simulated machines: once per machine, then repeated to its
    configurations by :func:`_element_rows`; each row's alone, so the same bits)."""
    mats, extras = elements
    out = {}
    for key, extra in extras.items():
        params = kin._elements[key]["params"]  # noqa: SLF001
        orient = [(c, params[c]) for c in "IJK" if c in params]
        out[key] = dict(extra, w_par=_tilt_velocities(kin._elements[key]["n0"], extra["b"], extra["norm"], orient)) \
            if orient else extra
    return mats, out


def _element_rows(elements: tuple | None, idx: np.ndarray, k: int) -> tuple | None:
    """The rows ``idx`` of :meth:`Kinematics._all_element_matrices`' output for ``k`` configurations (all: as is)."""
    if elements is None or len(idx) == k:
        return elements
    mats, extras = elements
    return ({key: d[idx] for key, d in mats.items()},
            {key: {name: v[idx] for name, v in e.items()} for key, e in extras.items()})


#: :meth:`Kinematics.assemble` with ``_inverse``: a chord step must be shorter than this share of the step before it,
#: else its row goes on by Gauss-Newton
CHORD_RATE = 0.02
#: a chord row stops when its step is below the tolerance and the error it leaves (the step times its contraction) is
#: below this (rad, or per length scale): the round-off of joint values of order one
CHORD_LEFT = 1e-16

#: a loop's members are taken as column runs (:func:`_member_runs`) when at most this share of the
#: (loop, column) weights is non-zero (the hexapod's defects: 31 %; the Triflex-II's: 63 %, dense)
SPARSE_MEMBERS = 0.5
_RUNS: dict = {}


def _member_runs(weights: np.ndarray) -> list | None:
    """Each row's non-zero columns as contiguous ``(start, stop)`` runs, or None when the rows are dense.

    Read once per weight matrix (the matrices are the model's constant memberships).

    >>> _member_runs(np.array([[1.0, 1.0, 0.0, 0.0, 0.0, -1.0], [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]]))
    [[(0, 2), (5, 6)], [(4, 5)]]
    """
    key = (weights.shape, weights.tobytes())
    if key not in _RUNS:
        nz = weights != 0
        runs = None
        if nz.size and nz.mean() <= SPARSE_MEMBERS:
            runs = []
            for row in nz:
                edges = np.flatnonzero(np.diff(np.r_[0, row.astype(np.int8), 0]))
                runs.append([(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])])
            if sum(len(r) for r in runs) > 4 * len(runs):  # scattered members: one dense pass is cheaper
                runs = None
        _RUNS[key] = runs
    return _RUNS[key]


def _loop_rows(tw_t: np.ndarray, p: np.ndarray, weights: np.ndarray, out: np.ndarray) -> None:
    """One loop's rows of a column run: ``out`` (K, 6, m) = ``(omega, v - p x omega) * weights``.

    The same element-wise operations, in the same order, as the dense path of ``Kinematics.evaluate``.
    """
    w0, w1, w2 = tw_t[:, 0], tw_t[:, 1], tw_t[:, 2]  # (K, m)
    px, py, pz = p[:, 0, None], p[:, 1, None], p[:, 2, None]  # (K, 1)
    # computed in a contiguous block, written once into ``out`` (a strided view of a large array: each pass over
    # it costs more than the arithmetic); the same products, differences and weights as before, bit for bit
    block = np.empty(out.shape)
    block[:, :3] = tw_t[:, :3]
    np.subtract(tw_t[:, 3], py * w2 - pz * w1, out=block[:, 3])
    np.subtract(tw_t[:, 4], pz * w0 - px * w2, out=block[:, 4])
    np.subtract(tw_t[:, 5], px * w1 - py * w0, out=block[:, 5])
    block *= weights[None, None, :]
    out[...] = block
