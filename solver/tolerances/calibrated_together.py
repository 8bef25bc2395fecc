"""The values with calibration together: the workspace they cost all at once, not each alone.

Units: mm and rad.

A compensable tolerance's value with calibration (:mod:`hyperstat.solver.tolerances.calibrated`) is limited,
among others, by what its compensation costs: the controller moves the actuators by ``(S K_a)^+ S K d`` per unit
defect, and where the joint ranges leave no margin around the workspace, or at the task's dead centres (where no
actuator motion cancels a defect), the calibrated machine loses that much of its workspace; the loss is held to
the declared budget (``workspace_loss``, 0.1 % by default) of each actuator's range or of the task's extent.  That
limit is set per tolerance; a machine built to the drawing has every defect at once.  :func:`loss_together`
checks the budget with every value with calibration together, at the worst configuration and the worst signs:

* an actuator ``a``: ``max over q of sum_i |c_ai(q)| v_i`` (the correction per unit of each defect), against its
  room (the margin its range leaves, or the budget of its range);
* the task's dead centres: the largest uncancelled task effect of the combination, ``max over q and signs of
  || sum_i s_i v_i l_i(q) ||`` (:func:`hyperstat.solver.tolerances.bounds.attainable`), against the budget of
  the task's extent.

Where the values together exceed a budget, every value that costs it is scaled by the same factor until it
fits (never below its value without calibration), and the limit's words say so.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["loss_together"]


def loss_together(cl, mechanism, kin, configurations: np.ndarray, workspace=None) -> dict:
    """Check (and if needed scale) the values with calibration together (see the module docstring); in place.

    Returns
    -------
    dict
        JSON-ready: per budget (``actuator <name>``, ``task dead centres``) the loss of the values alone at their
        worst, the loss together, the budget, the unit and the factor applied.
    """
    from hyperstat.solver.tolerances.accuracy import output_twist_maps
    from hyperstat.solver.tolerances.bounds import attainable
    from hyperstat.solver.tolerances.calibrated import (TASK_POSES, _actuation, _task_extent, _task_scale,
                                                        actuator_room, regular_task)
    from hyperstat.solver.tolerances.declaration import n_rotation_rows, task_rows
    from hyperstat.solver.tolerances.workspace import workspace_of
    from hyperstat.solver.tolerances.worst_case import workspace_candidates

    items = [t for t in cl.items if t.cls == "compensable" and t.value_with_calibration is not None and t.value]
    if not items or "measurements" not in cl.declaration.declared:
        return {}
    m = mechanism
    decl = cl.declaration
    loss = float(decl.workspace_loss)
    v = np.array([float(t.value_with_calibration) for t in items])
    floor = np.array([float(t.value) for t in items])
    dirs = np.stack([t.direction for t in items])
    q_all = np.atleast_2d(configurations)
    q_all = q_all[np.unique(np.linspace(0, len(q_all) - 1, min(len(q_all), TASK_POSES)).round().astype(int))]
    regular = regular_task(kin, decl, q_all)
    q_task = q_all[regular]
    _, _, rev, has_margin, room = actuator_room(m, workspace or workspace_of(m), loss)
    budgets = []  # (name, coefficients function of the values -> loss, budget, unit, members)
    if len(q_task):
        st = kin.evaluate(q_task, None, jacobians=True)
        k_xi, k_a = output_twist_maps(kin, st)
        sel = task_rows(decl.task, st.output_pose)
        corr = np.abs(np.linalg.pinv(sel @ k_a, rcond=1e-8) @ (sel @ k_xi @ dirs.T))  # (K, n_a, n)
        for a, i in enumerate(m.actuated):
            if not math.isfinite(room[a]):
                continue
            c = corr[:, a, :]
            members = np.max(c, axis=0) > 0
            budgets.append((f"actuator {m.joints[i].name}", lambda vals, c=c: float(np.max(c @ vals)), float(room[a]),
                            "rad" if rev[a] else "mm", members,
                            "the margin its range leaves around the workspace" if has_margin[a] else
                            f"{100 * loss:g} % of its range"))
    # the task's dead centres: the uncancelled task effect of every defect at once
    cand, _ = workspace_candidates(kin, workspace_of(m), q_all)
    median = float(np.median(_actuation(kin, decl, q_all, defects=False)[4]))
    pool = np.vstack([q_all] + ([cand] if len(cand) else []))
    singular = ~regular_task(kin, decl, pool, reference=median)
    if singular.any():
        st, k_xi, k_a, sel, _ = _actuation(kin, decl, pool[singular])
        scale = _task_scale(decl, kin.length_scale)[None, :, None]
        effect = sel @ k_xi @ dirs.T  # (K, r, n)
        ta = (sel @ k_a) * scale * kin.joint_scale[m.actuated][None, None, :]
        u, sv, _ = np.linalg.svd(ta, full_matrices=True)
        seen = sv >= 1e-2 * median
        left = effect.copy()
        for k in range(len(left)):
            span = u[k][:, :int(seen[k].sum())]
            if span.size:
                left[k] = effect[k] - (span * (1 / scale[0])) @ (span.T @ (effect[k] * scale[0]))
        n_rot = n_rotation_rows(decl.task)
        rows = left[:, n_rot:, :] if left.shape[1] > n_rot else left
        unit = "mm" if left.shape[1] > n_rot else "rad"
        extent = _task_extent(kin, decl, q_all)
        members = np.max(np.linalg.norm(rows, axis=1), axis=0) > 0
        budgets.append(("the task's dead centres", lambda vals, rows=rows: float(np.max(attainable(rows * vals))),
                        loss * extent, unit, members, f"{100 * loss:g} % of the task's extent ({extent:.4g} {unit})"))
    out = {"workspace_loss": loss, "declared": "workspace_loss" in decl.declared, "budgets": []}
    factor = np.ones(len(items))
    for _ in range(30):  # scale until every budget holds (a value at its floor stays there); a value in several
        vals = np.maximum(v * factor, floor)  # budgets takes the smallest of their factors
        step = np.ones(len(items))
        for b in budgets:
            got = b[1](vals)
            if got <= b[2] * (1 + 1e-9):
                continue
            members = b[4] & (v * factor > floor)
            fixed = b[1](np.where(members, 0.0, vals))
            grow = b[1](np.where(members, vals, 0.0))
            f = max((b[2] - fixed) / grow, 0.0) if grow > 0 else 1.0
            step[members] = np.minimum(step[members], min(f, 1.0))
        if np.all(step >= 1.0 - 1e-12):
            break
        factor *= step
    vals = np.maximum(v * factor, floor)
    for b in budgets:
        alone = max(b[1](np.where(np.arange(len(v)) == i, v, 0.0)) for i in range(len(v)))
        out["budgets"].append({"budget": b[0], "limit": b[2], "unit": b[3], "what": b[5],
                               "largest_alone": alone, "together_before": b[1](v), "together": b[1](vals)})
    changed = []
    for t, f, new in zip(items, factor, vals):
        if new < float(t.value_with_calibration) * (1 - 1e-12):
            hit = [b[0] for b in budgets if b[4][items.index(t)] and b[1](v) > b[2] * (1 + 1e-9)]
            t.value_with_calibration_limit = (
                f"workspace loss together: with every compensable defect at its value with calibration at once, "
                f"compensating them costs more than the budget of {', '.join(hit)}; every value that costs it is "
                f"scaled by {f:.3g} (alone: {float(t.value_with_calibration):.4g} {t.unit}, "
                f"{t.value_with_calibration_limit})")
            t.value_with_calibration = float(new)
            changed.append(t.id)
    out["scaled"] = changed
    out["unsatisfiable"] = [b[0] for b in budgets if b[1](vals) > b[2] * (1 + 1e-6)]
    return out
