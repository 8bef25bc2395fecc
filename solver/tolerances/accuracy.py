"""Accuracy coefficients (paper 2, Simas & Di Gregorio): how actuation and geometric errors move the platform.

Units: lengths in mm, angles in rad; coefficients are dimensionless (rad/rad, mm/mm) or
mm/rad (``epsilon_*R``) or rad/mm (``delta_*P``).

Paper 2 treats every geometric constant as an extra joint of an "extended spatial
mechanism" and eliminates the passive joints (eqs. 9-12): the platform's small rotation
``u dphi`` and the displacement ``dO_p`` of its point ``O_p`` are

    u dphi = D_f dq_f + D_g dq_g,      dO_p = E_f dq_f + E_g dq_g            (eq. 13)

with ``q_f`` the actuated joints and ``q_g`` the geometric errors.  In the joint-invariant
model the same maps are the output twist per unit actuated value and per unit defect with
the passive joints following by the implicit function theorem,
``K = O - O_p B_p^+ B`` (eq. 3 of paper 1): ``D`` are its rotation rows, ``E`` its
translation rows at the output frame's origin ``O_p``.  Splitting the columns by kind
(``P``: prismatic joints and length errors, ``R``: revolute joints and angle errors) gives
the eight matrices of eq. (17); their largest singular values are the accuracy
coefficients ``delta_fP, delta_fR, delta_gP, delta_gR, epsilon_fP, epsilon_fR, epsilon_gP,
epsilon_gR`` (eqs. 18), and ``|dphi| <= sum delta ||dq||``, ``||dO_p|| <= sum epsilon ||dq||``.
A single parameter's own coefficient is its column norm (section 3.2, last paragraph).

For an over-constrained mechanism only the admissible (free and coupled) defects are
accuracy inputs: the forced ones are assembly conditions (the stationarity analysis).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.tolerances.declaration import n_rotation_rows, task_rows
from hyperstat.solver.tolerances.workspace import Workspace, workspace_of

__all__ = ["COEFFICIENT_NAMES", "AccuracyMaps", "accuracy_maps", "allocate", "compensable", "grid_slice", "report_section",
           "sample_workspace", "weighted_allocation", "geometric_parameters", "largest_singular_value",
           "output_twist_maps", "in_chunks"]

COEFFICIENT_NAMES = ("delta_fP", "delta_fR", "delta_gP", "delta_gR", "epsilon_fP", "epsilon_fR", "epsilon_gP",
                     "epsilon_gR")


def output_twist_maps(kin: Kinematics, st, damping: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
    """Output twist per unit defect and per unit actuated value, passive joints following.

    ``K_xi = O_xi - O_p B_p^+ A`` and ``K_a = O_a - O_p B_p^+ B_a`` (paper 1, eq. 3; paper 2,
    eq. 12), the passive joints solving the (length-scaled) closure in the least-squares
    sense; shapes (K, 6, n_xi) and (K, 6, n_actuated), twists (omega, v) at the output origin.

    A state evaluated with ``jacobians="actuation"`` (no defect columns) gives ``K_xi`` as None.

    ``O_p B_p^+`` is formed with six right-hand sides whatever the number of defects: when
    ``B_p`` is square, ``(O_p B_p^-1)^T = B_p^-T O_p^T``; otherwise (over-constrained, or a
    singular configuration in the block) ``Z^T B_p^T S^2`` with ``(B_p^T S^2 B_p) Z = O_p^T``,
    ``S`` scaling the rotation rows by the length scale and the normal matrix damped by
    ``damping`` times its largest diagonal entry, so that the maps stay defined
    (minimum-norm-like) at a singular configuration.
    """
    m = kin.mechanism
    passive, act = m.passive, m.actuated
    o_xi, o_q = st.output_xi, st.output_q
    if not (len(passive) and len(m.closures)):
        return o_xi, o_q[:, :, act]
    b = st.closure_q[:, :, passive]  # (K, 6L, n_p)
    o_p = o_q[:, :, passive]
    gain = None
    if b.shape[1] == b.shape[2]:  # as many closure rows as passive joints: B_p^+ = B_p^-1, no scaling needed
        try:
            gain = np.swapaxes(np.linalg.solve(np.swapaxes(b, 1, 2), np.swapaxes(o_p, 1, 2)), 1, 2)
        except np.linalg.LinAlgError:  # a singular configuration in the block: the damped path below
            gain = None
    if gain is None:
        weight = np.ones(b.shape[1])  # S^2 on the diagonal
        for c in range(len(weight) // 6):
            weight[6 * c : 6 * c + 3] = kin.length_scale**2
        bt_w = np.ascontiguousarray(np.swapaxes(b, 1, 2)) * weight  # B_p^T S^2, (K, n_p, 6L)
        normal = bt_w @ b
        diag = np.einsum("kii->ki", normal)
        idx = np.arange(normal.shape[1])
        normal[:, idx, idx] += damping * np.maximum(diag.max(axis=1), 1e-300)[:, None]
        z = np.linalg.solve(normal, np.swapaxes(o_p, 1, 2))  # (K, n_p, 6)
        gain = np.swapaxes(z, 1, 2) @ bt_w  # O_p B_p^+ (K, 6, 6L)
    k_xi = None if o_xi is None else o_xi - gain @ st.closure_xi  # None: a state without the defects' columns
    return k_xi, o_q[:, :, act] - gain @ st.closure_q[:, :, act]


def largest_singular_value(m: np.ndarray) -> np.ndarray:
    """Largest singular value of each (3, n) matrix of a stack (K, 3, n).

    The square root of the largest eigenvalue of the 3x3 Gram matrix ``M M^T``, in closed
    form (the trigonometric solution of the characteristic cubic), vectorised over the
    stack: five times faster than a batched LAPACK call on 3x3 matrices.  Its relative
    error is at most about 1e-8 (when the two largest singular values coincide) and
    round-off elsewhere; ``tests/solver/test_accuracy.py`` checks it against
    :func:`numpy.linalg.svd`.
    """
    if m.shape[-1] == 0:
        return np.zeros(m.shape[0])
    r0, r1, r2 = m[:, 0], m[:, 1], m[:, 2]
    g00, g11, g22 = (r0 * r0).sum(-1), (r1 * r1).sum(-1), (r2 * r2).sum(-1)
    g01, g02, g12 = (r0 * r1).sum(-1), (r0 * r2).sum(-1), (r1 * r2).sum(-1)
    mean = (g00 + g11 + g22) / 3.0
    a, b, c = g00 - mean, g11 - mean, g22 - mean  # the deviatoric part G - mean I
    off = g01 * g01 + g02 * g02 + g12 * g12
    p = np.sqrt((a * a + b * b + c * c + 2.0 * off) / 6.0)
    det = a * (b * c - g12 * g12) - g01 * (g01 * c - g12 * g02) + g02 * (g01 * g12 - b * g02)
    with np.errstate(divide="ignore", invalid="ignore"):
        half_det = np.where(p > 0, det / (2.0 * p**3), 0.0)
    angle = np.arccos(np.clip(half_det, -1.0, 1.0)) / 3.0
    top = mean + 2.0 * p * np.cos(angle)
    return np.sqrt(np.maximum(top, 0.0))


def geometric_parameters(mechanism: Mechanism, analysis=None) -> tuple[list[str], np.ndarray]:
    """Geometric error coordinates and their map to the defect vector.

    Without an analysis: every defect parameter of the model (a template that declares only
    the paper's errors, as ``triflex_ii``, gives exactly those).  With one: the admissible
    influential coordinates (free defects, coupled ones through their relations).
    """
    if analysis is None:
        names = [p.name for p in mechanism.parameters]
        return names, np.eye(len(names))
    return analysis.parameterization(mechanism, influential_only=True)


@dataclass
class AccuracyMaps:
    """Accuracy coefficients over configurations.

    Attributes
    ----------
    coefficients : dict
        Paper name (:data:`COEFFICIENT_NAMES`) -> (K,) values.
    per_parameter : dict
        Parameter name -> {"rotation": (K,), "position": (K,)} column norms (its own coefficient);
        empty when the maps were computed with ``per_configuration=False`` (see
        :meth:`per_parameter_summary`, which both give).
    groups : dict
        ``fP``, ``fR``, ``gP``, ``gR`` -> parameter names in each group.
    q : ndarray
        The configurations (K, n_q).
    position : ndarray
        Position of ``O_p`` in the base frame (K, 3), mm ((0, 3) with ``per_configuration=False``).
    task_rows : tuple of ndarray or TaskSummary, optional
        With ``accuracy_maps(task=..., task_directions=...)``: the task rotation rows (rad) and
        position rows (mm) of the output twist per unit of each direction, (K, r, n) each, from
        the same Jacobians as the coefficients (what
        :func:`hyperstat.solver.tolerances.values.task_maps` computes); with ``task_columns``
        instead, their reductions (:class:`~hyperstat.solver.tolerances.task_summary.TaskSummary`).
    per_parameter_reduced : dict, optional
        With ``per_configuration=False``: parameter name -> {"rotation": {"max", "mean"}, "position": {...}}.
    """

    coefficients: dict
    per_parameter: dict
    groups: dict
    q: np.ndarray
    position: np.ndarray
    units: dict = field(default_factory=dict)
    task_rows: object = None
    per_parameter_reduced: dict | None = None

    def summary(self) -> dict:
        """min / max / mean of every coefficient (JSON-ready)."""
        return {k: {"min": float(v.min()), "max": float(v.max()), "mean": float(v.mean())}
                for k, v in self.coefficients.items()}

    def per_parameter_summary(self) -> dict:
        """Parameter name -> {"rotation": {"max", "mean"}, "position": {...}} of its column norms (JSON-ready)."""
        if self.per_parameter_reduced is not None:
            return self.per_parameter_reduced
        return {n: {k: {"max": float(v.max()), "mean": float(v.mean())} for k, v in d.items()}
                for n, d in self.per_parameter.items()}


#: the number of CPUs, read once (``os.cpu_count`` reads the system's CPU list at every call)
_CPUS = os.cpu_count() or 1


def in_chunks(block, n: int, chunk: int = 10000, workers: int | None = None) -> None:
    """Run ``block(start)`` for ``start = 0, chunk, 2 chunk, ... < n``, on threads when there are several blocks.

    numpy releases the GIL in its array loops, so blocks of batched kinematics overlap; each
    block must write only its own rows, which keeps the result independent of the threads.
    ``workers`` defaults to the number of CPUs (at most 8).

    Examples
    --------
    >>> starts = []
    >>> in_chunks(starts.append, 25, chunk=10, workers=1)
    >>> starts
    [0, 10, 20]
    """
    starts = range(0, n, chunk)
    threads = min(workers or min(_CPUS, 8), len(starts))
    if threads > 1:
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(block, starts))  # list(): re-raises an exception of any block
    else:
        for start in starts:
            block(start)


def _is_spilled(a) -> bool:
    from hyperstat.solver.tolerances.spilled import SpilledArray

    return isinstance(a, SpilledArray)


def _per_configuration(k: int, spilled: bool):
    """K zeros, in memory or in a temporary file (:class:`~hyperstat.solver.tolerances.spilled.SpilledArray`)."""
    if not spilled:
        return np.zeros(k)
    from hyperstat.solver.tolerances.spilled import SpilledArray

    return SpilledArray(k)


def accuracy_maps(mechanism: Mechanism, q: np.ndarray, analysis=None, kinematics: Kinematics | None = None,
                  chunk: int = 2048, workers: int | None = None, task: tuple | None = None,
                  task_directions: np.ndarray | None = None, per_configuration: bool = True,
                  task_columns: tuple | None = None) -> AccuracyMaps:
    """The accuracy coefficients at assembled configurations ``q`` (vectorised, in chunks).

    One set of Jacobians per configuration: each block of configurations is evaluated once
    (closure and output Jacobians, ``K = O - O_p B_p^+ B``) and serves the coefficients and,
    with ``task``, the task-restricted rows of the tolerance values.  The Jacobians are held a
    block at a time (``chunk`` configurations per thread); what is kept per configuration is the
    eight coefficients, and with ``per_configuration`` (the default) the parameters' column norms,
    ``O_p`` and the task rows as well (``per_configuration=False`` and ``task_columns``: their
    reductions instead, 128 bytes per configuration in all for the Triflex-II against 501).

    Parameters
    ----------
    mechanism : Mechanism
    q : ndarray or SpilledArray, (K, n_q)
        Assembled configurations (rad / mm).  In a temporary file
        (:class:`~hyperstat.solver.tolerances.spilled.SpilledArray`): read a block at a time, and the
        per-configuration coefficients (and the task summary's) written to temporary files as well.
    analysis : StationarityResult, optional
        Restrict the geometric errors to the admissible influential coordinates.
    chunk : int
        Configurations per vectorised block (memory bound; about 2,000 keep a block's arrays
        in the cache: 0.55 s of CPU for 68,000 Triflex-II configurations against 0.89 s in
        blocks of 10,000, and 115 MiB of peak memory against 291 MiB).
    workers : int, optional
        Threads that evaluate blocks concurrently (numpy releases the GIL in its array
        loops); default: the number of CPUs, at most 8.  Each block writes its own rows,
        so the result does not depend on the number of threads.
    task : tuple of str, optional
        Task components (:data:`hyperstat.solver.tolerances.declaration.TASK_COMPONENTS`):
        also fill :attr:`AccuracyMaps.task_rows` for ``task_directions``.
    task_directions : ndarray, (n_xi, n), optional
        Defect vector per unit of each tolerance (rad / mm), with ``task``.
    per_configuration : bool
        Keep every parameter's column norms and ``O_p`` at every configuration
        (:attr:`AccuracyMaps.per_parameter`, :attr:`AccuracyMaps.position`); ``False``: only their maxima
        and means (:attr:`AccuracyMaps.per_parameter_reduced`, added block by block: the means differ
        from one ``numpy.mean`` by round-off), so that what is kept per configuration is the eight
        coefficients (``hyperstat accuracy``, issue 39: the norms were 384 bytes per Triflex-II
        configuration).
    task_columns : tuple, optional
        With ``task``: ``(is_length, column_sets)``
        (:func:`hyperstat.solver.tolerances.task_summary.value_columns`): reduce the task rows block by
        block into a :class:`~hyperstat.solver.tolerances.task_summary.TaskSummary` (what the values stage
        needs of them) instead of keeping them, (K, r, n).
    """
    from hyperstat.solver.tolerances.task_summary import TaskAccumulator

    kin = kinematics or Kinematics(mechanism)
    names, matrix = geometric_parameters(mechanism, analysis)
    units = {p.name: p.unit for p in mechanism.parameters}
    g_units = [units[n] for n in names]
    act = mechanism.actuated
    f_names = [mechanism.joints[i].name for i in act]
    f_kind = ["P" if mechanism.joints[i].type == "P" else "R" for i in act]
    g_kind = ["P" if u == "mm" else "R" for u in g_units]
    groups = {"fP": [n for n, k in zip(f_names, f_kind) if k == "P"],
              "fR": [n for n, k in zip(f_names, f_kind) if k == "R"],
              "gP": [n for n, k in zip(names, g_kind) if k == "P"],
              "gR": [n for n, k in zip(names, g_kind) if k == "R"]}
    f_idx = {k: [i for i, kk in enumerate(f_kind) if kk == k] for k in "PR"}
    g_idx = {k: [i for i, kk in enumerate(g_kind) if kk == k] for k in "PR"}
    spilled = _is_spilled(q)  # a sample in a temporary file: the coefficients go to one too (issue 39: memory)
    if not spilled:
        q = np.atleast_2d(np.asarray(q, dtype=float))
    coeffs = {n: _per_configuration(len(q), spilled) for n in COEFFICIENT_NAMES}
    keep = len(q) if per_configuration else 0
    per = {n: {"rotation": np.zeros(keep), "position": np.zeros(keep)} for n in f_names + names} \
        if per_configuration else {}
    position = np.zeros((keep, 3))
    rot_rows, pos_rows = np.s_[:, :3], np.s_[:, 3:]
    on_task = accumulator = None
    parts: dict = {}  # block start -> its partial reductions (added in block order: independent of the threads)
    if task is not None:
        n_task = task_rows(task, np.eye(4)[None]).shape[1]
        if task_columns is None:
            on_task = np.zeros((len(q), n_task, task_directions.shape[1]))
        else:
            accumulator = TaskAccumulator(len(q), n_rotation_rows(task), n_task - n_rotation_rows(task),
                                          task_columns[0], task_columns[1], spill=spilled)

    def block(start: int) -> None:
        sl = slice(start, start + chunk)
        st = kin.evaluate(q[sl], None, jacobians=True)
        k_xi, k_a = output_twist_maps(kin, st)
        part = {}
        if task is not None:  # the same rows as values.task_maps, from these Jacobians
            rows = task_rows(task, st.output_pose) @ k_xi @ task_directions
            if on_task is not None:
                on_task[sl] = rows
            else:
                part["task"] = accumulator.add(start, rows)
        k_g = k_xi @ matrix
        if per_configuration:
            position[sl] = st.output_pose[:, :3, 3]
        for kind in "PR":
            for label, cols, src in (("f", f_idx[kind], k_a), ("g", g_idx[kind], k_g)):
                sub = src[:, :, cols]
                coeffs[f"delta_{label}{kind}"][sl] = largest_singular_value(sub[rot_rows])
                coeffs[f"epsilon_{label}{kind}"][sl] = largest_singular_value(sub[pos_rows])
        for names_of, src, which in ((f_names, k_a, "f"), (names, k_g, "g")):
            rot = np.sqrt(np.einsum("kij,kij->kj", src[rot_rows], src[rot_rows]))  # column norms
            pos = np.sqrt(np.einsum("kij,kij->kj", src[pos_rows], src[pos_rows]))
            if per_configuration:
                for j, n in enumerate(names_of):
                    per[n]["rotation"][sl] = rot[:, j]
                    per[n]["position"][sl] = pos[:, j]
            else:  # running maxima and sums (NaN propagates as in numpy's max and mean)
                part[which] = (rot.max(axis=0), rot.sum(axis=0), pos.max(axis=0), pos.sum(axis=0))
        parts[start] = part

    in_chunks(block, len(q), chunk, workers)
    unit_of = {"delta_fP": "rad/mm", "delta_fR": "rad/rad", "delta_gP": "rad/mm", "delta_gR": "rad/rad",
               "epsilon_fP": "mm/mm", "epsilon_fR": "mm/rad", "epsilon_gP": "mm/mm", "epsilon_gR": "mm/rad"}
    split = None if on_task is None else (on_task[:, :n_rotation_rows(task)], on_task[:, n_rotation_rows(task):])
    if accumulator is not None:
        split = accumulator.finish({s: p["task"] for s, p in parts.items()})
    reduced = None
    if not per_configuration:
        reduced = {}
        for names_of, which in ((f_names, "f"), (names, "g")):
            blocks = [parts[s][which] for s in sorted(parts)]
            for j, n in enumerate(names_of):
                reduced[n] = {}
                for kind, at in (("rotation", 0), ("position", 2)):
                    top = max((float(b[at][j]) for b in blocks), default=float("nan"))
                    if any(np.isnan(b[at][j]) for b in blocks):
                        top = float("nan")
                    total = 0.0
                    for b in blocks:
                        total += float(b[at + 1][j])
                    reduced[n][kind] = {"max": top, "mean": total / len(q) if len(q) else float("nan")}
    return AccuracyMaps(coeffs, per, groups, q, position, unit_of, split, reduced)


# ---------------------------------------------------------------------------- workspace
#: draws assembled by one call of the certified sampler; a larger sample is taken in chunks (memory), each also
#: starting from up to SAMPLING_POOL configurations certified in the chunk before
SAMPLING_CHUNK = 200_000
SAMPLING_POOL = 8192
#: draws per call of the closed form inside a chunk (memory: its arrays for 200,000 draws at once peaked at
#: 180 MiB; each draw is assembled alone, so the configurations do not depend on it)
CLOSED_FORM_BLOCK = 4096
#: draws from which a declared closed form assembles the sample (:func:`sample_workspace`)
CLOSED_FORM_FROM = 20_000


def sample_workspace(mechanism: Mechanism, n: int, seed: int = 0, ranges: dict | None = None,
                     kinematics: Kinematics | None = None, workspace: Workspace | None = None,
                     certificate: bool = False, closed_form: bool | None = None, spill: bool = False):
    """Configurations with actuated values uniform in the workspace's actuated box, certified on the home branch.

    The box and the assembly branch come from the workspace (:func:`workspace_of`: the
    model's joint ranges, the template's declaration, then ``ranges``).  Every draw is
    assembled by the certified nearest-neighbour sampler
    (:func:`hyperstat.solver.kinematics.continuation.continue_nearest`): from the
    nearest configuration already certified, in one step with one Jacobian and a
    Kantorovich test where it can (issue 32), else on a certified path, with a branch
    certificate per configuration (``sigma_min(B_p)`` bounded below, every step well
    inside the estimated distance to another solution).  Draws that cannot be certified
    (outside the reachable set, beyond a fold, near a singularity of the passive joints)
    or that leave the declared passive ranges are left out with a warning that says how
    many and why.  More than :data:`SAMPLING_CHUNK` draws are taken a chunk at a time
    (memory), each chunk also starting from :data:`SAMPLING_POOL` configurations of the
    chunk before.

    Parameters
    ----------
    ranges : dict, optional
        Joint name -> (lo, hi) replacing the declared or model range.
    workspace : Workspace, optional
        Use this workspace instead of building one from ``mechanism`` and ``ranges``.
    certificate : bool
        Also return the :class:`~hyperstat.solver.kinematics.continuation.BranchCertificate`
        of the kept configurations and the one of every draw.
    closed_form : bool, optional
        When the template declares its legs' inverse kinematics in closed form
        (:mod:`hyperstat.solver.kinematics.closed_form`: the Triflex-II), assemble the draws
        with it: a draw out of a leg's reach is rejected before any Newton step, the others
        are kept when they close to round-off with a well-conditioned passive Jacobian, and
        only the rest go to the certified continuation (issue 39).  ``False``: the
        continuation for every draw.  Default: the closed form from :data:`CLOSED_FORM_FROM`
        draws on, where the continuation's cost matters (100,000 Triflex-II draws: 7.5 s of CPU
        against 0.7 s); smaller samples keep the continuation's configurations, and with them
        the answers of the versions before (the closed form also keeps the 0.3-0.5 % of the
        reachable draws near a fold whose path the continuation gives up, which moves the
        sampled statistics and the searches' starts).

    spill : bool or SpilledArray
        Write the kept configurations, a block at a time, into a
        :class:`~hyperstat.solver.tolerances.spilled.SpilledArray` (a temporary file; this one when given, empty)
        instead of memory: the same rows, returned in it (``hyperstat accuracy``: memory independent of the count,
        issue 39).

    Returns
    -------
    ndarray, (K, n_q)
        The certified configurations (K <= n), in draw order (mm / rad); with
        ``certificate``, ``(q, certificate of the kept, certificate of every draw)``.
    """
    import warnings

    from hyperstat.solver.kinematics.continuation import BranchCertificate, continue_nearest

    kin = kinematics or Kinematics(mechanism)
    ws = workspace or workspace_of(mechanism, ranges)
    lo, hi = ws.actuated_box(mechanism)
    rng = np.random.default_rng(seed)  # drawn a chunk at a time: the same numbers as one (n, n_a) draw
    form = None
    if closed_form or (closed_form is None and n >= CLOSED_FORM_FROM):
        from hyperstat.solver.kinematics.closed_form import closed_form_of

        form = closed_form_of(mechanism, kin)
    # the kept configurations are written into one buffer of the draws' size: only the rows written become
    # resident memory, and the sample is not copied again at the end (a concatenation of the chunks held it twice)
    out, count, certs, pool = np.empty((0 if spill else n, kin.n_q)), 0, [], None
    if spill is not False and spill is not None:
        from hyperstat.solver.tolerances.spilled import SpilledArray

        out = spill if isinstance(spill, SpilledArray) else SpilledArray.empty((kin.n_q,))
        spill = True
    rejected: dict = {}  # why draws were left out -> how many, in order of first appearance (the warning's words)
    for start in range(0, n, SAMPLING_CHUNK):  # bounded memory: a chunk of draws at a time
        if spill and form is not None and not certificate:  # the chunk's blocks written as they are assembled
            good = _closed_form_streamed(kin, form, rng, lo, hi, min(SAMPLING_CHUNK, n - start), ws, pool, out,
                                         rejected)
            pool = np.array(out[count:count + min(good, SAMPLING_POOL)])
            count += good
            continue
        qa = lo + (hi - lo) * rng.random((min(SAMPLING_CHUNK, n - start), len(lo)))
        if form is None:
            q, cert = continue_nearest(kin, qa, None, mechanism.home, pool=pool, inside=ws.inside)
        else:
            q, cert = _closed_form_chunk(kin, form, qa, ws, pool)
        ok = cert.certified
        good = int(ok.sum())
        at = count
        for b in range(0, len(q), CLOSED_FORM_BLOCK):  # the rows of q[ok] a block at a time (no copy of them all;
            rows = q[b:b + CLOSED_FORM_BLOCK][ok[b:b + CLOSED_FORM_BLOCK]]  # numpy.compress(out=) is 30 x slower)
            if spill:
                out.append(rows)
            else:
                out[at:at + len(rows)] = rows
            at += len(rows)
        if certificate:
            certs.append(cert)
        else:  # the reasons only (issue 39: the certificates of 317,000 rejected draws held 23 MiB at 1,000,000)
            for reason, kept in zip(cert.reason, ok):
                if not kept:
                    rejected[reason] = rejected.get(reason, 0) + 1
        pool = np.array(out[count:count + min(good, SAMPLING_POOL)])  # the next chunk also starts from these
        count += good
        del q, cert, qa
    q = out if spill else out[:count]
    every = BranchCertificate.concatenate(certs) if certificate else _rejected(rejected)
    if len(q) < n:
        warnings.warn(f"workspace sampling of '{mechanism.name}': {every.summary(total=n)} They were left out.",
                      stacklevel=2)
    if certificate:
        return q, every.take(every.certified), every
    return q


def _rejected(counts: dict):
    """A certificate of uncertified draws with these reasons and counts (what its ``summary`` reads), in order."""
    from hyperstat.solver.kinematics.continuation import BranchCertificate

    total = sum(counts.values())
    z = np.zeros(total)
    return BranchCertificate(np.zeros(total, dtype=bool), [r for r, c in counts.items() for _ in range(c)], z, z, z, z,
                             np.zeros(total, dtype=int), np.zeros(total, dtype=int), z, z)


def _closed_form_chunk(kin: Kinematics, form, qa: np.ndarray, ws: Workspace, pool: np.ndarray | None):
    """A chunk of draws through the declared closed form; the draws it leaves (within reach, not closing or
    ill-conditioned) through the certified continuation, from home and the configurations just certified."""
    from hyperstat.solver.kinematics.closed_form import assemble_closed_form
    from hyperstat.solver.kinematics.continuation import BranchCertificate, continue_nearest

    q = None  # the blocks' configurations written into one array of the chunk (not a list of them and a copy)
    certs, generic = [], np.empty(len(qa), dtype=bool)
    for b in range(0, len(qa), CLOSED_FORM_BLOCK):
        qb, cb, gb = assemble_closed_form(kin, form, qa[b:b + CLOSED_FORM_BLOCK], ws.inside)
        if q is None:
            q = np.empty((len(qa), qb.shape[1]))
        q[b:b + len(qb)] = qb
        generic[b:b + len(qb)] = gb
        certs.append(cb)
        del qb, cb, gb
    cert = certs[0] if len(certs) == 1 else BranchCertificate.concatenate(certs)
    del certs
    if generic.any():
        first = np.nonzero(cert.certified)[0][:SAMPLING_POOL]  # the first certified rows (no copy of them all)
        seeds = [p for p in (pool, q[first]) if p is not None and len(p)]
        idx = np.nonzero(generic)[0]
        qg, cg = continue_nearest(kin, qa[idx], None, kin.mechanism.home, inside=ws.inside,
                                  pool=np.concatenate(seeds) if seeds else None)
        q[idx] = qg
        _replace_rows(cert, idx, cg)
    return q, cert


def _closed_form_streamed(kin: Kinematics, form, rng, lo: np.ndarray, hi: np.ndarray, n: int, ws: Workspace,
                          pool: np.ndarray | None, out, rejected: dict) -> int:
    """A chunk of ``n`` draws through the closed form, each block's kept rows appended to ``out`` (a
    :class:`~hyperstat.solver.tolerances.spilled.SpilledArray`) and its rejected draws counted in ``rejected`` as
    soon as it is assembled; the number of rows kept.

    The same rows as :func:`_closed_form_chunk` (and the same draws: a seeded generator fills its doubles in
    order, a block at a time or a chunk at once): while no draw of the chunk is left to the corrector a block is
    final when assembled (each draw is assembled alone).  From the first block with such a draw on, the rest of
    the chunk is held and finished as :func:`_closed_form_chunk` does (the corrector's seeds: the chunk before's and
    the chunk's first :data:`SAMPLING_POOL` rows the closed form certified), so a chunk holds only a block's arrays
    at a time when the closed form certifies or rejects every draw (the Triflex-II; issue 39: the arrays of a
    200,000-draw chunk were the 1,000,000 run's largest transient).
    """
    from hyperstat.solver.kinematics.closed_form import assemble_closed_form
    from hyperstat.solver.kinematics.continuation import BranchCertificate, continue_nearest

    kept, first, held = 0, [], None  # first: the chunk's first certified rows (the corrector's seeds)
    n_first = 0
    for b in range(0, n, CLOSED_FORM_BLOCK):
        qa = lo + (hi - lo) * rng.random((min(CLOSED_FORM_BLOCK, n - b), len(lo)))
        qb, cb, gb = assemble_closed_form(kin, form, qa, ws.inside)
        if held is None and not gb.any():
            rows = qb[cb.certified]
            out.append(rows)
            kept += len(rows)
            if n_first < SAMPLING_POOL:
                first.append(rows[:SAMPLING_POOL - n_first])
                n_first += len(first[-1])
            for reason, ok in zip(cb.reason, cb.certified):
                if not ok:
                    rejected[reason] = rejected.get(reason, 0) + 1
            continue
        held = [] if held is None else held
        held.append((qa, qb, cb, gb))
    if held is None:
        return kept
    qa = np.concatenate([h[0] for h in held])
    q = np.concatenate([h[1] for h in held])
    cert = BranchCertificate.concatenate([h[2] for h in held])
    generic = np.concatenate([h[3] for h in held])
    del held
    if n_first < SAMPLING_POOL:
        first.append(q[np.nonzero(cert.certified)[0][:SAMPLING_POOL - n_first]])
    seeds = [p for p in [pool] + first if p is not None and len(p)]
    idx = np.nonzero(generic)[0]
    qg, cg = continue_nearest(kin, qa[idx], None, kin.mechanism.home, inside=ws.inside,
                              pool=np.concatenate(seeds) if seeds else None)
    q[idx] = qg
    _replace_rows(cert, idx, cg)
    ok = cert.certified
    for b in range(0, len(q), CLOSED_FORM_BLOCK):
        out.append(q[b:b + CLOSED_FORM_BLOCK][ok[b:b + CLOSED_FORM_BLOCK]])
    for reason, good in zip(cert.reason, ok):
        if not good:
            rejected[reason] = rejected.get(reason, 0) + 1
    return kept + int(ok.sum())


def _replace_rows(cert, idx: np.ndarray, part) -> None:
    """Rows ``idx`` of a certificate replaced by those of ``part``, in place (what concatenating the other rows and
    ``part`` and putting them back in order gives, without three copies of a chunk's certificate)."""
    for name in ("certified", "min_condition", "min_sigma", "max_contraction", "max_branch_ratio", "steps", "rejected",
                 "path_length", "end_condition"):
        mine, theirs = getattr(cert, name), getattr(part, name)
        if np.result_type(mine, theirs) != mine.dtype:  # as the concatenation would: the wider type
            mine = mine.astype(np.result_type(mine, theirs))
            setattr(cert, name, mine)
        mine[idx] = theirs
    for i, r in zip(idx, part.reason):
        cert.reason[i] = r


def grid_slice(mechanism: Mechanism, axes: tuple, fixed: dict | None = None, n: int = 41,
               ranges: dict | None = None, kinematics: Kinematics | None = None) -> tuple[np.ndarray, np.ndarray,
                                                                                       np.ndarray]:
    """Configurations on a grid of two actuated joints, the others at home or at ``fixed`` values.

    Returns
    -------
    u, v : ndarray, (n,)
        Grid values of the two joints.
    q : ndarray, (n*n, n_q)
        Configurations (NaN rows where the mechanism does not assemble).
    """
    kin = kinematics or Kinematics(mechanism)
    act = list(mechanism.actuated)
    names = [mechanism.joints[i].name for i in act]
    idx = [names.index(a) for a in axes]
    lo, hi = mechanism.ranges[act].T.copy()
    for a, name in enumerate(names):
        if ranges and name in ranges:
            lo[a], hi[a] = ranges[name]
    u = np.linspace(lo[idx[0]], hi[idx[0]], n)
    v = np.linspace(lo[idx[1]], hi[idx[1]], n)
    base = mechanism.home[act].astype(float)
    for name, value in (fixed or {}).items():
        base[names.index(name)] = value
    qa = np.tile(base, (n * n, 1))
    uu, vv = np.meshgrid(u, v, indexing="ij")
    qa[:, idx[0]], qa[:, idx[1]] = uu.ravel(), vv.ravel()
    res = kin.solve(qa)
    q = res.q.copy()
    q[~res.converged] = np.nan
    return u, v, q


# ---------------------------------------------------------------------------- allocation
def compensable(maps_q: np.ndarray, mechanism: Mechanism, analysis=None, kinematics: Kinematics | None = None,
                tol: float = 1e-6) -> dict:
    """Which errors calibration can compensate: their effect lies in the range of the actuation map.

    An error is compensable when, at every configuration, its output twist is a combination
    of the actuated joints' twists (the controller can move the actuators to cancel it); the
    twist components are compared with rotations scaled by the length scale.  Returns
    parameter name -> largest relative part outside that range (0 for compensable).
    """
    kin = kinematics or Kinematics(mechanism)
    names, matrix = geometric_parameters(mechanism, analysis)
    st = kin.evaluate(maps_q, None, jacobians=True)
    k_xi, k_a = output_twist_maps(kin, st)
    k_g = k_xi @ matrix
    scale = np.r_[np.full(3, kin.length_scale), np.ones(3)][None, :, None]
    a = k_a * scale
    g = k_g * scale
    qa, _ = np.linalg.qr(a)
    rest = g - qa @ (np.swapaxes(qa, 1, 2) @ g)
    rel = np.linalg.norm(rest, axis=1) / np.linalg.norm(g, axis=1).clip(min=1e-300)
    return {n: float(rel[:, j].max()) for j, n in enumerate(names)}


def allocate(maps: AccuracyMaps, orientation_max: float | None = None, position_max: float | None = None,
             fixed: dict | None = None, weights: dict | None = None, maxima: dict | None = None) -> dict:
    """Tolerances per class (equal allocation, paper 2 eqs. 19, 30-31) and weighted per parameter.

    Parameters
    ----------
    maps : AccuracyMaps
        Coefficients over the workspace (their maxima are used: the bound holds everywhere).
    orientation_max, position_max : float, optional
        Required |dphi|max (rad) and ||dO_p||max (mm).
    fixed : dict, optional
        Class (``fP``, ``fR``, ``gP``, ``gR``) -> given tolerance per parameter (mm or rad), e.g.
        the actuation accuracy; the other classes share what is left.
    weights : dict, optional
        Parameter -> cost weight for the weighted allocation (cost ~ weight / tolerance).
    maxima : dict, optional
        Coefficient name -> its maximum over the workspace found by optimisation
        (:func:`hyperstat.solver.tolerances.worst_case.refine_extremes`); the larger of it
        and the sampled maximum is used, so the tolerances are never looser than the
        sample's.

    Returns
    -------
    dict
        ``classes`` (tolerance per parameter and the norm of the class), ``alpha_T`` (the
        angular geometric class) and ``d_T`` (the length class) when allocated,
        ``orientation_bound`` and ``position_bound`` (eqs. 18 at the allocated tolerances),
        and ``weighted`` per-parameter tolerances when weights are given.
    """
    c = {k: float(v.max()) for k, v in maps.coefficients.items()}
    for k, v in (maxima or {}).items():
        if k in c and v is not None and np.isfinite(v):
            c[k] = max(c[k], float(v))
    fixed = dict(fixed or {})
    counts = {k: len(v) for k, v in maps.groups.items()}
    classes = [k for k in ("fP", "fR", "gP", "gR") if counts[k]]
    unknown = [k for k in classes if k not in fixed]

    def coef(kind: str, cls: str) -> float:
        return c[f"{kind}_{cls}"]

    norms = {k: np.sqrt(counts[k]) * fixed[k] for k in classes if k in fixed}
    budgets = []
    if orientation_max is not None:
        budgets.append(("delta", orientation_max))
    if position_max is not None:
        budgets.append(("epsilon", position_max))
    tol = {}
    for k in unknown:
        best = np.inf
        for kind, budget in budgets:
            left = budget - sum(coef(kind, j) * norms[j] for j in norms)
            active = [j for j in unknown if coef(kind, j) > 1e-12]
            if k not in active:
                continue
            share = left / len(active)
            best = min(best, share / (coef(kind, k) * np.sqrt(counts[k])))
        tol[k] = best
    for k, t in tol.items():
        norms[k] = np.sqrt(counts[k]) * t if np.isfinite(t) else np.inf
    out = {"classes": {}, "coefficients_max": c}
    for k in classes:
        t = fixed.get(k, tol.get(k))
        out["classes"][k] = {"parameters": maps.groups[k], "tolerance": None if not np.isfinite(t) else float(t),
                             "norm": None if not np.isfinite(norms[k]) else float(norms[k]),
                             "given": k in fixed, "unit": "mm" if k.endswith("P") else "rad"}
    if "gR" in classes and np.isfinite(norms["gR"]):
        out["alpha_T"] = out["classes"]["gR"]["tolerance"]
    if "gP" in classes and np.isfinite(norms["gP"]):
        out["d_T"] = out["classes"]["gP"]["tolerance"]
    finite = all(np.isfinite(norms[k]) for k in classes)
    out["orientation_bound"] = float(sum(coef("delta", k) * norms[k] for k in classes)) if finite else None
    out["position_bound"] = float(sum(coef("epsilon", k) * norms[k] for k in classes)) if finite else None
    if weights:
        out["weighted"] = weighted_allocation(maps, weights, orientation_max, position_max)
    return out


def weighted_allocation(maps: AccuracyMaps, weights: dict, orientation_max: float | None,
                        position_max: float | None) -> dict:
    """Per-parameter tolerances minimising ``sum w_i / t_i`` under the linear bounds (Lagrange: t_i ~ sqrt(w_i / c_i)).

    Each parameter's coefficient ``c_i`` is its largest column norm over the workspace; the
    bound ``sum c_i t_i <= budget`` is conservative (triangle inequality).
    """
    names = list(maps.groups["gP"]) + list(maps.groups["gR"])
    out = {}
    scale = np.inf
    for kind, budget in (("rotation", orientation_max), ("position", position_max)):
        if budget is None:
            continue
        per = maps.per_parameter_summary()
        c = np.array([per[n][kind]["max"] for n in names])
        w = np.array([float(weights.get(n, 1.0)) for n in names])
        active = c > 1e-12
        if not np.any(active):
            continue
        shape = np.where(active, np.sqrt(w / np.where(active, c, 1.0)), 0.0)
        scale = min(scale, budget / float(np.sum(c[active] * shape[active])))
        out.setdefault("_shape", shape)
    shape = out.pop("_shape", None)
    if shape is None or not np.isfinite(scale):
        return {}
    return {n: float(scale * s) if s > 0 else None for n, s in zip(names, shape)}


def report_section(mechanism: Mechanism, analysis, kinematics: Kinematics | None = None, n: int = 400) -> dict:
    """Accuracy coefficients for the tolerance report: over ``n`` workspace configurations (JSON-ready)."""
    kin = kinematics or Kinematics(mechanism)
    q = sample_workspace(mechanism, n, seed=0, kinematics=kin)
    if len(q) == 0:
        return {}
    over = analysis is not None and analysis.overconstraint > 0
    maps = accuracy_maps(mechanism, q, analysis if over else None, kinematics=kin)
    worst = sorted(((d["position"]["max"], name) for name, d in maps.per_parameter_summary().items()), reverse=True)
    return {"configurations": len(q), "coefficients": maps.summary(), "units": maps.units,
            "allocation": {"largest_position_coefficients": [{"parameter": n_, "max": v} for v, n_ in worst[:10]]},
            "geometric_errors": "admissible influential defects" if over else "every defect parameter"}
