"""Values of the tolerances: allocation against the spec, clearances for assembly conditions.

Units: mm and rad.

* **accuracy-critical**: equal allocation of paper 2 (eqs. 19 and 30-31) against the spec
  over the workspace: the task-error coefficients of the accuracy-critical directions,
  split by kind (``gP``: lengths, ``gR``: angles), are the largest singular values of their
  task rows (``epsilon`` for position, ``delta`` for orientation, eq. 18), and the budget
  is the spec less what calibration noise leaves (:attr:`Classification.calibration`).
  The allocation divides by the *worst case* of each coefficient over the declared
  workspace, searched by the one worst-case engine
  (:func:`hyperstat.solver.tolerances.worst_case.search_extremes`: sample, corners, edges,
  faces and dead centres, then a projected-gradient search on the configuration manifold),
  plus its stated tolerance; a sampled maximum is low by construction and would make the
  values loose (the unsafe direction);
* **compensable**: the same allocation over every influential direction (accuracy-critical
  and compensable) without calibration: the value that keeps the spec on an
  uncalibrated machine; calibration lets it open;
* **non-influent**: no value from accuracy (any value the assembly conditions allow);
* **assembly**: the clearance-based worst-case assemblability of
  :mod:`hyperstat.solver.tolerances.clearance` over the given configurations and the
  workspace checkpoints (:func:`hyperstat.solver.tolerances.classification.workspace_checkpoints`).

Contribution (%): each tolerance's share of the first-order task-error variance at its
value (uniform distribution in ``+-value``), over the sample: the position error when the
task has position components, else the orientation error.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.tolerances.accuracy import AccuracyMaps, allocate, in_chunks
from hyperstat.solver.tolerances.classification import Classification, workspace_checkpoints
from hyperstat.solver.tolerances.declaration import n_rotation_rows, task_rows
from hyperstat.solver.tolerances.spilled import SpilledArray
from hyperstat.solver.tolerances.task_summary import TaskAccumulator, TaskSummary, value_columns
from hyperstat.solver.tolerances.twist_blocks import nominal_twist_maps
from hyperstat.solver.tolerances.worst_case import TASK_COEFFICIENTS, TaskCoefficients, search_extremes
from hyperstat.solver.threads import limited_blas

__all__ = ["assign_values", "task_maps", "task_summary", "monte_carlo_at_values", "ASSEMBLY_SAMPLE", "TASK_COEFFICIENTS"]

#: configurations of the stationarity sample on which the assemblability programme runs (report, accuracy)
ASSEMBLY_SAMPLE = 8
#: configurations per block of :func:`task_maps` (their full Jacobians: the bounds' search over a 100,000-
#: configuration sample peaked at 220 MiB of arrays with blocks of 10,000); the same rows whatever the block: blocks of
#: 256 keep a block's defect Jacobians near the cache (the hexapod's 36 x 234 per configuration: 17 MiB, not 138 MiB),
#: the hexapod's `accuracy` 0.8-1.0 s of CPU less than with 2,048 (issue 39)
TASK_BLOCK = 256

def task_maps(mechanism: Mechanism, kin: Kinematics, configurations: np.ndarray, task: tuple,
              directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Task rotation rows (rad) and position rows (mm) per unit of each direction, (K, r, n).

    Evaluated in blocks of :data:`TASK_BLOCK` configurations on threads (:func:`in_chunks`, as the accuracy
    maps): memory bounded by the blocks, the same rows bit for bit whatever the block.
    """
    q = np.atleast_2d(np.asarray(configurations, dtype=float))
    n_rot = n_rotation_rows(task)
    rows = task_rows(task, np.eye(4)[None]).shape[1]  # as many task rows at every pose
    out = np.zeros((len(q), rows, directions.shape[1]))

    def block(start: int) -> None:
        sl = slice(start, start + TASK_BLOCK)
        k_xi, _, pose = nominal_twist_maps(kin, q[sl])  # the task summary's blocks, read again (the same bits)
        out[sl] = task_rows(task, pose) @ k_xi @ directions

    in_chunks(block, len(q), TASK_BLOCK)
    return out[:, :n_rot], out[:, n_rot:]


def task_summary(mechanism: Mechanism, kin: Kinematics, configurations: np.ndarray, task: tuple,
                 directions: np.ndarray, is_length: np.ndarray, column_sets: list) -> TaskSummary:
    """What the values need of the task rows at ``configurations`` (:class:`TaskSummary`), block by block.

    The rows of :func:`task_maps`, in blocks of :data:`TASK_BLOCK` configurations on threads, reduced as
    they are computed: memory bounded by the blocks and the per-configuration coefficients.
    """
    q = np.atleast_2d(np.asarray(configurations, dtype=float))
    n_rot = n_rotation_rows(task)
    rows = task_rows(task, np.eye(4)[None]).shape[1]
    acc = TaskAccumulator(len(q), n_rot, rows - n_rot, is_length, column_sets)
    parts = {}

    def block(start: int) -> None:
        k_xi, _, pose = nominal_twist_maps(kin, q[start:start + TASK_BLOCK])  # kept for the bounds' search
        parts[start] = acc.add(start, task_rows(task, pose) @ k_xi @ directions)

    in_chunks(block, len(q), TASK_BLOCK)
    return acc.finish(parts)


