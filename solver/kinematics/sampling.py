"""Configurations sampled over the joint ranges, assembled on the home branch, screened for singularities.

Units: joint values in rad (revolute) and mm (prismatic).

Every configuration is reached by branch-safe continuation
(:func:`hyperstat.solver.kinematics.continuation.continue_nearest`) from the *nearest*
configuration already certified (home first), so that paths are short and every
configuration carries a certificate that it lies on the assembly branch of the home
configuration (by a chain of certified paths back to home).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.continuation import (
    BranchCertificate,
    ContinuationOptions,
    continue_nearest,
    continue_path,
)
from hyperstat.solver.errors import AnalysisError

__all__ = ["ConfigurationSample", "sample_configurations", "passive_conditioning", "continue_to",
           "assemble_nearest"]


@dataclass
class ConfigurationSample:
    """Assembled configurations and what was left out.

    Attributes
    ----------
    q : ndarray, (K, n_q)
        Assembled configurations (rad / mm).
    rejected : dict
        Counts of rejected draws by reason: ``"uncertified"`` (the continuation could not
        certify the home branch), ``"no_assembly"``, ``"out_of_range"``, ``"singular"``.
    warnings : list of str
        Sentences for the user about what was left out.
    certificate : BranchCertificate or None
        Branch certificate of every kept configuration (all certified).
    """

    q: np.ndarray
    rejected: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    certificate: BranchCertificate | None = None


def continue_to(
    kin: Kinematics,
    q_start_full: np.ndarray,
    qa_targets: np.ndarray,
    xi: np.ndarray | None = None,
    options: ContinuationOptions | None = None,
) -> tuple[np.ndarray, BranchCertificate]:
    """Configurations at ``qa_targets`` on the branch of ``q_start_full``, with their certificate.

    A thin entry point to :func:`hyperstat.solver.kinematics.continuation.continue_path`
    (predictor ``dq_p = -B_p^+ B_a dq_a``, Newton corrector, adaptive steps; see its
    guarantee).

    Parameters
    ----------
    kin : Kinematics
        Forward model.
    q_start_full : ndarray, (n_q,) or (K, n_q)
        Assembled start configuration(s), all joints (rad / mm).
    qa_targets : ndarray, (K, n_actuated)
        Actuated values to reach (rad / mm).
    xi : ndarray, (n_xi,) or (K, n_xi), optional
        Defects (rad / mm).
    options : ContinuationOptions, optional

    Returns
    -------
    q : ndarray, (K, n_q)
        Configurations; rows with ``certificate.certified`` false stopped at their last
        certified point and must not be used.
    certificate : BranchCertificate
    """
    return continue_path(kin, q_start_full, qa_targets, xi, options)


def assemble_nearest(
    kin: Kinematics,
    qa_targets: np.ndarray,
    xi: np.ndarray | None = None,
    start: np.ndarray | None = None,
    options: ContinuationOptions | None = None,
    pool: np.ndarray | None = None,
) -> tuple[np.ndarray, BranchCertificate]:
    """Assemble many actuated values on the branch of ``start``, each from the nearest one already assembled.

    The certified nearest-neighbour continuation
    (:func:`hyperstat.solver.kinematics.continuation.continue_nearest`, the sampler of every
    stage): the targets nearest to ``start`` first, in batches growing four-fold, then the
    others in waves; every target continues from the nearest configuration certified so
    far (``start`` and ``pool`` included) with adaptive, certified steps.  Every certified
    configuration is linked to ``start`` by a chain of certified paths, so it lies on the
    branch of ``start``.

    Parameters
    ----------
    kin : Kinematics
        Forward model.
    qa_targets : ndarray, (K, n_actuated)
        Actuated values (rad / mm).
    xi : ndarray, (n_xi,), optional
        Defects (rad / mm), the same for every target.
    start : ndarray, (n_q,), optional
        Assembled start configuration (default: home).
    options : ContinuationOptions, optional
        Step control (default: one first step over short paths).
    pool : ndarray, (P, n_q), optional
        Configurations already certified on the branch of ``start`` at the same ``xi``
        (e.g. a previous sample), used as further start points.

    Returns
    -------
    q : ndarray, (K, n_q)
        Configurations (uncertified rows must not be used).
    certificate : BranchCertificate
        Per target; ``steps`` and ``path_length`` count the path from its neighbour.
    """
    return continue_nearest(kin, qa_targets, xi, start, options, pool)


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
    *,
    pool: np.ndarray | None = None,
) -> ConfigurationSample:
    """Draw ``n`` assembled, non-singular configurations uniformly over the actuated ranges, on the home branch.

    Each draw is assembled by certified continuation from the nearest configuration
    already assembled (:func:`assemble_nearest`); a draw that cannot be certified on the
    branch of the home configuration is left out with a warning that says how many and
    why.

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
    pool : ndarray, (P, n_q), optional
        Configurations already certified on the home branch (e.g. an earlier sample) to
        continue from; the draws stay independent of them.

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
    rejected = {"uncertified": 0, "no_assembly": 0, "out_of_range": 0, "singular": 0}
    certs: list = []
    reasons: dict[str, int] = {}
    for _ in range(max_rounds):
        need = n - sum(len(k) for k in kept)
        if need <= 0:
            break
        draw = max(2 * need, 8)
        qa = lo[act] + rng.random((draw, len(act))) * (hi[act] - lo[act])
        known = [k_ for k_ in kept if len(k_)] + ([] if pool is None else [np.atleast_2d(pool)])
        q, cert = assemble_nearest(kin, qa, pool=np.concatenate(known) if known else None)
        ok = cert.certified.copy()
        for r in np.asarray(cert.reason, dtype=object)[~ok]:
            reasons[r] = reasons.get(r, 0) + 1
        rejected["uncertified"] += int(np.sum(~ok))
        if np.any(ok):
            res = kin.residual_norm(kin.evaluate(q[ok], jacobians=False).residual)
            closed = res <= 1e-7 * kin.length_scale
            rejected["no_assembly"] += int(np.sum(~closed))
            ok[np.nonzero(ok)[0][~closed]] = False
        in_range = np.all((q >= ranges[:, 0] - 1e-9) & (q <= ranges[:, 1] + 1e-9), axis=1)
        rejected["out_of_range"] += int(np.sum(ok & ~in_range))
        ok &= in_range
        if np.any(ok):
            # exact inverse condition of B_p (the certificate holds a lower bound from Frobenius norms)
            cond = passive_conditioning(kin, q[ok])
            good = cond > singular_tol
            rejected["singular"] += int(np.sum(~good))
            kept.append(q[ok][good])
            certs.append(cert.take(np.nonzero(ok)[0][good]))
    q = np.concatenate(kept, axis=0)[:n] if kept else np.zeros((0, kin.n_q))
    certificate = BranchCertificate.concatenate(certs).take(np.arange(len(q))) if certs else None
    notes = []
    if rejected["uncertified"]:
        why = "; ".join(f"{c} {r}" for r, c in sorted(reasons.items(), key=lambda t: -t[1]))
        notes.append(
            f"{rejected['uncertified']} drawn configuration(s) could not be certified on the assembly branch of the "
            f"home configuration and were left out ({why})."
        )
    if rejected["singular"]:
        notes.append(
            f"{rejected['singular']} sampled configuration(s) lie close to a singularity of the passive joints "
            f"(inverse condition number below {singular_tol:g}) and were left out of the sample."
        )
    if len(q) == 0:
        hint = ("; it does not move from its home: a home drawn off the mechanism's motion closes its loops there "
                "only (docs/authoring.md, 'Closing a loop at home')"
                if rejected["no_assembly"] and not rejected["out_of_range"] else "")
        raise AnalysisError(
            f"no configuration of '{m.name}' could be assembled over the actuated joint ranges "
            f"({rejected['no_assembly']} failed to close, {rejected['out_of_range']} left a passive joint range){hint}."
        )
    if len(q) < n:
        notes.append(f"only {len(q)} of the {n} requested configurations could be assembled inside the joint ranges.")
    for note in notes:
        warnings.warn(note, stacklevel=2)
    return ConfigurationSample(q, rejected, notes, certificate)
