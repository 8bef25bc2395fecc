"""Configurations sampled over the joint ranges, assembled, screened for singularities.

Units: joint values in rad (revolute) and mm (prismatic).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.errors import AnalysisError

__all__ = ["ConfigurationSample", "sample_configurations", "passive_conditioning"]


@dataclass
class ConfigurationSample:
    """Assembled configurations and what was left out.

    Attributes
    ----------
    q : ndarray, (K, n_q)
        Assembled configurations (rad / mm).
    rejected : dict
        Counts of rejected draws by reason: ``"no_assembly"``, ``"out_of_range"``,
        ``"singular"``.
    warnings : list of str
        Sentences for the user about what was left out.
    """

    q: np.ndarray
    rejected: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)


def passive_conditioning(kin: Kinematics, q: np.ndarray) -> np.ndarray:
    """Inverse condition number of the scaled passive Jacobian ``B_s`` per configuration.

    Only the non-zero singular values up to the generic rank count; a value near zero
    flags a configuration close to a singularity of the passive joints.
    """
    m = kin.mechanism
    if len(m.passive) == 0 or len(m.closures) == 0:
        return np.ones(len(q))
    st = kin.evaluate(q)
    b = kin.dimensionless(st.closure_q[:, :, m.passive], kin.joint_scale[m.passive])
    s = np.linalg.svd(b, compute_uv=False)
    rank = int(np.max(np.sum(s > 1e-9 * s[:, :1], axis=1)))
    return s[:, rank - 1] / s[:, 0]


def sample_configurations(
    kin: Kinematics,
    n: int,
    seed: int = 0,
    margin: float = 0.05,
    singular_tol: float = 1e-4,
    max_rounds: int = 4,
) -> ConfigurationSample:
    """Draw ``n`` assembled, non-singular configurations uniformly over the actuated ranges.

    Parameters
    ----------
    kin : Kinematics
        Forward model.
    n : int
        Number of configurations wanted.
    seed : int
        Seed of the random generator (results are reproducible).
    margin : float
        Fraction of each actuated range left out at both ends.
    singular_tol : float
        Configurations whose passive Jacobian has an inverse condition number below
        this value are left out (close to a singularity) with a warning.
    max_rounds : int
        Draw rounds before giving up.

    Returns
    -------
    ConfigurationSample

    Raises
    ------
    AnalysisError
        If no configuration can be assembled.
    """
    m = kin.mechanism
    kin.check_home()
    rng = np.random.default_rng(seed)
    ranges = m.ranges
    lo = ranges[:, 0] + margin * (ranges[:, 1] - ranges[:, 0])
    hi = ranges[:, 1] - margin * (ranges[:, 1] - ranges[:, 0])
    act = m.actuated
    kept: list[np.ndarray] = []
    rejected = {"no_assembly": 0, "out_of_range": 0, "singular": 0}
    for _ in range(max_rounds):
        need = n - sum(len(k) for k in kept)
        if need <= 0:
            break
        draw = max(2 * need, 8)
        qa = lo[act] + rng.random((draw, len(act))) * (hi[act] - lo[act])
        res = kin.solve(qa)
        q = res.q
        ok = res.converged.copy()
        rejected["no_assembly"] += int(np.sum(~ok))
        in_range = np.all((q >= ranges[:, 0] - 1e-9) & (q <= ranges[:, 1] + 1e-9), axis=1)
        rejected["out_of_range"] += int(np.sum(ok & ~in_range))
        ok &= in_range
        if np.any(ok):
            cond = passive_conditioning(kin, q[ok])
            good = cond > singular_tol
            rejected["singular"] += int(np.sum(~good))
            kept.append(q[ok][good])
    q = np.concatenate(kept, axis=0)[:n] if kept else np.zeros((0, kin.n_q))
    notes = []
    if rejected["singular"]:
        notes.append(
            f"{rejected['singular']} sampled configuration(s) lie close to a singularity of the passive joints "
            f"(inverse condition number below {singular_tol:g}) and were left out of the sample."
        )
    if len(q) == 0:
        raise AnalysisError(
            f"no configuration of '{m.name}' could be assembled over the actuated joint ranges "
            f"({rejected['no_assembly']} failed to close, {rejected['out_of_range']} left a passive joint range)."
        )
    if len(q) < n:
        notes.append(f"only {len(q)} of the {n} requested configurations could be assembled inside the joint ranges.")
    for note in notes:
        warnings.warn(note, stacklevel=2)
    return ConfigurationSample(q, rejected, notes)
