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
at the base origin) is returned, from which :class:`solver.closure.Kinematics` builds
the closure and output Jacobians (paper 2, eq. 7).  Cross-checked in the tests against
the element-by-element path of :meth:`solver.closure.Kinematics.evaluate` and, for a
serial chain, against pinocchio in ``benchmarks/run.py``.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .model import Joint, Mechanism

__all__ = ["FramePlan", "PlanResult", "DEFAULT_CHUNK"]

#: Configurations per chunk: 3 * 2048 * 16 = 98,304 multiply-adds per BLAS call, below
#: OpenBLAS's single-thread threshold (262,144), and two (3, 2048, 4) frames (393 KiB) fit in L2.
DEFAULT_CHUNK = 2048

_POOL: ThreadPoolExecutor | None = None


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
    """

    frames: dict
    closing: dict
    joint_twists: np.ndarray | None = None


class FramePlan:
    """A mechanism compiled for one constant geometry.

    Parameters
    ----------
    mechanism : Mechanism
        The model (its chains, joints and topology).
    matrices : dict
        ``(chain, element)`` -> (4, 4) matrix ``D`` of every element at the geometry of
        interest (what :meth:`solver.closure.Kinematics.element_matrices` returns).

    Examples
    --------
    >>> plan = FramePlan(mech, kin.element_matrices())       # doctest: +SKIP
    >>> plan.run(q).frames[mech.output].shape                # doctest: +SKIP
    (K, 4, 4)
    """

    def __init__(self, mechanism: Mechanism, matrices: dict) -> None:
        m = mechanism
        self.mechanism = m
        self.n_q = len(m.joints)
        self.base = m.base
        self._chains = []  # (start, [(D (4,4), joint index or -1, type or None)], end, closing chain or None)
        defined = {m.base}
        for ci in m.topology["order"]:
            ch = m.chains[ci]
            ops = []
            for ei, el in enumerate(ch.elements):
                d = np.ascontiguousarray(np.asarray(matrices[(ci, ei)], dtype=float)[:4, :4])
                if isinstance(el, Joint):
                    ops.append((d, m.joint_index[el.name], el.type))
                else:
                    ops.append((d, -1, None))
            closing = ci if ch.end in defined else None
            defined.add(ch.end)
            self._chains.append((ch.start, ops, ch.end, closing))
        self.frame_names = [m.base] + [end for _, _, end, closing in self._chains if closing is None]
        self.closing_chains = [closing for _, _, _, closing in self._chains if closing is not None]
        types = [j.type for j in m.joints]
        self._rev = np.array([i for i, t in enumerate(types) if t == "R"], dtype=int)
        self._pri = np.array([i for i, t in enumerate(types) if t == "P"], dtype=int)
        self._rev_slot = {int(j): s for s, j in enumerate(self._rev)}

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
            for k, (_, j, typ) in enumerate(ops):
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
    ) -> PlanResult:
        """Frames at configurations ``q`` (and the joint twists).

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

        Returns
        -------
        PlanResult
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.shape[1] != self.n_q:
            raise ValueError(f"q must have {self.n_q} columns (one per joint), got {q.shape[1]}.")
        k = q.shape[0]
        names = self.frame_names if frames is None else list(frames)
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
        tw = np.zeros((k, self.n_q, 6)) if joint_twists else None
        qt = np.ascontiguousarray(q.T)  # (n_q, K): joint rows are contiguous
        starts = list(range(0, k, max(int(chunk), 1)))
        n_threads = min(threads or os.cpu_count() or 1, len(starts))

        def work(s: int) -> None:
            self._chunk(qt[:, s : s + chunk], s, out_frames, out_closing, tw)

        if n_threads <= 1:
            for s in starts:
                work(s)
        else:
            list(_pool(n_threads).map(work, starts))
        if self.base in out_frames:
            out_frames[self.base][:, :3, :] = np.eye(4)[:3]
        return PlanResult(out_frames, out_closing, tw)

    def _chunk(self, q: np.ndarray, s: int, out_frames: dict, out_closing: dict, tw: np.ndarray | None) -> None:
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
        axes = np.empty((self.n_q, 3, k, 2)) if tw is not None else None
        reached: dict[str, np.ndarray | None] = {self.base: None}  # None: identity
        rows = slice(s, s + k)
        for start, ops, end, closing in self._chains:
            t = reached[start]
            for d, j, typ in ops:
                y = np.empty((3, k, 4))
                if t is None:
                    y[...] = d[:3, None, :]
                else:
                    np.matmul(t.reshape(3 * k, 4), d, out=y.reshape(3 * k, 4))
                if j >= 0:
                    if axes is not None:
                        axes[j] = y[:, :, 2:4]  # joint axis (z) and origin of L_j
                    if typ == "R":
                        z = y.view(complex)[:, :, 0]
                        np.multiply(z, e[self._rev_slot[j]], out=z)
                    else:
                        y[:, :, 3] += y[:, :, 2] * q[j]
                t = y
            target = out_closing.get(closing) if closing is not None else out_frames.get(end)
            if closing is None:
                reached[end] = t
            if target is not None:
                target[rows, :3, :] = np.eye(4)[:3] if t is None else t.transpose(1, 0, 2)
        if tw is not None:
            z, o = axes[..., 0], axes[..., 1]  # (n_q, 3, k)
            block = tw[rows]
            if self._rev.size:
                zr, orr = z[self._rev], o[self._rev]
                v = np.stack(
                    [orr[:, 1] * zr[:, 2] - orr[:, 2] * zr[:, 1],
                     orr[:, 2] * zr[:, 0] - orr[:, 0] * zr[:, 2],
                     orr[:, 0] * zr[:, 1] - orr[:, 1] * zr[:, 0]],
                    axis=1,
                )
                block[:, self._rev, :3] = zr.transpose(2, 0, 1)
                block[:, self._rev, 3:] = v.transpose(2, 0, 1)
            if self._pri.size:
                block[:, self._pri, 3:] = z[self._pri].transpose(2, 0, 1)
