"""The nominal machine's output twist maps at blocks of configurations, kept for the stages that read them again.

Units: the maps relate rad and mm as :func:`hyperstat.solver.tolerances.accuracy.output_twist_maps` states
(twists ``(omega [rad], v [mm])`` per unit defect and per unit actuated value).

One ``accuracy`` or ``report`` evaluates the nominal machine's full Jacobians at the same configurations
several times: the workspace sample for the task summary of the allocations and again for the bounds' search,
the structured candidates (corners, edges, dead centres) for each of the three searches' objectives.  They are
evaluated in the same blocks (:data:`hyperstat.solver.tolerances.values.TASK_BLOCK` and
:data:`hyperstat.solver.tolerances.worst_case.EVALUATION_BLOCK` configurations from the first), so a block's
maps are kept, keyed by the kinematics and the block's bytes, and the next stage reads them instead of
computing them again: the same arrays, bit for bit (a block is computed once), read-only.  Only blocks of
:data:`KEPT_ROWS` configurations or more are kept (a search path's trial points are not read again), at most
:data:`KEPT_BLOCKS` of them (the least recently read goes first).
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

from hyperstat.solver.tolerances.spilled import array_digest

__all__ = ["nominal_twist_maps", "KEPT_BLOCKS", "KEPT_ROWS"]

#: blocks kept (the hexapod's: 3 MiB each at 256 configurations; one command reads 13 of them again)
KEPT_BLOCKS = 16
#: the smallest block kept (configurations)
KEPT_ROWS = 64

_KEPT: OrderedDict = OrderedDict()
_LOCK = threading.Lock()


def nominal_twist_maps(kin, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``K_xi`` (K, 6, n_xi), ``K_a`` (K, 6, n_a) and the output poses (K, 4, 4) of the nominal machine at ``q``.

    :func:`hyperstat.solver.tolerances.accuracy.output_twist_maps` of ``kin.evaluate(q, None, jacobians=True)``;
    a block read before is returned as it was computed (read-only arrays).

    Examples
    --------
    >>> from hyperstat.solver.kinematics.build import MechanismBuilder
    >>> from hyperstat.solver.kinematics.closure import Kinematics
    >>> b = MechanismBuilder("pendulum")
    >>> b.revolute("1", point=(0, 0, 0), axis=(0, 0, 1), role="actuated")
    >>> b.frame("tip", origin=(100, 0, 0), z_axis=(0, 0, 1), x_axis=(1, 0, 0))
    >>> b.chain("arm", "R0", "tip", ["1"])
    >>> kin = Kinematics(b.build())
    >>> q = np.linspace(0.0, 1.0, 80)[:, None]
    >>> first, again = nominal_twist_maps(kin, q), nominal_twist_maps(kin, q.copy())
    >>> all(a is b for a, b in zip(first, again)), first[1].shape
    (True, (80, 6, 1))
    """
    from hyperstat.solver.tolerances.accuracy import output_twist_maps

    q = np.ascontiguousarray(np.atleast_2d(q), dtype=float)
    keep = len(q) >= KEPT_ROWS
    if keep:
        # the evaluation path is part of the key (the plan and the element-by-element pass agree to round-off only)
        key = (id(kin), bool(getattr(kin, "use_plan", True)), q.shape, array_digest(q))
        with _LOCK:
            hit = _KEPT.get(key)
            if hit is not None:
                _KEPT.move_to_end(key)
                return hit[1]
    st = kin.evaluate(q, None, jacobians=True)
    k_xi, k_a = output_twist_maps(kin, st)
    out = (k_xi, k_a, np.array(st.output_pose))
    if keep:
        for a in out:
            a.flags.writeable = False
        with _LOCK:
            _KEPT[key] = (kin, out)  # the kinematics kept with its entry: its id is not reused while the entry lives
            while len(_KEPT) > KEPT_BLOCKS:
                _KEPT.popitem(last=False)
    return out