def _summary_of_rows(rot: np.ndarray, pos: np.ndarray, is_length: np.ndarray, column_sets: list) -> TaskSummary:
    """The :class:`TaskSummary` of whole task rows (the ``(rot, pos)`` form of ``task_maps_at``)."""
    acc = TaskAccumulator(rot.shape[0], rot.shape[1], pos.shape[1], is_length, column_sets)
    return acc.finish({0: acc.add(0, np.concatenate([rot, pos], axis=1))})


def _coefficients(summary: TaskSummary, cols: np.ndarray, names: list, q: np.ndarray) -> AccuracyMaps:
    """Task-restricted coefficients (eq. 18 on the task rows) at the sampled configurations, as AccuracyMaps."""
    coeffs = dict(summary.of(cols))
    is_len = summary.is_length[cols]
    # the actuators' coefficients are zero here; in a (sparse) temporary file when the others are (issue 39: calloc'd
    # zeros on a reused heap are written, 8 x 5.5 MiB at 685,000 configurations)
    spilled = any(isinstance(v, SpilledArray) for v in coeffs.values())
    for kind in ("fP", "fR"):
        for name in (f"delta_{kind}", f"epsilon_{kind}"):
            coeffs[name] = SpilledArray(summary.configurations) if spilled else np.zeros(summary.configurations)
    groups = {"fP": [], "fR": [], "gP": [n for n, b in zip(names, is_len) if b],
              "gR": [n for n, b in zip(names, is_len) if not b]}
    return AccuracyMaps(coeffs, {}, groups, q if isinstance(q, SpilledArray) else np.atleast_2d(q), np.zeros((0, 3)))


def _allocate(maps: AccuracyMaps, position: float | None, orientation: float | None,
              extremes: dict | None = None) -> dict:
    """Equal allocation (paper 2, eqs. 30-31) through :func:`hyperstat.solver.tolerances.accuracy.allocate`.

    With ``extremes``, each coefficient's maximum is the refined one plus its stated
    tolerance (an upper bound when the tolerance estimate holds); the sampled maximum
    otherwise.
    """
    maxima = {}
    for name, e in (extremes or {}).items():
        maxima[name] = e.value + (e.tolerance if math.isfinite(e.tolerance) else 0.0)
    out = allocate(maps, orientation, position, maxima=maxima)
    if extremes:
        out["worst_cases"] = {name: {"max": e.value, "sampled_max": e.sampled, "optimiser_tolerance": e.tolerance,
                                     "location": e.location, "where": e.where(),
                                     "supremum_on_boundary": bool(getattr(e, "supremum", False)),
                                     "actuated": dict(e.actuated), "agreeing_starts": e.agreeing, "starts": e.starts,
                                     "evidence": e.evidence, "configuration": e.q.tolist()}
                              for name, e in extremes.items()}
    return out


