"""Lean batched forward kinematics for one constant geometry (frames and joint screws).

Units: lengths in mm, angles in rad.

The forward model of paper 1 (eq. 2) is a product of constant geometric matrices
``D_i`` and motion matrices ``M_i(q_i)`` along each chain.  When the defects ``xi``
are the same for every configuration (the nominal geometry, or one identified
machine), every ``D_i`` is a constant and a batch of ``K`` configurations can be
evaluated with few, large numpy operations instead of one small operation per
element and per quantity.  This module does that:

* A frame is held as its top three rows, ``(3, K, 4)`` (row, configuration, column),
  so that ``T @ D`` for all configurations is one BLAS product of a ``(3K, 4)``
  matrix by the constant ``(4, 4)`` matrix ``D``.
* A revolute motion ``Rz(theta)`` only mixes the first two columns:
  ``(c0, c1) -> (cos c0 + sin c1, cos c1 - sin c0)``.  Seen as complex numbers
  ``z = c0 + i c1`` this is ``z * exp(-i theta)``: one complex multiplication of a
  strided view, no copy.
* ``cos`` and ``sin`` come from one tangent of the half angle,
  ``t = tan(theta/2)``, ``cos = 2/(1+t^2) - 1``, ``sin = 2t/(1+t^2)``, for all joints
  at once (numpy's vectorised ``tan`` is several times cheaper than ``sin`` plus ``cos``).
* A prismatic motion adds ``x`` times the third column to the fourth.
* Configurations are processed in chunks that stay in the L2 cache and keep the BLAS
  product single-threaded (``3 * chunk * 16`` multiply-adds below OpenBLAS's threading
  threshold); chunks run on a small thread pool (numpy releases the GIL in its loops).

Optionally the spatial twist ``(omega, v)`` of every joint (``v``: velocity of the point
at the base origin) is returned, from which :class:`hyperstat.solver.kinematics.closure.Kinematics` builds
the closure and output Jacobians (paper 2, eq. 7).  Cross-checked in the tests against
the element-by-element path of :meth:`hyperstat.solver.kinematics.closure.Kinematics.evaluate` and, for a
serial chain, against pinocchio in ``benchmarks/run.py``.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from hyperstat.solver.kinematics.model import Joint, Mechanism

__all__ = ["FramePlan", "PlanResult", "DEFAULT_CHUNK"]

#: Configurations per chunk: 3 * 4096 * 16 = 196,608 multiply-adds per BLAS call, below
#: OpenBLAS's single-thread threshold (262,144), and two (3, 4096, 4) frames (786 KiB) fit in L2.
DEFAULT_CHUNK = 4096

_POOL: ThreadPoolExecutor | None = None
#: the number of CPUs, read once (``os.cpu_count`` reads the system's CPU list at every call: 0.1 ms, thousands of
#: times in a worst-case search of small batches)
_CPUS = os.cpu_count() or 1


def _pool(threads: int) -> ThreadPoolExecutor:
    global _POOL
    if _POOL is None or _POOL._max_workers < threads:  # noqa: SLF001 - size check only
        _POOL = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="hyperstat-fk")
    return _POOL


@dataclass
class PlanResult:
    """Frames (and joint twists) at a batch of configurations.

    Attributes
    ----------
    frames : dict
        Frame name -> (K, 4, 4) transform in the base frame (base included).
    closing : dict
        Index of a closing chain -> (K, 4, 4) frame that chain reaches (to compare with
        the frame of the same name reached by its defining chain, eq. 7).
    joint_twists : ndarray, (K, n_q, 6) or None
        Spatial twist ``(omega, v)`` of every joint per unit joint velocity (rad/s or
        mm/s); ``v`` is the velocity of the point at the base origin.
    jacobian : ndarray, (K, 6, n_q) or None
        Jacobian of the frame named in ``run(jacobian_at=...)``, rows ``(omega, v)`` at
        its origin, base axes.
    closure_q : ndarray, (K, 6 L, n_q) or None
        ``dr/dq`` of the loop closures (``run(closure_rows=True)``).
    parents : ndarray, (K, E, 3, 4) or None
        Top three rows ``[R | p]`` of the frame each element of ``FramePlan(tapped=...)``
        starts from (the frame before its ``D``), in the order of ``tapped``
        (``run(parents=True)``).
    """

    frames: dict
    closing: dict
    joint_twists: np.ndarray | None = None
    jacobian: np.ndarray | None = None
    closure_q: np.ndarray | None = None
    parents: np.ndarray | None = None


class FramePlan:
    """A mechanism compiled for one constant geometry.

    Parameters
    ----------
    mechanism : Mechanism
        The model (its chains, joints and topology).
    matrices : dict
        ``(chain, element)`` -> (4, 4) matrix ``D`` of every element at the geometry of
        interest (what :meth:`hyperstat.solver.kinematics.closure.Kinematics.element_matrices` returns).
    tapped : list of (chain, element), optional
        Elements whose parent frame ``run(parents=True)`` returns (the frames the defect
        twists of :meth:`hyperstat.solver.kinematics.closure.Kinematics.evaluate` are built from).

    Examples
    --------
    >>> plan = FramePlan(mech, kin.element_matrices())       # doctest: +SKIP
    >>> plan.run(q).frames[mech.output].shape                # doctest: +SKIP
    (K, 4, 4)
    """

    def __init__(self, mechanism: Mechanism, matrices: dict, tapped: list | None = None) -> None:
        m = mechanism
        self.mechanism = m
        self.n_q = len(m.joints)
        self.base = m.base
        self.tapped = [tuple(key) for key in (tapped or [])]
        slot_of = {key: i for i, key in enumerate(self.tapped)}
        # (start, [(D (4,4), joint index or -1, type or None, tap slot or -1)], end, closing chain or None)
        self._chains = []
        defined = {m.base}
        for ci in m.topology["order"]:
            ch = m.chains[ci]
            ops = []
            for ei, el in enumerate(ch.elements):
                d = np.ascontiguousarray(np.asarray(matrices[(ci, ei)], dtype=float)[:4, :4])
                slot = slot_of.get((ci, ei), -1)
                if isinstance(el, Joint):
                    ops.append((d, m.joint_index[el.name], el.type, slot))
                else:
                    ops.append((d, -1, None, slot))
            closing = ci if ch.end in defined else None
            defined.add(ch.end)
            self._chains.append((ch.start, ops, ch.end, closing))
        self.frame_names = [m.base] + [end for _, _, end, closing in self._chains if closing is None]
        self.closing_chains = [closing for _, _, _, closing in self._chains if closing is not None]
        types = [j.type for j in m.joints]
        self._rev = np.array([i for i, t in enumerate(types) if t == "R"], dtype=int)
        self._pri = np.array([i for i, t in enumerate(types) if t == "P"], dtype=int)
        self._rev_slot = {int(j): s for s, j in enumerate(self._rev)}
        # loop closures (eq. 7): signed joints of the closing path minus the defining path
        self._closures = []
        for cl in m.closures:
            sign = np.zeros(self.n_q)
            for path, sgn in ((cl.path, 1.0), (cl.reference_path, -1.0)):
                for ci, ei in path:
                    el = m.chains[ci].elements[ei]
                    if isinstance(el, Joint):
                        sign[m.joint_index[el.name]] += sgn
            rev = np.array([j for j in self._rev if sign[j] != 0], dtype=int)
            pri = np.array([j for j in self._pri if sign[j] != 0], dtype=int)
            self._closures.append((cl.frame, rev, sign[rev], pri, sign[pri]))

    # ------------------------------------------------------------------ flop count
    def flops_per_configuration(self) -> dict:
        """Arithmetic of the plan per configuration (the minimal count, not what BLAS executes).

        A product ``[R|p] @ D`` with a constant rigid ``D`` costs 27 multiplications and
        18 additions for the rotation and 9 + 9 for the origin (63); a revolute motion
        mixes two columns of three rows (12 multiplications, 6 additions: 18) and needs
        one ``(cos, sin)`` pair; a prismatic motion adds ``x`` times a column (6).

        Returns
        -------
        dict
            ``{"flops": arithmetic operations, "trig_pairs": number of (cos, sin) pairs}``.
        """
        flops = 0
        pairs = 0
        for start, ops, _, _ in self._chains:
            for k, (_, j, typ, _slot) in enumerate(ops):
                if not (k == 0 and start == self.base):
                    flops += 63  # the first element after the base is D itself
                if typ == "R":
                    flops += 18
                    pairs += 1
                elif typ == "P":
                    flops += 6
        return {"flops": flops, "trig_pairs": pairs}

    # ------------------------------------------------------------------ evaluation
    def run(
        self,
        q: np.ndarray,
        joint_twists: bool = False,
        chunk: int = DEFAULT_CHUNK,
        threads: int | None = None,
        frames: list[str] | None = None,
        jacobian_at: str | None = None,
        closure_rows: bool = False,
        parents: bool = False,
    ) -> PlanResult:
        """Frames at configurations ``q`` (and the joint twists, or a frame's Jacobian).

        Parameters
        ----------
        q : ndarray, (K, n_q) or (n_q,)
            Joint values (rad / mm).
        joint_twists : bool
            Also return the spatial twist of every joint.
        chunk : int
            Configurations per chunk.
        threads : int, optional
            Worker threads for the chunks (default: the number of CPUs, at most the
            number of chunks).
        frames : list of str, optional
            Named frames to return (default: all, base included).
        jacobian_at : str, optional
            A named frame: also return its Jacobian ``(K, 6, n_q)``, rows ``(omega, v)``
            (angular velocity, velocity of the frame origin, base axes) per unit joint
            velocity; joints off its defining path have zero columns.
        closure_rows : bool
            Also return ``dr/dq`` of the loop closures (eqs. 7, 9), ``(K, 6 L, n_q)``:
            per loop the signed joint screws at the origin of the loop's frame.
        parents : bool
            Also return the parent frame of every tapped element (see :class:`PlanResult`).

        Returns
        -------
        PlanResult
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.shape[1] != self.n_q:
            raise ValueError(f"q must have {self.n_q} columns (one per joint), got {q.shape[1]}.")
        k = q.shape[0]
        names = self.frame_names if frames is None else list(frames)
        if jacobian_at is not None and jacobian_at not in names:
            names.append(jacobian_at)
        out_frames = {}
        for name in names:
            buf = np.empty((k, 4, 4))
            buf[:, 3, :] = (0.0, 0.0, 0.0, 1.0)
            out_frames[name] = buf
        out_closing = {}
        for ci in self.closing_chains:
            buf = np.empty((k, 4, 4))
            buf[:, 3, :] = (0.0, 0.0, 0.0, 1.0)
            out_closing[ci] = buf
        tw = np.empty((k, self.n_q, 6)) if joint_twists else None
        jac = None
        path = None
        if jacobian_at is not None:
            jac = np.empty((k, 6, self.n_q))
            path = np.zeros(self.n_q, dtype=bool)
            for ci, ei in self.mechanism.path_to(jacobian_at):
                el = self.mechanism.chains[ci].elements[ei]
                if isinstance(el, Joint):
                    path[self.mechanism.joint_index[el.name]] = True
        rows_q = np.empty((k, 6 * len(self._closures), self.n_q)) if closure_rows else None
        par = np.empty((k, len(self.tapped), 3, 4)) if parents else None
        qt = np.ascontiguousarray(q.T)  # (n_q, K): joint rows are contiguous
        chunk = max(int(chunk), 1)
        starts = list(range(0, k, chunk))
        n_threads = min(threads or _CPUS, len(starts))

        def work(s: int) -> None:
            self._chunk(qt[:, s : s + chunk], s, out_frames, out_closing, tw, jac, jacobian_at, path, rows_q, par)

        if n_threads <= 1:
            for s in starts:
                work(s)
        else:
            list(_pool(n_threads).map(work, starts))
        if self.base in out_frames:
            out_frames[self.base][:, :3, :] = np.eye(4)[:3]
        if frames is not None and jacobian_at is not None and jacobian_at not in frames:
            out_frames.pop(jacobian_at)
        return PlanResult(out_frames, out_closing, tw, jac, rows_q, par)

    def _chunk(self, q, s, out_frames, out_closing, tw, jac, jacobian_at, path, rows_q, par=None) -> None:
        """Evaluate one chunk ``q`` (n_q, k) and write its rows ``s:s+k`` of the outputs."""
        k = q.shape[1]
        e = None
        if self._rev.size:
            # exp(-i theta) = cos - i sin from t = tan(theta / 2)
            h = np.multiply(q[self._rev], 0.5)
            np.tan(h, out=h)
            u = np.multiply(h, h)
            u += 1.0
            np.divide(-2.0, u, out=u)  # u = -2 / (1 + t^2)
            e = np.empty(h.shape, dtype=complex)
            np.multiply(h, u, out=e.imag)  # -sin
            np.subtract(-1.0, u, out=e.real)  # cos = 2 / (1 + t^2) - 1
        need_axes = tw is not None or jac is not None or rows_q is not None
        axis = np.empty((self.n_q, 3, k)) if need_axes else None  # z of every L_j
        origin = np.empty((self.n_q, 3, k)) if need_axes else None  # origin of every L_j
        reached: dict[str, np.ndarray | None] = {self.base: None}  # None: identity
        rows = slice(s, s + k)
        end_frame = None
        for start, ops, end, closing in self._chains:
            t = reached[start]
            for d, j, typ, slot in ops:
                if par is not None and slot >= 0:
                    if t is None:
                        par[rows, slot] = np.eye(4)[:3]
                    else:
                        par[rows, slot] = t.transpose(1, 0, 2)
                y = np.empty((3, k, 4))
                if t is None:
                    y[...] = d[:3, None, :]
                else:
                    np.matmul(t.reshape(3 * k, 4), d, out=y.reshape(3 * k, 4))
                if j >= 0:
                    if need_axes:
                        axis[j] = y[:, :, 2]
                        origin[j] = y[:, :, 3]
                    if typ == "R":
                        z = y.view(complex)[:, :, 0]
                        np.multiply(z, e[self._rev_slot[j]], out=z)
                    else:
                        y[:, :, 3] += y[:, :, 2] * q[j]
                t = y
            target = out_closing.get(closing) if closing is not None else out_frames.get(end)
            if closing is None:
                reached[end] = t
                if end == jacobian_at:
                    end_frame = t
            if target is not None:
                target[rows, :3, :] = np.eye(4)[:3] if t is None else t.transpose(1, 0, 2)
        if tw is not None:
            block = np.zeros((self.n_q, 6, k))
            if self._rev.size:
                block[self._rev, :3] = axis[self._rev]
                block[self._rev, 3:] = _cross(origin[self._rev], axis[self._rev])  # (z, o x z)
            if self._pri.size:
                block[self._pri, 3:] = axis[self._pri]  # (0, z)
            tw[rows] = block.transpose(2, 0, 1)
        if jac is not None:
            block = np.zeros((self.n_q, 6, k))
            point = np.zeros((1, 3, k)) if end_frame is None else end_frame[None, :, :, 3]
            rev = self._rev[path[self._rev]]
            pri = self._pri[path[self._pri]]
            if rev.size:
                zr = axis[rev]
                block[rev, :3] = zr
                block[rev, 3:] = _cross(zr, point - origin[rev])  # (z, z x (p - o))
            if pri.size:
                block[pri, 3:] = axis[pri]
            jac[rows] = block.transpose(2, 1, 0)
        if rows_q is not None and self._closures:
            block = np.zeros((len(self._closures), self.n_q, 6, k))
            for c, (frame, rev, rsign, pri, psign) in enumerate(self._closures):
                point = np.zeros((1, 3, k)) if reached[frame] is None else reached[frame][None, :, :, 3]
                if rev.size:
                    zr = axis[rev] * rsign[:, None, None]
                    block[c, rev, :3] = zr
                    block[c, rev, 3:] = _cross(zr, point - origin[rev])  # s (z, z x (p - o))
                if pri.size:
                    block[c, pri, 3:] = axis[pri] * psign[:, None, None]
            rows_q[rows].reshape(k, len(self._closures), 6, self.n_q)[...] = block.transpose(3, 0, 2, 1)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over axis 1 of (n, 3, k) arrays."""
    res = np.empty(np.broadcast_shapes(a.shape, b.shape))
    np.multiply(a[:, 1], b[:, 2], out=res[:, 0])
    res[:, 0] -= a[:, 2] * b[:, 1]
    np.multiply(a[:, 2], b[:, 0], out=res[:, 1])
    res[:, 1] -= a[:, 0] * b[:, 2]
    np.multiply(a[:, 0], b[:, 1], out=res[:, 2])
    res[:, 2] -= a[:, 1] * b[:, 0]
    return res
