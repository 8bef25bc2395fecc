"""Forward kinematics of the 6R benchmark arm by the peers that are not dependencies (units: mm, rad).

Each builder takes the arm's geometry (``serial6r.arm_geometry``: the ``D`` matrix of every
element and its joint type) and returns ``fk(q) -> (K, 4, 4)`` output poses, the same
product ``D_1 M_1(q_1) ... D_6 M_6(q_6) D_tool`` as hyperstat (paper 1, eq. 2):

* :func:`numba_fk`: a compiled loop (numba ``njit(parallel=True)``), one configuration at a
  time with its 4 x 4 frame in local storage, ``sin``/``cos`` per joint: the compiled
  reference for what a kernel outside numpy could gain;
* :func:`jax_fk`: the same product in ``jax.numpy``, ``jit`` of ``vmap`` over configurations
  (float64 enabled).

Both raise :class:`ImportError` when their package is missing (``benchmarks/run.py`` then
skips them and says so).  ``benchmarks/run.py`` checks them against ``Kinematics.forward``
to 1e-9 before timing.
"""

from __future__ import annotations

import numpy as np

__all__ = ["numba_fk", "jax_fk"]


def _stack(geometry) -> tuple[np.ndarray, np.ndarray]:
    """``D`` matrices (n, 4, 4) and joint codes (n,): 0 fixed, 1 revolute, 2 prismatic."""
    mats = np.ascontiguousarray(np.array([d for d, _ in geometry], dtype=float))
    codes = np.array([0 if t is None else (1 if t == "R" else 2) for _, t in geometry], dtype=np.int64)
    return mats, codes


def numba_fk(geometry):
    """Compiled (numba) forward kinematics; the first call compiles (do it before timing)."""
    import numba

    mats, codes = _stack(geometry)

    @numba.njit(parallel=True, fastmath=False, cache=False)
    def kernel(q, mats, codes, out):
        n = mats.shape[0]
        for k in numba.prange(q.shape[0]):
            t = np.eye(4)
            tmp = np.empty((4, 4))
            j = 0
            for e in range(n):
                d = mats[e]
                for r in range(4):
                    for c in range(4):
                        tmp[r, c] = t[r, 0] * d[0, c] + t[r, 1] * d[1, c] + t[r, 2] * d[2, c] + t[r, 3] * d[3, c]
                if codes[e] == 1:  # t = tmp @ Rz(q): columns 0 and 1 rotate
                    cq, sq = np.cos(q[k, j]), np.sin(q[k, j])
                    for r in range(4):
                        a, b = tmp[r, 0], tmp[r, 1]
                        t[r, 0] = a * cq + b * sq
                        t[r, 1] = -a * sq + b * cq
                        t[r, 2] = tmp[r, 2]
                        t[r, 3] = tmp[r, 3]
                    j += 1
                elif codes[e] == 2:  # t = tmp @ Tz(q)
                    for r in range(4):
                        t[r, 0], t[r, 1], t[r, 2] = tmp[r, 0], tmp[r, 1], tmp[r, 2]
                        t[r, 3] = tmp[r, 3] + tmp[r, 2] * q[k, j]
                    j += 1
                else:
                    for r in range(4):
                        for c in range(4):
                            t[r, c] = tmp[r, c]
            for r in range(4):
                for c in range(4):
                    out[k, r, c] = t[r, c]

    def fk(q: np.ndarray) -> np.ndarray:
        q = np.ascontiguousarray(q, dtype=float)
        out = np.empty((q.shape[0], 4, 4))
        kernel(q, mats, codes, out)
        return out

    fk(np.zeros((2, int(np.sum(codes > 0)))))  # compile
    return fk


def jax_fk(geometry):
    """JAX ``jit(vmap(...))`` forward kinematics in float64; the first call compiles."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    mats, codes = _stack(geometry)
    dm = [jnp.asarray(m) for m in mats]

    def one(qk):
        t = jnp.eye(4)
        j = 0
        for e, code in enumerate(codes):
            t = t @ dm[e]
            if code == 1:
                c, s = jnp.cos(qk[j]), jnp.sin(qk[j])
                rz = jnp.array([[c, -s, 0.0, 0.0], [s, c, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
                t = t @ rz
                j += 1
            elif code == 2:
                tz = jnp.eye(4).at[2, 3].set(qk[j])
                t = t @ tz
                j += 1
        return t

    batched = jax.jit(jax.vmap(one))

    def fk(q: np.ndarray) -> np.ndarray:
        return np.asarray(batched(jnp.asarray(q)).block_until_ready())

    fk(np.zeros((2, int(np.sum(codes > 0)))))  # compile
    return fk