@limited_blas
def assign_values(cl: Classification, mechanism: Mechanism, kin: Kinematics, configurations: np.ndarray,
                  position_accuracy: float | None = None, orientation_accuracy: float | None = None,
                  assembly: bool = True, assembly_configurations: np.ndarray | None = None, refine: bool = True,
                  workspace=None, task_maps_at: tuple | None = None, calibrate: bool = True,
                  background: bool = False, memo: Callable | None = None) -> Classification:
    """Fill ``value``, ``value_source`` and ``contribution`` of every tolerance of ``cl`` (in place).

    Parameters
    ----------
    configurations : ndarray, (K, n_q)
        Workspace sample: the allocation's worst cases start from it, and the assemblability
        check runs on it.
    position_accuracy, orientation_accuracy : float, optional
        Spec overriding the declaration's (mm, rad).
    assembly : bool
        Compute the assembly conditions' values from the clearances.
    assembly_configurations : ndarray, optional
        Configurations checked for assemblability besides the fixed workspace checkpoints
        (:func:`hyperstat.solver.tolerances.classification.workspace_checkpoints`: a sample of
        the declared workspace and the corners of its actuated box): e.g. the analysis'
        configurations, whose own worst case is reported beside the value.
    refine : bool
        Search the worst cases of the task-restricted coefficients
        (:func:`hyperstat.solver.tolerances.worst_case.search_extremes`); ``False``: the sampled
        maxima (loose: a sampled maximum is low).
    workspace : Workspace, optional
        Bounds of the refinement (default: the mechanism's declared workspace).
    task_maps_at : tuple of ndarray or TaskSummary, optional
        :func:`task_maps` at ``configurations`` for the accuracy-critical and compensable
        tolerances in the order of ``cl.items``, or their reductions (:func:`task_summary`), when
        already computed from the same Jacobians (``accuracy_maps(task=..., task_directions=...,
        task_columns=...)``, as ``hyperstat accuracy`` does).  Without it the rows are computed
        and reduced block by block (:func:`task_summary`).
    calibrate : bool
        Also the compensable tolerances' values with calibration
        (:func:`hyperstat.solver.tolerances.calibrated.calibrated_values`, simulated), and the share of the
        calibrated budget kept for their second-order residual.
    background : bool
        Compute the values with calibration in a forked child (:class:`hyperstat.solver.forked.Forked`) while
        the assembly conditions and the bounds are searched here: the same values, on the second core (the
        report's wall clock; not the CPU).
    memo : callable, optional
        ``memo(stage, inputs, compute)``: ``compute()``, or the value an earlier command stored for the same
        ``stage`` and ``inputs`` (:func:`hyperstat.solver.cli.cached.stage_memo`, the cache of results).  Given to
        the stages that do not depend on ``configurations`` (the assembly conditions' values and the whole
        drawing's: they start from ``assembly_configurations`` and the workspace's fixed checkpoints), so that
        ``accuracy``, ``report`` and ``montecarlo`` of one model compute them once whatever their samples.
    """
    return _assign_values(cl, mechanism, kin, configurations, position_accuracy, orientation_accuracy, assembly,
                          assembly_configurations, refine, workspace, calibrate, task_maps_at, background, memo)


def _with_calibration(cl, mechanism, kin, q, spec_p, spec_o, workspace, reserve) -> dict:
    """The values with calibration (in place) and their evidence; returned with every tolerance's two fields (what a
    forked child hands back)."""
    from hyperstat.solver.tolerances.calibrated import calibrated_values

    # on the fixed workspace checkpoints (the same whatever the command's sample: one value per tolerance in
    # report, accuracy and montecarlo)
    q_fixed = workspace_checkpoints(mechanism, kin, workspace)[0]
    q_fixed = q_fixed if len(q_fixed) else np.asarray(q)
    evidence = calibrated_values(cl, mechanism, kin, q_fixed, spec_p, spec_o, workspace, share=reserve)
    if evidence:
        from hyperstat.solver.tolerances.calibrated_together import loss_together

        evidence["together"] = loss_together(cl, mechanism, kin, q_fixed, workspace)
    return {"evidence": evidence,
            "items": [[t.value_with_calibration, t.value_with_calibration_limit] for t in cl.items]}


