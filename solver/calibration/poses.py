"""Pose selection for identification: pick N measurement poses out of candidates.

Units: lengths in mm, angles in rad.

Greedy D-optimal design: starting from nothing, add the candidate pose whose three
position rows increase ``log det(J^T W J + eps I)`` the most (matrix determinant lemma,
a 3x3 determinant per candidate), then improve the set by exchanges (Fedorov) until
no swap increases it.  The Jacobian is that of the nominal model (what the designer
knows before measuring), restricted to the identifiable (base) parameters and with
commensurate, unit-norm columns, so the criterion is unit-free.  D-optimality
maximises the product of the singular values, i.e. the observability index O1
(Borm and Menq); the condition number usually follows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hyperstat.solver.errors import DataError
from hyperstat.solver.calibration.identify import MeasurementModel, _column_scale, base_parameters, observability_indices
from hyperstat.solver.calibration.measurements import MeasurementSet, NoiseModel
from hyperstat.solver.calibration.virtual import default_tracker

__all__ = ["PoseSelection", "select_poses", "design_jacobian"]


@dataclass
class PoseSelection:
    """Outcome of :func:`select_poses`.

    Attributes
    ----------
    index : ndarray of int
        Chosen candidate rows.
    condition_number : float
        Condition number of the chosen poses' scaled Jacobian (base columns).
    random_condition_number : float
        Median condition number of random subsets of the same size.
    observability : dict
        O1-O4 of the chosen set; ``random_observability`` the same for the median random set.
    base : list of str
        Base parameters the design is made for.
    """

    index: np.ndarray
    condition_number: float
    random_condition_number: float
    observability: dict
    random_observability: dict
    base: list

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return {"index": self.index.tolist(), "condition_number": self.condition_number,
                "random_condition_number": self.random_condition_number, "observability": self.observability,
                "random_observability": self.random_observability, "base": self.base}


def design_jacobian(model: MeasurementModel, candidates: np.ndarray, noise: NoiseModel | None = None,
                    tracker: np.ndarray | None = None, target: np.ndarray | None = None) -> tuple[np.ndarray, list]:
    """Per-pose weighted, column-scaled Jacobian of the nominal model at candidate poses.

    Returns
    -------
    jacobian : ndarray, (K, 3, n_base)
        Unit-norm columns over all candidates.
    base : list of int
        Base parameter columns of ``model``.
    """
    k = len(candidates)
    data = MeasurementSet([f"C{i}" for i in range(k)], [], np.asarray(candidates, float), np.zeros((k, 3)),
                          noise=noise)
    # the design depends on the tracker pose only through the noise weights and the tracker columns
    theta = model.initial(default_tracker(model.kin) if tracker is None else tracker,
                          np.zeros(3) if target is None else target)
    pred = model.predict(theta, data, jacobian=True)
    if not pred.converged.all():
        raise DataError(f"{int((~pred.converged).sum())} candidate poses do not assemble on the nominal model.")
    w = np.ones(k) if noise is None else 1.0 / noise.sigma(np.linalg.norm(pred.position, axis=1))
    jac = pred.jacobian * w[:, None, None] * _column_scale(model)
    preferred = [j for j, kind in enumerate(model.kinds) if kind in ("tracker", "target")]
    base, *_ = base_parameters(jac.reshape(-1, model.n), preferred)
    jb = jac[:, :, base]
    jb = jb / np.linalg.norm(jb.reshape(-1, len(base)), axis=0)
    return jb, base


def _condition(jac: np.ndarray) -> tuple[float, dict]:
    flat = jac.reshape(-1, jac.shape[-1])
    flat = flat / np.linalg.norm(flat, axis=0).clip(min=1e-300)
    s = np.linalg.svd(flat, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf"), observability_indices(s, flat.shape[0])


def select_poses(model: MeasurementModel, candidates: np.ndarray, n: int, seed: int = 0,
                 noise: NoiseModel | None = None, exchanges: int = 3, random_trials: int = 20) -> PoseSelection:
    """D-optimal choice of ``n`` poses among ``candidates`` (greedy + Fedorov exchange).

    Parameters
    ----------
    model : MeasurementModel
        Identification model (nominal parameters are used).
    candidates : ndarray, (K, n_actuated)
        Candidate actuated configurations (rad / mm).
    n : int
        Poses to choose.
    seed : int
        Seed of the random subsets the choice is compared with.
    noise : NoiseModel, optional
        Weights the rows as the identification will.
    exchanges : int
        Passes of the exchange improvement.
    random_trials : int
        Random subsets drawn for the comparison.

    Returns
    -------
    PoseSelection

    Raises
    ------
    DataError
        If ``n`` exceeds the number of candidates or cannot determine the base parameters.
    """
    k = len(candidates)
    if n > k:
        raise DataError(f"cannot choose {n} poses out of {k} candidates.")
    jac, base = design_jacobian(model, candidates, noise)
    nb = len(base)
    if 3 * n <= nb:
        raise DataError(f"{n} poses give {3 * n} equations, too few for {nb} identifiable parameters.")
    eps = 1e-6
    info = eps * np.eye(nb)
    chosen: list[int] = []
    free = np.ones(k, dtype=bool)

    def gains(inv: np.ndarray) -> np.ndarray:
        # log det(I3 + J_c inv J_c^T) per candidate
        m = np.matmul(jac @ inv, jac.transpose(0, 2, 1)) + np.eye(3)
        return np.linalg.slogdet(m)[1]

    for _ in range(n):
        g = gains(np.linalg.inv(info))
        g[~free] = -np.inf
        c = int(np.argmax(g))
        chosen.append(c)
        free[c] = False
        info = info + jac[c].T @ jac[c]
    for _ in range(exchanges):
        improved = False
        for pos in range(n):
            out = chosen[pos]
            reduced = info - jac[out].T @ jac[out]
            g = gains(np.linalg.inv(reduced))
            g[~free] = -np.inf
            g_out = np.linalg.slogdet(np.eye(3) + jac[out] @ np.linalg.inv(reduced) @ jac[out].T)[1]
            c = int(np.argmax(g))
            if g[c] > g_out + 1e-9:
                chosen[pos] = c
                free[c] = False
                free[out] = True
                info = reduced + jac[c].T @ jac[c]
                improved = True
            else:
                info = reduced + jac[out].T @ jac[out]
        if not improved:
            break
    index = np.array(sorted(chosen))
    cond, obs = _condition(jac[index])
    rng = np.random.default_rng(seed)
    trials = [_condition(jac[rng.choice(k, n, replace=False)]) for _ in range(random_trials)]
    order = np.argsort([t[0] for t in trials])
    median = trials[order[len(order) // 2]]
    return PoseSelection(index, cond, median[0], obs, median[1], [model.names[b] for b in base])
