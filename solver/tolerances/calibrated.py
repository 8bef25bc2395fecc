"""Compensable tolerances with calibration: the largest defects a calibrated, compensated machine still holds.

Units: mm and rad.

A compensable tolerance's ``value`` keeps the spec on an *uncalibrated* machine.  A machine built to be
calibrated may be made coarser: the template's declared measurements identify the defect (or the
combination that absorbs it) and the controller cancels its effect on the task.  What limits how far
(:func:`calibrated_values`):

* **the second-order residual**: identification and compensation are exact only to first order when a
  defect is absorbed by other parameters; what is left grows as the square of the defects.  It is
  *simulated*, not assumed: for each compensable direction at a probe size, the machine's declared
  measurements (every target, the declared frame and offsets as unknowns) at the classification's
  configurations are fitted by Gauss-Newton over the admissible coordinates and the nuisances (the
  nonlinear model), the actuators are then solved in the fitted model for the nominal task poses over
  the workspace sample (Newton), and the true machine's task error there is measured.  Its
  coefficient ``kappa_i = residual / probe^2`` shapes the values (``v_i`` proportional to
  ``1 / sqrt(kappa_i)``), and all compensable defects *together* at those values, with random and
  all-equal signs (nine machines), scale them so that the largest residual is the share of the spec
  left for it (a residual of second order scales with the square of the values).  A defect stops
  growing with the scale at the value its other limits (below) or the validity cap give it: the
  combination is simulated with every defect at most at the value a machine built to the drawing can
  have, and the search ends when every defect is there;
* **the identification noise**: the calibration's 3-sigma task error from the declared measurement
  noise (:attr:`Classification.calibration`) comes off the spec first; the second-order residual
  shares what is left equally with the accuracy-critical classes (paper 2, eq. 30: equal shares), so
  the accuracy-critical allocation keeps its share;
* **the actuator stroke or the workspace**: the controller moves the actuators by the first-order
  correction ``(S K_a)^+ S K d`` per unit defect; where the joint ranges leave a margin around the
  declared workspace, the value must fit in it ("actuator stroke"); where they do not, the
  compensated machine loses that much of its workspace at the bounds, and the loss is held to
  :data:`WORKSPACE_LOSS` of each actuator's range ("workspace loss").

The value with calibration is the smallest of these limits (never below the uncalibrated value:
calibration cannot make a tolerance tighter), and the limit that binds is named.
"""

from __future__ import annotations

import math

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics, _element_rows, _with_tilt_velocities
from hyperstat.solver.kinematics.continuation import batched_lstsq
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.tolerances.accuracy import output_twist_maps
from hyperstat.solver.tolerances.declaration import n_rotation_rows, task_rows

__all__ = ["calibrated_values", "simulate_calibration", "regular_task", "actuator_room", "WORKSPACE_LOSS", "PROBE",
           "VALIDITY"]

#: the share of each actuator's range the compensation may cost at the workspace's bounds (assumed)
WORKSPACE_LOSS = 1e-3
#: probe size of the second-order simulation: rad, or mm per length scale
PROBE = 1e-3
#: the largest defect the simulation is trusted at (rad, or mm per length scale): the small-defect model
VALIDITY = 1e-2
#: configurations of the simulated calibration (evenly taken from the classification's, which span the workspace)
CALIBRATION_POSES = 36
#: configurations the compensated task error is measured at (evenly taken from the workspace sample)
TASK_POSES = 40
#: singular values of the nominal measurement design below this share of the largest are directions the
#: measurements do not see (round-off: the hexapod's gap is 1e-16 against 1e-2)
IDENTIFIABLE = 1e-8
#: compensation steps with the nominal machine's actuator map before the fitted model's own (Newton)
CHORD_STEPS = 6
#: largest move (rad, or per length scale) an assembly of a simulated machine starts with from the nominal machine's
#: first-order passive response: one Gauss-Newton step of the assembly at most (its ``max_step``); a larger predicted
#: move (a nominal configuration near a singularity of its passive joints) is not taken, that row starts as before
PREDICTED = 0.3
#: the largest defect (rad, or per length scale) whose machines are assembled by chord steps with the nominal
#: machine's passive inverse (Kinematics.assemble's ``_inverse``): it contracts about as much as the defects move the
#: passive map (hexapod: 1e-3 to 1e-2 per step at the probe, 0.05 to 0.2 at the validity cap, where Gauss-Newton's
#: fewer, dearer iterations cost less)
CHORD_DEFECTS = 2 * PROBE
#: an uncancelled task effect at the dead centres below this (dimensionless: per length scale) is round-off: no
#: workspace loss
ROUND_OFF = 1e-9
#: the largest share of the task configurations a compensated machine may miss (its reachable set moved: the
#: workspace's edge); more, and the defects are refused
MISSED = 0.05


def _targets(decl) -> np.ndarray:
    return np.asarray(decl.targets_mm, dtype=float)