def _assign_values(cl, mechanism, kin, configurations, position_accuracy, orientation_accuracy, assembly,
                   assembly_configurations, refine, workspace, calibrate, task_maps_at=None,
                   background: bool = False, memo: Callable | None = None) -> Classification:
    """Body of :func:`assign_values` (BLAS single-threaded by the caller)."""
    decl = cl.declaration
    spec_p = position_accuracy if position_accuracy is not None else decl.position_mm
    spec_o = orientation_accuracy if orientation_accuracy is not None else decl.orientation_rad
    q = configurations if isinstance(configurations, SpilledArray) else np.atleast_2d(configurations)
    influential = [t for t in cl.items if t.cls in ("accuracy-critical", "compensable")]
    calibrating = None  # the values with calibration computed in a forked child (``background``)
    info = {"spec": {"position_mm": spec_p, "orientation_rad": spec_o}, "configurations": int(len(q)),
            "method": "equal allocation, paper 2 eqs. (19), (30)-(31), on the worst case of each task-restricted "
                      "coefficient over the declared workspace: " + (
                          f"searched from {len(q)} sampled configurations and the corners, edges, faces and dead "
                          "centres of the actuated box by a projected-gradient search on the configuration manifold "
                          "within the workspace bounds (hyperstat.solver.tolerances.worst_case), plus the search's "
                          "stated tolerance" if refine else
                          f"the maximum over {len(q)} sampled configurations (not refined: may be low, which makes "
                          "the values loose)")}
    if influential:
        dirs = np.stack([t.direction for t in influential], axis=1)
        is_len, column_sets = value_columns(influential)
        if task_maps_at is None:
            summary = task_summary(mechanism, kin, q, decl.task, dirs, is_len, column_sets)
        elif isinstance(task_maps_at, TaskSummary):
            summary = task_maps_at
        else:
            rot, pos = task_maps_at
            if rot.shape[0] != len(q) or rot.shape[2] != len(influential):
                raise ValueError(f"task_maps_at: {rot.shape[2]} directions at {rot.shape[0]} configurations, "
                                 f"expected {len(influential)} at {len(q)}.")
            summary = _summary_of_rows(rot, pos, is_len, column_sets)
        if summary.configurations != len(q) or summary.directions != len(influential) or \
                not np.array_equal(summary.is_length, is_len):
            raise ValueError(f"task_maps_at: {summary.directions} directions at {summary.configurations} "
                             f"configurations, expected {len(influential)} at {len(q)}.")
        names = [t.parameters[0] for t in influential]
        has_r, has_p = summary.n_rot > 0, summary.n_pos > 0
        cal = cl.calibration
        left_p = None if spec_p is None else spec_p - cal.get("position_mm", 0.0)
        left_o = None if spec_o is None else spec_o - cal.get("orientation_rad", 0.0)
        if (left_p is not None and left_p <= 0) or (left_o is not None and left_o <= 0):
            cl.warnings.append("the calibration noise alone uses up the spec: no accuracy-critical tolerance fits.")
        crit = np.array([t.cls == "accuracy-critical" for t in influential])
        comp = np.array([t.cls == "compensable" for t in influential])
        # the calibrated machine: the compensable defects leave a second-order residual after calibration, which
        # shares the budget equally with the accuracy-critical classes (paper 2, eq. 30: one share per class)
        reserve = {}
        if calibrate and comp.any():
            for key, left, n_rows, moves in (("position_mm", left_p, summary.n_pos, summary.moves_position),
                                             ("orientation_rad", left_o, summary.n_rot, summary.moves_rotation)):
                if left is None or left <= 0 or not n_rows:
                    continue
                classes = sum(1 for kind in (True, False) if np.any(crit & (is_len == kind)) and
                              np.any(moves[crit & (is_len == kind)]))
                reserve[key] = left / (classes + 1)
            if crit.any():
                left_p = None if left_p is None else left_p - reserve.get("position_mm", 0.0)
                left_o = None if left_o is None else left_o - reserve.get("orientation_rad", 0.0)
            info["second_order_share"] = dict(reserve)

        def allocation(cols: np.ndarray, p_budget, o_budget) -> dict:
            maps = _coefficients(summary, cols, [n for n, c in zip(names, cols) if c], q)
            ext = {}
            if refine:
                objective = TaskCoefficients(kin, decl.task, dirs[:, cols], is_len[cols])
                ext = {n: e for (n, _), e in search_extremes(kin, objective, q, workspace, starts=2,
                                                             sampled=maps.coefficients).items()}
            return _allocate(maps, p_budget if has_p else None, o_budget if has_r else None, ext)

        uncalibrated = allocation(np.ones(len(influential), dtype=bool), spec_p, spec_o)
        if calibrate and background:
            # the values with calibration read the compensable tolerances' values (the uncalibrated allocation's)
            # and nothing of the calibrated allocation: started now, beside that allocation's search (issue 39)
            for t, length in zip(influential, is_len):
                if t.cls == "compensable":
                    t.value = uncalibrated["classes"].get("gP" if length else "gR", {}).get("tolerance")
            from hyperstat.solver.forked import Forked

            calibrating = Forked(_with_calibration, cl, mechanism, kin, q, spec_p, spec_o, workspace, reserve)
        try:
            calibrated = allocation(crit, left_p if left_p is None or left_p > 0 else 0.0,
                                    left_o if left_o is None or left_o > 0 else 0.0) if crit.any() else None
        except BaseException:
            if calibrating is not None:
                calibrating.cancel()
            raise
        info["calibrated"] = calibrated
        info["uncalibrated"] = uncalibrated
        for t, length in zip(influential, is_len):
            kind = "gP" if length else "gR"
            src = calibrated if t.cls == "accuracy-critical" else uncalibrated
            v = src["classes"].get(kind, {}).get("tolerance") if src else None
            t.value = v
            worst = ""
            if src and src.get("worst_cases"):
                key = "calibrated" if t.cls == "accuracy-critical" else "uncalibrated"
                moved = [f"{n} max {w['max']:.6g} (sampled {w['sampled_max']:.6g})"
                         for n, w in src["worst_cases"].items() if w["location"] != "constant"]
                if moved:
                    worst = "; " + ", ".join(moved) + f" (where: allocation.{key}.worst_cases)"
            if t.cls == "accuracy-critical":
                t.value_source = ("equal allocation against the spec less the calibration residual, worst case "
                                  f"over the declared workspace (paper 2, eqs. 30-31){worst}")
            else:
                t.value_source = ("equal allocation against the spec without calibration (paper 2, eqs. 30-31), "
                                  f"worst case over the declared workspace; calibration lets it open{worst}")
        for key, a in (("calibrated", calibrated), ("uncalibrated", uncalibrated)):
            for name, w in ((a or {}).get("worst_cases") or {}).items():
                tol_w = w["optimiser_tolerance"]
                if "iteration limit" in w["evidence"] and not (math.isfinite(tol_w) and tol_w <= 1e-3 * abs(w["max"])):
                    cl.warnings.append(f"the worst case of {name} ({key} allocation) was still rising when the ascent "
                                       f"stopped ({w['max']:.4g}, last gain {tol_w:.2g}): the values divided by it may "
                                       "be loose (the unsafe direction); the declared workspace may reach a singularity.")
                if "singular edge" in w["evidence"]:
                    cl.warnings.append(f"the worst case of {name} ({key} allocation) lies at the singular edge of the "
                                       "declared workspace, where it grows without bound: the values hold where the "
                                       "passive Jacobian's conditioning is at least 1e-2 of its median over the sample "
                                       "(declare a workspace away from the singularity to relax them).")
        # the verdicts again with the worst-case configurations added (compensable means cancellable at every
        # configuration of the workspace, and the worst cases are where the coefficients peak)
        extra = [np.asarray(w["configuration"]) for a in (calibrated, uncalibrated) if a
                 for w in a.get("worst_cases", {}).values() if w["location"] != "constant"]
        if extra and cl.analysis is not None and cl.configurations is not None:
            from hyperstat.solver.tolerances.classification import classify

            # identification from the analysis configurations (as analyze did before the workspace checks), the
            # residual test at them and at the worst cases
            again = classify(mechanism, cl.analysis, kin, decl,
                             configurations=np.vstack([cl.analysis.configurations] + extra))
            changed = [f"{t.id} ({t.cls} -> {u.cls})" for t, u in zip(cl.items, again.items) if t.cls != u.cls]
            cl.checked["worst_cases"] = len(extra)
            cl.checked["worst_case_margin"] = again.checked.get("margin")
            cl.checked["worst_cases_agree"] = not changed
            if changed:
                cl.warnings.append("at the accuracy worst cases the verdict changes for " + ", ".join(changed) +
                                   ": the class shown holds at the sampled configurations only.")
        # contributions: first-order variance at the values (uniform: t^2 / 3)
        vals = np.array([t.value or 0.0 for t in influential])
        var = summary.mean_squares() * vals**2 / 3.0
        total = float(var.sum())
        for t, v in zip(influential, var):
            t.contribution = 100.0 * float(v) / total if total > 0 else 0.0
        info["contribution_of"] = "position" if summary.n_pos else "orientation"
    for t in cl.items:
        if t.cls == "non-influent":
            t.value = None
            t.value_source = "not limited by accuracy (moves nothing the task uses)"
    # the values with calibration depend on the allocation only: computed beside the assembly conditions and the
    # bounds when asked (the same function of the same state: the same values)
    if calibrate and influential and background and calibrating is None:
        from hyperstat.solver.forked import Forked

        calibrating = Forked(_with_calibration, cl, mechanism, kin, q, spec_p, spec_o, workspace, reserve)
    bounding = None
    try:
        qa = _assembly_values(cl, mechanism, kin, q, assembly, assembly_configurations, workspace, info, memo)
        if influential:
            # the bounds read the allocations only, and nothing after them reads the bounds: by a child beside the
            # values with calibration and the drawing when a core is idle (the same values; issue 39)
            from hyperstat.solver.forked import when_idle

            bounding = when_idle(_bounds, cl, influential, mechanism, kin, q, workspace, info, dirs, is_len, spec_p,
                                 spec_o)
        if calibrate and influential:
            done = calibrating.result() if calibrating is not None else \
                _with_calibration(cl, mechanism, kin, q, spec_p, spec_o, workspace, reserve)
            for t, (value, limit) in zip(cl.items, done["items"]):
                t.value_with_calibration, t.value_with_calibration_limit = value, limit
            info["with_calibration"] = done["evidence"]
        info.update(_drawing_values(cl, mechanism, kin, qa, workspace, memo))
    except BaseException:
        for job in (calibrating, bounding):
            if job is not None:
                job.cancel()
        raise
    if bounding is not None:
        _apply_bounds(bounding.result(), influential, info)
    cl.allocation = info
    return cl


def _memoised(memo: Callable | None, stage: str, inputs: Callable[[], Any], compute: Callable[[], Any]) -> Any:
    """``compute()`` through ``memo`` (:func:`assign_values`) under ``inputs()``; computed when there is no memo or
    the inputs cannot be written as a key (an object the cache does not encode)."""
    if memo is None:
        return compute()
    try:
        key_inputs = inputs()
    except (TypeError, ValueError):
        return compute()
    return memo(stage, key_inputs, compute)


def _state(t) -> dict:
    """A tolerance's attributes (the inputs of a memoised stage; its changes are its outputs)."""
    return dict(vars(t))


def _assembly_values(cl, mechanism, kin, q, assembly, assembly_configurations, workspace, info, memo=None):
    """The assembly conditions' values (in place); the assembly configurations."""
    decl = cl.declaration
    qa = None
    if assembly:
        from hyperstat.solver.tolerances.clearance import assembly_tolerances

        items = cl.by_class("assembly")
        if items:
            # the search starts from the same configurations whatever the command: the given ones (the
            # reference set), a fixed sample of the declared workspace and the corners of its actuated box
            ref = None if assembly_configurations is None else np.atleast_2d(assembly_configurations)
            ws_part, corners = workspace_checkpoints(mechanism, kin, workspace)
            parts = ([ref] if ref is not None else []) + [p for p in (ws_part, corners) if len(p)]
            qa = np.vstack(parts) if parts else q
            vals = _memoised(memo, "assembly-values",
                             lambda: (vars(decl), [_state(t) for t in items], qa, None if ref is None else len(ref),
                                      None if workspace is None else vars(workspace)),
                             lambda: assembly_tolerances(mechanism, items, decl, qa,
                                                         reference=None if ref is None else len(ref),
                                                         workspace=workspace))
            n_ref = 0 if ref is None else len(ref)
            info["assembly_configurations"] = {"total": int(len(qa)), "analysis": n_ref, "workspace": int(len(ws_part)),
                                               "box_corners": int(len(corners))}
            for t in items:
                v = vals[t.id]
                t.value = v["value"]
                t.evidence["assemblability"] = {k: v.get(k) for k in (
                    "limiting", "at_bound", "configurations", "reference_value", "sampled_value", "searched",
                    "search_tolerance", "where", "start", "location", "evidence")}
                wq = v.get("worst_q")
                if wq is not None:
                    t.evidence["assemblability"]["worst_actuated"] = {
                        mechanism.joints[i].name: float(wq[i]) for i in mechanism.actuated}
                    t.evidence["assemblability"]["worst_configuration"] = wq.tolist()
                    t.evidence["assemblability"]["worst_in"] = v.get("start")
                if v["value"] is None:
                    t.value_source = "the clearances absorb any small violation (no limit to first order)"
                    continue
                t.value_source = (f"largest violation the joint clearances absorb at every configuration of the declared "
                                  f"workspace (worst-case assemblability, linear programme), searched from {len(qa)} "
                                  f"configurations ({n_ref} of the analysis, {len(ws_part)} sampled, {len(corners)} "
                                  "corners of the actuated box) and the box's edges, faces and dead centres; worst "
                                  f"{v.get('location') or 'at a configuration'}, from a {v.get('start')} start")
                rv, sv = v.get("reference_value"), v.get("sampled_value")
                if sv is not None and sv > v["value"] * (1 + 1e-9):
                    t.value_source += f"; the starting configurations alone give {sv:.4g} {t.unit} " \
                                      f"({100 * (sv / v['value'] - 1):.2f} % looser)"
                if rv is not None and n_ref and rv > v["value"] * (1 + 1e-9):
                    t.value_source += (f"; the analysis configurations alone give {rv:.4g} {t.unit} "
                                       f"({100 * (rv / v['value'] - 1):.0f} % looser)")
    return qa