def _measure(kin: Kinematics, q: np.ndarray, xi: np.ndarray, decl,
             pose: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Measured positions (K, 3 n_t) of every target (mm), and the output rotations (K, 3, 3) for ``poses``.

    ``pose``: the output poses at ``q`` (K, 4, 4) when already evaluated (an assembly's last state)."""
    pose = kin.evaluate(q, xi, jacobians=False).output_pose if pose is None else pose
    points = np.concatenate([pose[:, :3, :3] @ t + pose[:, :3, 3] for t in _targets(decl)], axis=1)
    return points, (pose[:, :3, :3] if decl.measurement_kind == "poses" else None)


def _misfit(measured: tuple, predicted: tuple, ls: float) -> np.ndarray:
    """Measured minus predicted rows (K, 3 n_t [+ 3]), dimensionless: positions per length scale, and for ``poses``
    the rotation taking the predicted orientation to the measured one (rad, in the base frame: the rows of the
    measurement maps)."""
    from hyperstat.solver.kinematics.frames import so3_log

    out = [(measured[0] - predicted[0]) / ls]
    if measured[1] is not None:
        out.append(so3_log(measured[1] @ np.swapaxes(predicted[1], 1, 2)))
    return np.concatenate(out, axis=1)


def calibration_setup(kin: Kinematics, analysis, decl, q_cal: np.ndarray, q_task: np.ndarray) -> dict:
    """What every :func:`simulate_calibration` at the same poses shares: the nominal machine's design and maps.

    The nominal measurement design (its identifiable subspace by SVD), the nominal measurements at
    ``q_cal`` and the nominal task poses, actuator maps and chord inverses at ``q_task`` depend on the
    poses only, not on the simulated machines: computed once (one batched Jacobian evaluation at each
    set of poses) and handed to every simulation of :func:`calibrated_values`.  So do the nominal
    machine's first-order passive responses (``-B_p^+ A`` to the defects at both sets of poses,
    ``-B_p^+ B_a`` to the actuators at ``q_task``), the simulations' assembly starts.
    """
    from hyperstat.solver.tolerances.classification import _measurement_maps

    ls = kin.length_scale
    basis = analysis.admissible_basis  # dimensionless
    n_s = basis.shape[1]
    k_c = len(q_cal)
    st0 = kin.evaluate(q_cal, None, jacobians=True)
    meas0, nuis0, _ = _measurement_maps(decl, st0, output_twist_maps(kin, st0)[0], ls, kin.parameter_scale)
    design = np.concatenate([(meas0 @ basis).reshape(-1, n_s), nuis0.reshape(k_c * nuis0.shape[1], -1)], axis=1)
    _, sv, vt = np.linalg.svd(design, full_matrices=False)
    seen = vt[sv > IDENTIFIABLE * sv[0]].T if sv.size and sv[0] > 0 else np.zeros((design.shape[1], 0))
    st_n = kin.evaluate(q_task, None, jacobians=True)
    sel_n = task_rows(decl.task, st_n.output_pose)
    rows_n = sel_n @ output_twist_maps(kin, st_n)[1]  # (K_t, r, n_a)
    return {"q_cal": q_cal, "q_task": q_task, "design": design, "seen": seen,
            "at_nominal": _measure(kin, q_cal, None, decl), "goal": st_n.output_pose, "chord": _damped_inverse(rows_n),
            **_passive_responses(kin, st0, st_n)}


def _passive_responses(kin: Kinematics, st_cal, st_task) -> dict:
    """The nominal machine's first-order passive responses at the calibration and task poses (an assembly's start).

    ``passive_cal`` (K_c, n_p, n_xi) and ``passive_task`` (K_t, n_p, n_xi): ``-B_p^+ A``, the passive joints' move
    per unit of each defect; ``passive_act`` (K_t, n_p, n_a): ``-B_p^+ B_a``, per unit of each actuator (closure
    rows scaled as :meth:`Kinematics.assemble` scales them).  Empty (no entries) without closures or passive joints:
    the assemblies then start as given.
    """
    m = kin.mechanism
    passive, act = np.asarray(m.passive), np.asarray(m.actuated)
    if not len(m.closures) or not len(passive):
        return {}
    inv_cal = _damped_inverse(kin.scaled_rows(st_cal.closure_q[:, :, passive]))
    inv_task = _damped_inverse(kin.scaled_rows(st_task.closure_q[:, :, passive]))
    return {"inverse_cal": inv_cal, "inverse_task": inv_task,
            "passive_cal": -inv_cal @ kin.scaled_rows(st_cal.closure_xi),
            "passive_task": -inv_task @ kin.scaled_rows(st_task.closure_xi),
            "passive_act": -inv_task @ kin.scaled_rows(st_task.closure_q[:, :, act]) if len(act) else None}


def simulate_calibration(mechanism: Mechanism, kin: Kinematics, analysis, decl, xi_true: np.ndarray,
                         q_cal: np.ndarray, q_task: np.ndarray, iterations: int = 3,
                         setup: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Task errors of machines with defects ``xi_true`` (M, n_xi) after calibration and compensation, noise-free.

    Calibration: the declared measurements at ``q_cal`` (actuated values held, passive joints solved on
    the true machine) fitted by Gauss-Newton over the admissible coordinates (the analysis' basis) and
    the nuisances the declaration leaves unknown (tracker frame, target offsets).  Compensation: at each
    ``q_task`` the actuators are solved in the fitted model so that it reaches the nominal task pose
    there (Newton); the true machine is then assembled at those actuated values.

    ``setup``: :func:`calibration_setup` at the same ``q_cal`` and ``q_task`` (computed here if omitted).

    Returns
    -------
    position, orientation : ndarray, (M, K_task)
        Task error norms per machine and configuration (mm, rad) on the declared task components.
    reached : ndarray of bool, (M, K_task)
        Whether the fitted model reached the nominal task pose there (False beyond its reachable set).
    """
    from hyperstat.solver.tolerances.classification import _measurement_maps

    m = mechanism
    xi_true = np.atleast_2d(xi_true)
    n_m, k_c, k_t = len(xi_true), len(q_cal), len(q_task)
    ls = kin.length_scale
    pscale = kin.parameter_scale
    basis = analysis.admissible_basis  # dimensionless
    n_s = basis.shape[1]
    act = np.asarray(m.actuated)

    def assembled(q0: np.ndarray, xi: np.ndarray, elements: tuple | None = None,
                  inverse: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        # the assembled configurations and their output poses (the assembly's last evaluation at them); ``elements``:
        # the element matrices of ``xi`` when the same machines were assembled before (computed once: the same bits);
        # ``inverse``: the nominal machine's passive inverse at each row's pose (chord steps, Kinematics.assemble).
        # Block by block of rows: each configuration's Gauss-Newton is its own (the same bits), in a working set that
        # stays in the cache
        parts = [kin.assemble(q0[idx], xi[idx], _elements=_element_rows(elements, idx, len(q0)),
                              _inverse=None if inverse is None else inverse[idx])
                 for idx in _row_blocks(len(q0), ASSEMBLY_ROWS)]
        return _joined([(res.q, res.output_pose) for res in parts])

    def design_rows(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # the measurement rows per admissible coordinate and the nuisance columns of the rows ``idx`` of (qe, xe)
        st = kin.evaluate(qe[idx], xe[idx], jacobians=True, _elements=_element_rows(elements_d, idx, len(qe)))
        k_xi, _ = output_twist_maps(kin, st)
        meas_xi, nuisance, _ = _measurement_maps(decl, st, k_xi, ls, pscale)
        return meas_xi @ basis, nuisance

    def newton_rows(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # the Newton step of the actuators at the rows ``idx`` of ``todo`` (the fitted models' own map), and the
        # step's right-hand side; the actuators' map only (the defects' columns are not needed: the same numbers)
        rows = todo[idx]
        st = kin.evaluate(qt[rows], xt[rows], jacobians="actuation", _elements=_element_rows(elements_t, rows, len(qt)))
        sel = task_rows(decl.task, st.output_pose)
        rhs = -np.einsum("krs,ks->kr", sel, _pose_error(st.output_pose, goal[rows]))
        return batched_lstsq(sel @ output_twist_maps(kin, st)[1], rhs[..., None], damping=1e-14)[..., 0], rhs

    if setup is None or setup["q_cal"] is not q_cal or setup["q_task"] is not q_task:
        setup = calibration_setup(kin, analysis, decl, q_cal, q_task)
    passive = np.asarray(m.passive)
    # the nominal machine's passive inverses at every row's pose (machine-major): each assembly's chord steps
    chordal = "inverse_cal" in setup and float(np.max(np.abs(xi_true) / pscale, initial=0.0)) <= CHORD_DEFECTS
    inverse_cal = np.tile(setup["inverse_cal"], (n_m, 1, 1)) if chordal else None
    inverse_task = np.tile(setup["inverse_task"], (n_m, 1, 1)) if chordal else None
    step_scale = kin.joint_scale[passive] * PREDICTED if len(passive) else None

    def shift(q: np.ndarray, rows: np.ndarray, dq: np.ndarray) -> None:
        # the passive joints of ``q[rows]`` moved by ``dq`` (in place), except where the move exceeds PREDICTED of
        # a joint's scale (more than one assembly step: that row starts where it was)
        small = np.max(np.abs(dq) / step_scale, axis=1) <= 1.0
        q[np.ix_(rows[small], passive)] += dq[small]

    def predicted(q: np.ndarray, key: str, dxi: np.ndarray) -> np.ndarray:
        # an assembly's start: ``q`` (M K, n_q; machine-major, K poses each) with its passive joints moved by the
        # nominal machine's first-order response to the change of defects ``dxi`` (M, n_xi) since ``q`` was
        # assembled (or from the nominal machine).  The fixed point is the assembly's, as from any start in its
        # basin; only the Gauss-Newton iterations to reach it are fewer (an error of second order in the defects
        # instead of first)
        if key not in setup:
            return q
        q = q.copy()
        shift(q, np.arange(len(q)), np.einsum("kpx,mx->mkp", setup[key], dxi).reshape(len(q), -1))
        return q

    # the true machines' measurements; each machine's element matrices computed once and repeated to its rows
    # (every row's are its own: the same bits as computed row by row), for this assembly and the last one.  Each
    # assembly starts from the nominal configuration moved by the passive joints' first-order response
    qc = predicted(np.tile(q_cal, (n_m, 1)), "passive_cal", xi_true)
    xc = np.repeat(xi_true, k_c, axis=0)
    elements_true = _machine_elements(kin, xi_true)
    qe, pose_e = assembled(qc, xc, _per_row(elements_true, n_m, k_c, len(xc)), inverse_cal)
    y = _measure(kin, qe, xc, decl, pose_e)
    # Gauss-Newton over (admissible coordinates, nuisances); the nuisances enter linearly (tracker frame as a
    # small rigid motion, offsets in the output frame), so their columns are those of the analysis' design.  The
    # fit runs over the combinations the measurements see on the nominal machine (the identifiable subspace, as
    # identify fits them); a direction they do not see stays at zero.  Orientation rows compare rotations (the
    # rotation from the predicted to the measured one), as the measurement maps' rows do.  The first step starts
    # from the nominal machine, whose configurations and maps are known (one design for every machine)
    design, seen, at_nominal = setup["design"], setup["seen"], setup["at_nominal"]
    at_nominal = (np.tile(at_nominal[0], (n_m, 1)),
                  None if at_nominal[1] is None else np.tile(at_nominal[1], (n_m, 1, 1)))
    first = _misfit(y, at_nominal, ls).reshape(n_m, -1)
    coef = np.linalg.lstsq(design @ seen, first.T, rcond=None)[0].T  # coordinates in the identifiable subspace
    xi_at = xi_true  # the machines ``qe`` is assembled for
    for _ in range(iterations - 1):  # then Gauss-Newton at the estimate, warm-started at the true machines
        x = coef @ seen.T
        xi_est = (basis @ x[:, :n_s].T).T * pscale[None, :]
        qe, xi_at = predicted(qe, "passive_cal", xi_est - xi_at), xi_est
        xe = np.repeat(xi_est, k_c, axis=0)
        machines = _machine_elements(kin, xi_est)
        elements_e = _per_row(machines, n_m, k_c, len(xe))  # for the assembly
        # and for the Jacobians, with the axis tilts' velocities of each machine (computed once per machine)
        elements_d = _per_row(_with_tilt_velocities(kin, machines), n_m, k_c, len(xe))
        qe, pose_e = assembled(qe, xe, elements_e, inverse_cal)
        meas_s, nuisance = _joined([design_rows(idx) for idx in _row_blocks(len(qe))])
        jac = meas_s.reshape(n_m, k_c, -1, n_s).reshape(n_m, -1, n_s)
        nj = nuisance.reshape(n_m, k_c * nuisance.shape[1], -1)
        resid = _misfit(y, _measure(kin, qe, xe, decl, pose_e), ls).reshape(n_m, -1) - np.einsum("krn,kn->kr", nj, x[:, n_s:])
        full = np.concatenate([jac, nj], axis=2) @ seen
        coef += batched_lstsq(full, resid[..., None], damping=1e-14)[..., 0]
    xi_est = (basis @ (coef @ seen.T)[:, :n_s].T).T * pscale[None, :]
    # compensation: actuators solved in the fitted model for the nominal task poses, steps capped: chord steps with
    # the nominal machine's actuator map (the same for every machine: no Jacobian per machine), then Newton steps
    # with the fitted model's own map where the chord has not converged.  The assemblies start from the nominal
    # configuration moved by the passive joints' first-order response to the fitted defects, and after each actuator
    # step by their nominal response to it (the fixed points are the assemblies' own, reached in fewer iterations)
    n_rot = n_rotation_rows(decl.task)
    chord = np.tile(setup["chord"], (n_m, 1, 1))
    goal = np.tile(setup["goal"], (n_m, 1, 1))
    qt = predicted(np.tile(q_task, (n_m, 1)), "passive_task", xi_est)
    xt = np.repeat(xi_est, k_t, axis=0)
    elements_t = _per_row(_machine_elements(kin, xi_est), n_m, k_t, len(xt))  # the fitted models', for every step
    cap = 0.05 * kin.joint_scale[act]
    tscale = _task_scale(decl, ls)
    todo = np.arange(len(qt))
    pose = np.empty((len(qt), 4, 4))  # each row's last assembled pose
    follow = setup.get("passive_act")
    for it in range(CHORD_STEPS + iterations):
        qt[todo], pose[todo] = assembled(qt[todo], xt[todo], _element_rows(elements_t, todo, len(qt)),
                                          None if inverse_task is None else inverse_task[todo])
        if it < CHORD_STEPS:
            rhs = -np.einsum("krs,ks->kr", task_rows(decl.task, pose[todo]), _pose_error(pose[todo], goal[todo]))
            done = np.linalg.norm(rhs * tscale[None, :], axis=1) <= 1e-12
            da = np.einsum("kar,kr->ka", chord[todo], rhs)
        else:  # Newton with the fitted model's map
            da, rhs = _joined([newton_rows(idx) for idx in _row_blocks(len(todo))])
            done = np.linalg.norm(rhs * tscale[None, :], axis=1) <= 1e-12
        da = da / np.maximum(np.max(np.abs(da) / cap, axis=1, keepdims=True), 1.0)
        moved = todo[~done]
        qt[moved[:, None], act[None, :]] += da[~done]
        if follow is not None:
            shift(qt, moved, np.einsum("kpa,ka->kp", follow[moved % k_t], da[~done]))
        todo = moved
        if not len(todo):
            break
    if len(todo):  # the rows moved by the last step; the others were assembled at their actuated values already
        qt[todo], pose[todo] = assembled(qt[todo], xt[todo], _element_rows(elements_t, todo, len(qt)),
                                          None if inverse_task is None else inverse_task[todo])
    reached = np.einsum("krs,ks->kr", task_rows(decl.task, pose), _pose_error(pose, goal))
    reached = np.linalg.norm(reached * tscale[None, :], axis=1) <= 1e-9
    xt_true = np.repeat(xi_true, k_t, axis=0)
    qt = predicted(qt, "passive_task", xi_true - xi_est)
    qt, true_pose = assembled(qt, xt_true, _per_row(elements_true, n_m, k_t, len(xt_true)), inverse_task)
    err = np.einsum("krs,ks->kr", task_rows(decl.task, true_pose), _pose_error(true_pose, goal))
    pos = np.linalg.norm(err[:, n_rot:], axis=1).reshape(n_m, k_t)
    rot = np.linalg.norm(err[:, :n_rot], axis=1).reshape(n_m, k_t)
    return pos, rot, reached.reshape(n_m, k_t)


#: configurations per block of a simulated calibration's Jacobians (every configuration is computed alone: the same
#: bits whatever the block): the hexapod's probe wrote the defect Jacobians of 2,592 machine-configurations, 175 MiB,
#: at once; a block's are 26 MiB
ROWS = 384
#: configurations per block of its assemblies (the same bits): a block's Gauss-Newton arrays stay in the cache, and the
#: hexapod's probe took 2.3 instead of 2.6 s of CPU (blocks of 350: 2.5 s, the calls' overhead)
ASSEMBLY_ROWS = 768


def _machine_elements(kin: Kinematics, xi: np.ndarray) -> tuple:
    """The element matrices of each machine ``xi`` (M, n_xi) (:meth:`Kinematics._all_element_matrices`)."""
    return kin._all_element_matrices(np.ascontiguousarray(xi, dtype=float))  # noqa: SLF001


def _per_row(elements: tuple, n_m: int, k: int, rows: int) -> tuple | None:
    """The element matrices of ``n_m`` machines (:func:`_machine_elements`) repeated to their ``k`` configurations
    each (the rows of ``np.repeat(xi, k, axis=0)``): row ``i`` is machine ``i // k``'s, computed once for all of its
    configurations instead of once per configuration (each row's matrices are computed alone: the same bits).  None
    when ``rows`` is one (as before: an evaluation of one row reads its defects as one geometry)."""
    if rows <= 1:
        return None
    return _element_rows(elements, np.repeat(np.arange(n_m), k), n_m)


def _row_blocks(n: int, size: int = ROWS) -> list:
    """Row indices of ``n`` rows in near-equal blocks of about ``size`` (never a block of one row when ``n > 1``: an
    evaluation of one row reads its defects as one geometry for all).

    >>> [len(b) for b in _row_blocks(5, 2)], [len(b) for b in _row_blocks(1000)]
    ([3, 2], [334, 333, 333])
    """
    if n <= size:
        return [np.arange(n)]
    return np.array_split(np.arange(n), min(-(-n // size), n // 2))


def _joined(parts: list) -> tuple:
    """The blocks' results (tuples of arrays over their rows) joined row-wise."""
    if len(parts) == 1:
        return tuple(parts[0])
    return tuple(np.concatenate(arrays, axis=0) for arrays in zip(*parts))


def _damped_inverse(rows: np.ndarray, damping: float = 1e-14) -> np.ndarray:
    """``(A^T A + lambda)^-1 A^T`` of each (r, n) matrix of a stack (K, r, n): the least-squares step's map (K, n, r)."""
    at = np.swapaxes(rows, 1, 2)
    ata = at @ rows
    idx = np.arange(ata.shape[1])
    ata[:, idx, idx] += damping * np.maximum(np.einsum("kii->ki", ata).max(axis=1), 1e-300)[:, None]
    return np.linalg.solve(ata, at)


def _task_scale(decl, ls: float) -> np.ndarray:
    """Task rows in dimensionless units: rotations in rad, positions per length scale."""
    n_rot = n_rotation_rows(decl.task)
    rows = task_rows(decl.task, np.eye(4)[None]).shape[1]
    return np.r_[np.ones(n_rot), np.full(rows - n_rot, 1.0 / ls)]


def _actuation(kin: Kinematics, decl, q: np.ndarray, defects: bool = True) -> tuple:
    """Kinematic state, twist maps, task rows and the dimensionless singular values of the actuators' task map.

    ``defects=False``: the defects' twist map is not computed (None); the rest is the same."""
    st = kin.evaluate(q, None, jacobians=True if defects else "actuation")
    k_xi, k_a = output_twist_maps(kin, st)
    sel = task_rows(decl.task, st.output_pose)
    rows = (sel @ k_a) * _task_scale(decl, kin.length_scale)[None, :, None]
    rows = rows * kin.joint_scale[kin.mechanism.actuated][None, None, :]
    s = np.linalg.svd(rows, compute_uv=False)
    smallest = s[:, min(rows.shape[1:]) - 1] if s.size else np.ones(len(q))
    return st, k_xi, k_a, sel, smallest


def regular_task(kin: Kinematics, decl, q: np.ndarray, floor: float = 1e-2, reference: float | None = None) -> np.ndarray:
    """Configurations where the actuators command every task direction: the smallest singular value of the
    dimensionless task map of the actuators at least ``floor`` of its median over ``q`` (or of ``reference``);
    a dead centre of the task, where a defect moves the reachable task space itself, is left out and counted as
    workspace loss."""
    smallest = _actuation(kin, decl, q, defects=False)[4]
    return smallest >= floor * (float(np.median(smallest)) if reference is None else reference)


def _pose_error(pose: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Twist (omega, v) taking ``goal`` to ``pose`` (K, 6): rotation vector (rad), position difference (mm)."""
    from hyperstat.solver.kinematics.frames import so3_log

    return np.concatenate([so3_log(pose[:, :3, :3] @ np.swapaxes(goal[:, :3, :3], 1, 2)),
                           pose[:, :3, 3] - goal[:, :3, 3]], axis=1)


def calibrated_values(cl, mechanism: Mechanism, kin: Kinematics, configurations: np.ndarray, spec_p, spec_o,
                      workspace=None, share: dict | None = None, seed: int = 0) -> dict:
    """Fill ``value_with_calibration`` and ``value_with_calibration_limit`` of every compensable tolerance (in place).

    Parameters
    ----------
    cl : Classification
        With the uncalibrated values filled (:func:`hyperstat.solver.tolerances.values.assign_values`).
    configurations : ndarray, (K, n_q)
        The workspace sample the compensated task error is measured on.
    spec_p, spec_o : float or None
        The spec (mm, rad).
    share : dict, optional
        ``position_mm`` / ``orientation_rad``: the part of the spec left to the second-order residual
        (the values' allocation sets it; default: the spec less the calibration residual).

    Returns
    -------
    dict
        JSON-ready evidence: the budget, the probe, every ``kappa``, the combined simulation's worst
        residuals, the limits per tolerance.
    """
    from hyperstat.solver.tolerances.workspace import workspace_of
    from hyperstat.solver.tolerances.worst_case import remember_candidates

    items = [t for t in cl.items if t.cls == "compensable" and t.value]
    if not items or cl.analysis is None:
        return {}
    m = mechanism
    decl = cl.declaration
    loss = float(getattr(decl, "workspace_loss", WORKSPACE_LOSS))  # the declared budget (default 0.1 %)
    cal = cl.calibration
    share = dict(share or {})
    budget = {"position_mm": share.get("position_mm", None if spec_p is None else spec_p - cal.get("position_mm", 0.0)),
              "orientation_rad": share.get("orientation_rad",
                                           None if spec_o is None else spec_o - cal.get("orientation_rad", 0.0))}
    n_rot = n_rotation_rows(decl.task)
    has_p = len(task_rows(decl.task, np.eye(4)[None])[0]) > n_rot
    budget = {k: v for k, v in budget.items() if v is not None and ((k == "position_mm") == has_p or
                                                                   (k == "orientation_rad" and n_rot))}
    q_cal = cl.configurations if cl.configurations is not None else cl.analysis.configurations
    q_cal = q_cal[np.unique(np.linspace(0, len(q_cal) - 1, min(len(q_cal), CALIBRATION_POSES)).round().astype(int))]
    q_all = np.atleast_2d(configurations)
    q_all = q_all[np.unique(np.linspace(0, len(q_all) - 1, min(len(q_all), TASK_POSES)).round().astype(int))]
    regular = regular_task(kin, decl, q_all)
    q_task = q_all[regular]  # the dead centres of the task are counted as workspace loss, below
    ls = kin.length_scale
    units = {t.id: t.unit for t in items}
    probe = {t.id: PROBE * (ls if t.unit == "mm" else 1.0) for t in items}
    dirs = np.stack([t.direction for t in items])  # (n, n_xi) per unit of each tolerance
    # the task's dead centres (3. below) do not depend on the simulations: a forked child searches them meanwhile
    # (the same arithmetic: the same bits), and hands back the workspace's candidates too, which loss_together
    # reads next (issue 39: 0.4 s of the Triflex-II's values with calibration, on the command's critical path)
    from hyperstat.solver.forked import Forked

    is_mm = np.array([units[t.id] == "mm" for t in items])
    dead_centres = Forked(_task_space_loss_and_candidates, kin, decl, q_all, dirs, is_mm)
    # 1. every direction alone at its probe: kappa (residual per probe^2), position and orientation
    sizes = np.array([probe[t.id] for t in items])
    setup = calibration_setup(kin, cl.analysis, decl, q_cal, q_task)  # shared by every simulation below
    pos, rot, ok = simulate_calibration(m, kin, cl.analysis, decl, dirs * sizes[:, None], q_cal, q_task, setup=setup)
    # a residual at the round-off of the probe reads as that round-off: kappa is never below it (it shapes the values)
    floor = 1e-11 * ls / sizes**2
    kappa = {"position_mm": np.maximum(np.where(ok, pos, 0.0).max(axis=1) / sizes**2, floor),
             "orientation_rad": np.maximum(np.where(ok, rot, 0.0).max(axis=1) / sizes**2, floor / ls)}
    # 2. the shape: v_i ~ 1 / sqrt(kappa_i) (each defect the same second-order share), the worst kind first
    weight = np.zeros(len(items))
    for key, b in budget.items():
        if b and b > 0:
            weight = np.maximum(weight, kappa[key] / b)
    shape = 1.0 / np.sqrt(np.maximum(weight, 1e-300))
    # 3. actuator stroke, or the workspace lost where the compensation cannot follow (before the combined simulation:
    # a defect these limit sits at that value on the machine, and the combination is simulated with it there)
    margin, width, rev, has_margin, room = actuator_room(m, workspace or workspace_of(m), loss)
    st = kin.evaluate(q_task, None, jacobians=True)
    k_xi, k_a = output_twist_maps(kin, st)
    sel = task_rows(decl.task, st.output_pose)
    corr = np.abs(np.linalg.pinv(sel @ k_a, rcond=1e-8) @ (sel @ k_xi @ dirs.T))  # (K, n_a, n)
    per_actuator = corr.max(axis=0)  # (n_a, n) actuator motion per unit of each tolerance
    # round-off is no motion (the Tripteor's dK of a wrist axis: 7e-15 rad per rad, which read as a limit of 4e10 rad)
    moves = per_actuator / kin.joint_scale[m.actuated][:, None] * np.where(is_mm, ls, 1.0)[None, :] > ROUND_OFF
    per_actuator = np.where(moves, per_actuator, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        per_unit = np.where(per_actuator > 0, room[:, None] / per_actuator, np.inf)
    stroke, which = per_unit.min(axis=0), per_unit.argmin(axis=0)
    # the task's dead centres (where the actuators lose a task direction: the slider-crank's stroke ends): there the
    # defect moves the reachable task space itself, by its uncancelled task effect; the loss is held to
    # WORKSPACE_LOSS of the task's extent over the sample
    (loss_task, loss_where), searched = dead_centres.result()
    remember_candidates(kin, workspace_of(m), q_all, searched)
    extent = _task_extent(kin, decl, q_all)
    with np.errstate(divide="ignore"):
        task_limit = np.where(loss_task > 0, loss * extent / loss_task, np.inf)
    # 4. all together, nine machines (all-equal signs and eight random patterns), scaled to the budget: a second-order
    # residual scales with the square of the values, and the scaling is checked by simulating again at the values.
    # Each defect grows with the scale up to the value it can have: the validity cap, or its actuator-stroke and
    # workspace-loss limits (never below its value without calibration).  A machine built to the values has every
    # defect at its own, so the combination is simulated with them there: a defect bound by another limit does not
    # grow on to the cap and spend the others' share of the residual (48 of the hexapod's defects, held to 0.12 mm by the
    # workspace loss, were simulated at 4.98 mm, and the search ended at its step limit before the others reached
    # their own values)
    rng = np.random.default_rng(seed)
    signs = np.vstack([np.ones(len(items)), rng.choice([-1.0, 1.0], size=(8, len(items)))])
    dimensionless = shape / np.where(is_mm, ls, 1.0)
    unit = shape * (PROBE / max(float(np.max(dimensionless)), 1e-300))  # scale 1: the largest defect at the probe
    cap = VALIDITY * np.where(is_mm, ls, 1.0)  # the simulation is trusted up to this (rad, mm)
    floor_value = np.array([float(t.value) for t in items])  # mm or rad: the value without calibration
    top = np.minimum(cap, np.maximum(np.minimum(stroke, task_limit), floor_value))  # where each defect stops growing
    noise_bound = any(b <= 0 for b in budget.values())
    worst, unreached, limiting_kind = {}, 0, None
    # from the probe (scale 1) up, each step by what the residual left so far allows (a residual of second order
    # grows as the square of the scale), every scale checked by simulation; a refused one is bisected
    good, bad, scale, missed = 0.0, np.inf, 1.0, False
    for _ in range(6):
        if noise_bound:
            break
        values = np.minimum(scale * unit, top)
        pos_c, rot_c, ok_c = simulate_calibration(m, kin, cl.analysis, decl, (signs * values[None, :]) @ dirs, q_cal,
                                                  q_task, setup=setup)
        found = {"position_mm": float(np.where(ok_c, pos_c, 0.0).max()),
                 "orientation_rad": float(np.where(ok_c, rot_c, 0.0).max())}
        ratio, kind = min(((math.sqrt(b / found[k]) if found[k] > 0 else np.inf, k) for k, b in budget.items()),
                          default=(np.inf, None))
        if np.mean(~ok_c) > MISSED:  # the calibrated model misses the task poses: beyond what it can compensate
            ratio, missed = min(ratio, 0.5), True
        elif ratio < 1.0:
            missed = False
        if ratio >= 1.0:  # within the budget: verified
            good, worst, unreached, limiting_kind = scale, found, int(np.sum(~ok_c)), kind
            if ratio <= 1.15 or np.all(values >= top):  # within 15 % of the budget (close enough, on the safe side),
                # or every defect at the value it can have
                break
            scale = min(scale * min(0.99 * ratio, 10.0), math.sqrt(scale * bad) if math.isfinite(bad) else np.inf)
        else:  # beyond it: back between the verified scale and this one
            bad = scale
            scale = math.sqrt(good * scale) if good else scale * 0.25
        if not math.isfinite(scale):
            break
    values = np.zeros(len(items)) if noise_bound else np.minimum(good * unit, top)
    capped = values >= cap * (1 - 1e-12)
    # stopped by another limit (or its value without calibration) before the cap: the combination kept the spec with
    # the defect there, so the second-order residual does not limit it below that value
    elsewhere = (values >= top * (1 - 1e-12)) & ~capped
    second = values
    evidence = {"budget": budget, "probe": {"rad": PROBE, "mm": PROBE * ls}, "validity": {"rad": VALIDITY,
                                                                                         "mm": VALIDITY * ls},
                "machines_combined": int(len(signs)), "combined_worst_at_the_values": worst,
                "workspace_loss_allowed": loss, "task_extent": extent,
                "configurations": {"calibration": int(len(q_cal)), "task": int(len(q_task)),
                                   "task_singular_left_out": int(np.sum(~regular)),
                                   "task_dead_centres": loss_where,
                                   "not_reached_in_the_combined_machines": unreached}, "items": {}}
    unit_of = lambda a: "rad" if rev[a] else "mm"  # noqa: E731
    task_unit = "mm" if len(task_rows(decl.task, np.eye(4)[None])[0]) > n_rot else "rad"
    budget_words = (f"the workspace-loss budget, {100 * loss:g} % ("
                    + ("declared" if "workspace_loss" in decl.declared else "the default, assumed")
                    + "; TOLERANCING workspace_loss or --workspace-loss)")
    for i, t in enumerate(items):
        a = int(which[i])
        actuator = m.joints[m.actuated[a]].name
        limits: dict = {}
        for n, (key, v) in enumerate(((("workspace loss" if missed and not capped[i] else "second-order residual"),
                                        second[i]),
                                       (("actuator stroke" if has_margin[a] else "workspace loss"), stroke[i]),
                                       ("workspace loss", task_limit[i]))):
            if math.isfinite(v) and not (n == 0 and elsewhere[i]):  # the second-order residual limits it, or not
                limits[key] = min(limits.get(key, np.inf), float(v))
        if noise_bound:
            value, limit = 0.0, "identification noise"
            words = ("identification noise: the calibration's 3-sigma task error from the declared noise "
                     f"({cal.get('position_mm', 0.0):.3g} mm, {cal.get('orientation_rad', 0.0):.3g} rad) uses up "
                     "the spec")
        else:
            limit = min(limits, key=limits.get)
            value = limits[limit]
            if limit == "workspace loss" and missed and limits[limit] == float(second[i]):
                words = (f"workspace loss: beyond it the calibrated machines (nine simulated, every compensable defect "
                         f"at its value) miss more than {100 * MISSED:g} % of the task poses over the workspace sample: "
                         "the reachable task space moves by the defects")
            elif limit == "second-order residual" and capped[i]:
                words = (f"second-order residual: simulated only up to {VALIDITY:g} rad or {VALIDITY:g} of the length "
                         f"scale ({VALIDITY * ls:.3g} mm), where the nine calibrated machines still keep the spec "
                         "(the small-defect model is not trusted beyond)")
            elif limit == "second-order residual" and limiting_kind is None:
                words = ("second-order residual: no simulated calibrated machine kept the spec down to the probe size "
                         f"({PROBE:g} rad or {PROBE:g} of the length scale)")
            elif limit == "second-order residual":
                words = (f"second-order residual: with every compensable defect at its value together (nine simulated "
                         f"machines, calibrated from the declared measurements and compensated through the nonlinear "
                         f"model), the task error left reaches the share of the spec it has after the identification "
                         f"noise ({budget[limiting_kind]:.3g} {limiting_kind.split('_')[1]})")
            elif limit == "actuator stroke":
                words = (f"actuator stroke: compensating it moves actuator {actuator} by {per_actuator[a, i]:.3g} "
                         f"{unit_of(a)} per {t.unit} of the defect, within the {margin[a]:.3g} {unit_of(a)} its range "
                         "leaves around the workspace")
            elif math.isfinite(task_limit[i]) and limits["workspace loss"] == float(task_limit[i]):
                words = (f"workspace loss: at the task's dead centres the actuators cannot follow it, and the reachable "
                         f"task space moves by {loss_task[i]:.3g} {task_unit} per {t.unit} of the defect; the loss is "
                         f"held to {loss * extent:.3g} {task_unit}, {budget_words} of the task's extent "
                         f"({extent:.4g} {task_unit})")
            else:
                words = (f"workspace loss: compensating it moves actuator {actuator} by {per_actuator[a, i]:.3g} "
                         f"{unit_of(a)} per {t.unit} of the defect and its range leaves no margin around the "
                         f"workspace: the loss is held to {loss * width[a]:.3g} {unit_of(a)}, {budget_words} of its "
                         f"range ({width[a]:.4g} {unit_of(a)})")
        if value < t.value:
            value, words = t.value, words + "; calibration does not open it beyond the value without calibration"
        t.value_with_calibration = float(value)
        t.value_with_calibration_limit = words
        evidence["items"][t.id] = {"kappa_position": float(kappa["position_mm"][i]),
                                   "kappa_orientation": float(kappa["orientation_rad"][i]), "limits": limits,
                                   "binding": limit, "in_the_combined_machines": float(values[i])}
    return evidence


def actuator_room(mechanism: Mechanism, workspace, loss: float) -> tuple:
    """What each actuator's range leaves for the compensation around the declared workspace (mm or rad).

    Returns
    -------
    margin, width : ndarray, (n_a,)
        The range beyond the workspace's actuated box on its tighter side, and the box's width.
    revolute, has_margin : ndarray of bool, (n_a,)
    room : ndarray, (n_a,)
        The margin where there is one, else ``loss`` of the width (the workspace-loss budget); infinite for a
        revolute actuator turning a full turn.
    """
    m = mechanism
    lo_ws, hi_ws = workspace.actuated_box(m)
    lo_j, hi_j = m.ranges[m.actuated].T
    margin = np.minimum(lo_ws - lo_j, hi_j - hi_ws)
    width = hi_ws - lo_ws
    rev = np.array([m.joints[i].type == "R" for i in m.actuated])
    turn = rev & (width >= 2 * math.pi - 1e-9)
    has_margin = margin > 1e-12 * np.maximum(width, 1e-300)
    return margin, width, rev, has_margin, np.where(turn, np.inf, np.where(has_margin, margin, loss * width))


def _task_space_loss_and_candidates(kin: Kinematics, decl, q: np.ndarray, dirs: np.ndarray,
                                    lengths: np.ndarray) -> tuple:
    """:func:`_task_space_loss` and the workspace's candidates it searched (what a forked child hands back)."""
    from hyperstat.solver.tolerances.workspace import workspace_of
    from hyperstat.solver.tolerances.worst_case import workspace_candidates

    return _task_space_loss(kin, decl, q, dirs, lengths), workspace_candidates(kin, workspace_of(kin.mechanism), q)


def _task_space_loss(kin: Kinematics, decl, q: np.ndarray, dirs: np.ndarray,
                     lengths: np.ndarray) -> tuple[np.ndarray, int]:
    """Largest uncancellable task effect per unit of each direction at the task's dead centres (n,), and how many.

    ``lengths``: which directions are lengths (mm; the others rad).  An uncancelled effect below :data:`ROUND_OFF`
    in dimensionless units (task positions and length defects per length scale) is round-off: no loss.

    The dead centres: the workspace's candidates solved where a passive joint's velocity changes sign
    (:func:`hyperstat.solver.tolerances.worst_case.workspace_candidates`) and the sample's configurations,
    kept where the actuators lose a task direction (:func:`regular_task` false).
    """
    from hyperstat.solver.tolerances.workspace import workspace_of
    from hyperstat.solver.tolerances.worst_case import workspace_candidates

    m = kin.mechanism
    cand, labels = workspace_candidates(kin, workspace_of(m), q)
    median = float(np.median(_actuation(kin, decl, q, defects=False)[4]))
    pool = np.vstack([q] + ([cand] if len(cand) else []))
    singular = ~regular_task(kin, decl, pool, reference=median)
    if not singular.any():
        return np.zeros(len(dirs)), 0
    st, k_xi, k_a, sel, _ = _actuation(kin, decl, pool[singular])
    scale = _task_scale(decl, kin.length_scale)[None, :, None]
    effect = sel @ k_xi @ dirs.T  # (K, r, n)
    ta = (sel @ k_a) * scale * kin.joint_scale[m.actuated][None, None, :]
    u, sv, _ = np.linalg.svd(ta, full_matrices=True)
    seen = (sv >= 1e-2 * median)  # the task directions the actuators still command there
    left = effect.copy()
    for k in range(len(left)):
        span = u[k][:, :int(seen[k].sum())]
        left[k] = effect[k] - (span * (1 / scale[0])) @ (span.T @ (effect[k] * scale[0])) if span.size else effect[k]
    # round-off is no loss (the slider-crank's dK4 moves nothing at its stroke ends: 1e-14 mm per rad, which read as
    # a limit of 8e12 mm)
    largest = np.linalg.norm(left, axis=1).max(axis=0)
    dimensionless = np.linalg.norm(left * scale, axis=1).max(axis=0) * np.where(lengths, kin.length_scale, 1.0)
    return np.where(dimensionless > ROUND_OFF, largest, 0.0), int(singular.sum())


def _task_extent(kin: Kinematics, decl, q: np.ndarray) -> float:
    """The smallest extent of the task over the sample: of the position components (mm), else the rotations (rad)."""
    pose = kin.evaluate(q, None, jacobians=False).output_pose
    n_rot = n_rotation_rows(decl.task)
    rows = task_rows(decl.task, pose[:1])[0]
    if rows.shape[0] > n_rot:
        p = pose[:, :3, 3] @ rows[n_rot:, 3:].T
        return float(np.min(np.ptp(p, axis=0)))
    from hyperstat.solver.kinematics.frames import so3_log

    r = so3_log(pose[:, :3, :3]) @ rows[:n_rot, :3].T
    return float(np.min(np.ptp(r, axis=0)))