def _bounds(cl, influential, mechanism, kin, q, workspace, info, dirs, is_len, spec_p, spec_o) -> list:
    """The attainable linear worst case and the triangle bound of each allocation, searched over the workspace:
    ``[(allocation key, its bounds, which of influential it holds)]`` (JSON-ready; :func:`_apply_bounds` puts them
    in ``info`` and on the tolerances).  Reads ``info`` and ``cl``, changes neither: a forked child may compute it
    (:func:`hyperstat.solver.forked.when_idle`)."""
    from hyperstat.solver.tolerances.bounds import LinearWorstCase

    decl = cl.declaration
    n_rot = n_rotation_rows(decl.task)
    out = []
    for key, members in (("uncalibrated", [True] * len(influential)),
                         ("calibrated", [t.cls == "accuracy-critical" for t in influential])):
        if not info.get(key):
            continue
        # every tolerance of the allocation at that allocation's value (an accuracy-critical one carries its
        # calibrated value; without calibration it is held to the uncalibrated one)
        per_kind = {k: c.get("tolerance") for k, c in info[key]["classes"].items()}
        values = np.array([per_kind.get("gP" if length else "gR") or 0.0 for length in is_len])
        cols = np.array(members, dtype=bool) & (values > 0)
        if not cols.any():
            continue
        values = values[cols]

        def rows(qq: np.ndarray, cols=cols) -> np.ndarray:
            rot, pos = task_maps(mechanism, kin, qq, decl.task, dirs[:, cols])
            return pos if pos.shape[1] else rot

        objective = LinearWorstCase(rows, values)
        found = search_extremes(kin, objective, q, workspace, starts=1, structured=1)
        unit = "mm" if task_rows(decl.task, np.eye(4)[None]).shape[1] > n_rot else "rad"
        spec = spec_p if unit == "mm" else spec_o
        att, tri = found.get(("attainable", "max")), found.get(("triangle", "max"))
        bounds = {"attainable_linear_worst_case": None if att is None else att.value,
                  "triangle_bound": None if tri is None else tri.value, "unit": unit, "spec": spec,
                  "attainable_where": None if att is None else att.where(),
                  "meaning": "attainable: the largest first-order task error of a machine with every tolerance "
                             "within its value (the worst sign pattern at the worst configuration found); triangle: "
                             "every tolerance at its extreme with every effect adding up (a bound no machine need "
                             "reach)"}
        out.append((key, bounds, [bool(c) for c in cols]))
    return out


def _apply_bounds(found: list, influential: list, info: dict) -> None:
    """The bounds of :func:`_bounds` in ``info`` (per allocation) and on the tolerances of each allocation whose
    value they are (an accuracy-critical tolerance carries the calibrated one, the others the uncalibrated)."""
    for key, bounds, cols in found:
        info[key]["bounds"] = bounds
        for t, c in zip(influential, cols):
            if c and (key == "calibrated") == (t.cls == "accuracy-critical"):
                t.bounds = {k: bounds[k] for k in ("attainable_linear_worst_case", "triangle_bound", "unit")}


def _drawing_values(cl, mechanism, kin=None, assembly_q=None, workspace=None, memo=None) -> dict:
    """The assembly values together (the drawing read as a whole), the values a drawing carries (rounded to the safe
    side) and the part drawings (:mod:`hyperstat.solver.tolerances.drawing`); returns the whole drawing's evidence."""
    from hyperstat.solver.tolerances.drawing import add_drawing, safe_round

    out = {}
    if assembly_q is not None and kin is not None:
        from hyperstat.solver.tolerances.whole_drawing import allocate_together

        # a function of the assembly conditions (their state after their values), the declaration, the
        # configurations and the workspace only: what it changes on them is kept with its evidence
        conditions = [t for t in cl.items if t.cls == "assembly"]

        def together() -> dict:
            evidence = allocate_together(cl, mechanism, kin, assembly_q, workspace)
            return {"evidence": evidence, "conditions": [_state(t) for t in conditions]}

        done = _memoised(memo, "whole-drawing",
                         lambda: (vars(cl.declaration), [_state(t) for t in conditions], assembly_q,
                                  None if workspace is None else vars(workspace)), together)
        for t, state in zip(conditions, done["conditions"]):
            for name, value in state.items():
                setattr(t, name, value)
        out["whole_drawing"] = done["evidence"]
    calibrated = "measurements" in cl.declaration.declared
    for t in cl.items:
        v = t.value_with_calibration if calibrated and t.cls == "compensable" and \
            t.value_with_calibration is not None else t.value
        t.drawing_value = safe_round(v)
    add_drawing(cl, mechanism, kin)
    if out.get("whole_drawing"):
        from hyperstat.solver.tolerances.whole_drawing import confirm_corner

        out["whole_drawing"]["nonlinear"] = confirm_corner(cl, mechanism, out["whole_drawing"])
    return out


def monte_carlo_at_values(cl: Classification, mechanism: Mechanism, kin: Kinematics, configurations: np.ndarray,
                          samples: int = 10000, seed: int = 0, distribution: str = "uniform",
                          position_accuracy: float | None = None, orientation_accuracy: float | None = None) -> dict:
    """Monte Carlo through the nonlinear model with every accuracy tolerance at its value (JSON-ready).

    Every accuracy-critical and compensable tolerance is drawn within ``+-value`` along its
    direction (uniform, or normal with sigma = value / 3), the mechanism re-assembled at a
    workspace configuration and the task error measured
    (:func:`hyperstat.solver.tolerances.montecarlo.monte_carlo` with the declared task).  Two
    machines: as built (every tolerance drawn) and calibrated (the compensable ones cancelled,
    so only the accuracy-critical ones remain; the calibration noise of
    :attr:`Classification.calibration` is added to the spec check as a worst case).
    Assembly conditions are not drawn: violating one deforms the structure, which a rigid
    model does not describe.

    Returns
    -------
    dict
        ``samples``, statistics of the task errors (mm, rad), ``out_of_spec_*_percent`` for both
        machines, ``linear_worst_case`` (the triangle bound over the sample, every tolerance at its
        extreme and every effect adding up, mm / rad), ``attainable_linear_worst_case`` (the worst
        sign pattern), and ``contributors`` by tolerance id, sorted
        by position share.
    """
    from hyperstat.solver.tolerances.montecarlo import monte_carlo

    decl = cl.declaration
    spec_p = position_accuracy if position_accuracy is not None else decl.position_mm
    spec_o = orientation_accuracy if orientation_accuracy is not None else decl.orientation_rad
    drawn = [t for t in cl.items if t.cls in ("accuracy-critical", "compensable") and t.value]
    if not drawn:
        return {}
    names = [t.id for t in drawn]
    matrix = np.stack([t.direction for t in drawn], axis=1)
    units = [t.unit for t in drawn]
    # parts made to the drawing: each tolerance within its drawing value (with calibration where the template declares
    # its measurements), the value report and accuracy print
    tol = {t.id: float(t.drawing_value if t.drawing_value else t.value) for t in drawn}
    res = monte_carlo(mechanism, configurations, tol, samples, distribution, seed, kinematics=kin,
                      directions=(names, matrix, units), task=decl.task)
    out = res.summary(spec_o, spec_p)
    label = {t.id: f"{t.id} {t.statement}" for t in drawn}
    for c in out["contributors"]:
        c["label"] = label.get(c["parameter"], c["parameter"])
    out["contributors"].sort(key=lambda c: -c["position_share"])
    from hyperstat.solver.tolerances.bounds import attainable, triangle

    rot, pos = task_maps(mechanism, kin, configurations, decl.task, matrix)
    vals = np.array([tol[n] for n in names])
    # named for what they are (over the Monte Carlo's configurations): the triangle bound (every tolerance at
    # its extreme and every effect adding up, which no machine need reach) and the attainable worst case
    out["linear_worst_case"] = {
        "position_mm": float(np.max(triangle(pos * vals))) if pos.shape[1] else None,
        "orientation_rad": float(np.max(triangle(rot * vals))) if rot.shape[1] else None,
        "meaning": "triangle bound: every tolerance at its extreme with every effect adding up"}
    out["attainable_linear_worst_case"] = {
        "position_mm": float(np.max(attainable(pos * vals))) if pos.shape[1] else None,
        "orientation_rad": float(np.max(attainable(rot * vals))) if rot.shape[1] else None,
        "meaning": "the worst sign pattern of the tolerances at their values, at the worst configuration sampled"}
    crit = [t for t in drawn if t.cls == "accuracy-critical"]
    calibrated = {}
    declared = "measurements" in decl.declared and any(t.cls == "compensable" for t in drawn)
    if declared:  # the machines calibrated as declared, by simulation (montecarlo_drawing)
        from hyperstat.solver.tolerances.montecarlo_drawing import calibrated_machines

        calibrated = calibrated_machines(cl, mechanism, kin, configurations, drawn, tol, seed=seed + 1,
                                         distribution=distribution, spec_p=spec_p, spec_o=spec_o)
    elif crit:
        cn = [t.id for t in crit]
        res_c = monte_carlo(mechanism, configurations, {t.id: float(t.value) for t in crit}, samples, distribution,
                            seed + 1, kinematics=kin, directions=(cn, np.stack([t.direction for t in crit], axis=1),
                                                                  [t.unit for t in crit]), task=decl.task)
        ok = res_c.converged
        cal = cl.calibration
        if spec_p is not None:
            calibrated["out_of_spec_position_percent"] = float(
                100 * np.mean(res_c.position[ok] + cal.get("position_mm", 0.0) > spec_p))
        if spec_o is not None:
            calibrated["out_of_spec_orientation_percent"] = float(
                100 * np.mean(res_c.orientation[ok] + cal.get("orientation_rad", 0.0) > spec_o))
        calibrated["position_max_mm"] = float(res_c.position[ok].max())
        calibrated["orientation_max_rad"] = float(res_c.orientation[ok].max())
    else:
        calibrated = {"out_of_spec_position_percent": 0.0 if spec_p is not None else None,
                      "out_of_spec_orientation_percent": 0.0 if spec_o is not None else None,
                      "note": "no accuracy-critical tolerance: calibration leaves only its noise"}
    if not declared and calibrated:
        calibrated["note"] = ("no calibration declared: the compensable tolerances are drawn at their values without "
                              "calibration; this rate assumes a calibration that cancels them exactly (first order)")
    out["calibrated"] = calibrated
    out["drawn_values"] = {t.id: tol[t.id] for t in drawn}
    out["drawn"] = ("parts made to the drawing: every accuracy-critical and compensable tolerance within its drawing "
                    "value" + (" (compensable ones with calibration: the machine is calibrated as declared)"
                               if declared else ""))
    out["spec"] = {"position_mm": spec_p, "orientation_rad": spec_o}
    out["task"] = list(decl.task)
    return out
