"""Values of the tolerances: allocation against the spec, clearances for assembly conditions.

Units: mm and rad.

* **accuracy-critical**: equal allocation of paper 2 (eqs. 19 and 30-31) against the spec
  over the workspace: the task-error coefficients of the accuracy-critical directions,
  split by kind (``gP``: lengths, ``gR``: angles), are the largest singular values of their
  task rows (``epsilon`` for position, ``delta`` for orientation, eq. 18) at their worst
  configuration of the given sample, and the budget is the spec less what calibration
  noise leaves (:attr:`Classification.calibration`);
* **compensable**: the same allocation over every influential direction (accuracy-critical
  and compensable) without calibration: the value that keeps the spec on an
  uncalibrated machine; calibration lets it open;
* **non-influent**: no value from accuracy (any value the assembly conditions allow);
* **assembly**: the clearance-based worst-case assemblability of
  :mod:`hyperstat.solver.tolerances.clearance`.

Contribution (%): each tolerance's share of the first-order task-error variance at its
value (uniform distribution in ``+-value``), over the sample: the position error when the
task has position components, else the orientation error.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.tolerances.accuracy import AccuracyMaps, allocate, output_twist_maps
from hyperstat.solver.tolerances.classification import Classification
from hyperstat.solver.tolerances.declaration import n_rotation_rows, task_rows

__all__ = ["assign_values", "task_maps", "monte_carlo_at_values", "ASSEMBLY_SAMPLE"]

#: configurations of the stationarity sample on which the assemblability programme runs (report, accuracy)
ASSEMBLY_SAMPLE = 8


def task_maps(mechanism: Mechanism, kin: Kinematics, configurations: np.ndarray, task: tuple,
              directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Task rotation rows (rad) and position rows (mm) per unit of each direction, (K, r, n)."""
    st = kin.evaluate(configurations, None, jacobians=True)
    k_xi, _ = output_twist_maps(kin, st)
    sel = task_rows(task, st.output_pose)
    n_rot = n_rotation_rows(task)
    t = sel @ k_xi @ directions
    return t[:, :n_rot], t[:, n_rot:]


def _sigma_max(block: np.ndarray) -> np.ndarray:
    if block.shape[1] == 0 or block.shape[2] == 0:
        return np.zeros(block.shape[0])
    return np.linalg.svd(block, compute_uv=False)[:, 0]


def _allocate(rot: np.ndarray, pos: np.ndarray, is_len: np.ndarray, names: list, position: float | None,
              orientation: float | None) -> dict:
    """Equal allocation (paper 2, eqs. 30-31) through :func:`hyperstat.solver.tolerances.accuracy.allocate`."""
    coeffs = {}
    for kind, cols in (("P", is_len), ("R", ~is_len)):
        coeffs[f"delta_g{kind}"] = _sigma_max(rot[:, :, cols])
        coeffs[f"epsilon_g{kind}"] = _sigma_max(pos[:, :, cols])
    for kind in ("fP", "fR"):
        coeffs[f"delta_{kind}"] = np.zeros(rot.shape[0])
        coeffs[f"epsilon_{kind}"] = np.zeros(rot.shape[0])
    groups = {"fP": [], "fR": [], "gP": [n for n, b in zip(names, is_len) if b],
              "gR": [n for n, b in zip(names, is_len) if not b]}
    maps = AccuracyMaps(coeffs, {}, groups, np.zeros((rot.shape[0], 0)), np.zeros((rot.shape[0], 3)))
    return allocate(maps, orientation if rot.shape[1] else None, position if pos.shape[1] else None)


def assign_values(cl: Classification, mechanism: Mechanism, kin: Kinematics, configurations: np.ndarray,
                  position_accuracy: float | None = None, orientation_accuracy: float | None = None,
                  assembly: bool = True, assembly_configurations: np.ndarray | None = None) -> Classification:
    """Fill ``value``, ``value_source`` and ``contribution`` of every tolerance of ``cl`` (in place).

    Parameters
    ----------
    configurations : ndarray, (K, n_q)
        Workspace sample for the allocation (the worst case over it is used).
    position_accuracy, orientation_accuracy : float, optional
        Spec overriding the declaration's (mm, rad).
    assembly : bool
        Compute the assembly conditions' values from the clearances.
    assembly_configurations : ndarray, optional
        Configurations for the assemblability check (default: ``configurations``).
    """
    decl = cl.declaration
    spec_p = position_accuracy if position_accuracy is not None else decl.position_mm
    spec_o = orientation_accuracy if orientation_accuracy is not None else decl.orientation_rad
    q = np.atleast_2d(configurations)
    influential = [t for t in cl.items if t.cls in ("accuracy-critical", "compensable")]
    info = {"spec": {"position_mm": spec_p, "orientation_rad": spec_o}, "configurations": int(len(q)),
            "method": "equal allocation, paper 2 eqs. (19), (30)-(31), worst case over the sample"}
    if influential:
        dirs = np.stack([t.direction for t in influential], axis=1)
        rot, pos = task_maps(mechanism, kin, q, decl.task, dirs)
        is_len = np.array([t.unit == "mm" for t in influential])
        names = [t.id for t in influential]
        cal = cl.calibration
        left_p = None if spec_p is None else spec_p - cal.get("position_mm", 0.0)
        left_o = None if spec_o is None else spec_o - cal.get("orientation_rad", 0.0)
        if (left_p is not None and left_p <= 0) or (left_o is not None and left_o <= 0):
            cl.warnings.append("the calibration noise alone uses up the spec: no accuracy-critical tolerance fits.")
        crit = np.array([t.cls == "accuracy-critical" for t in influential])
        calibrated = _allocate(rot[:, :, crit], pos[:, :, crit], is_len[crit], [n for n, c in zip(names, crit) if c],
                               left_p if left_p is None or left_p > 0 else 0.0,
                               left_o if left_o is None or left_o > 0 else 0.0) if crit.any() else None
        uncalibrated = _allocate(rot, pos, is_len, names, spec_p, spec_o)
        info["calibrated"] = calibrated
        info["uncalibrated"] = uncalibrated
        for t, length in zip(influential, is_len):
            kind = "gP" if length else "gR"
            src = calibrated if t.cls == "accuracy-critical" else uncalibrated
            v = src["classes"].get(kind, {}).get("tolerance") if src else None
            t.value = v
            if t.cls == "accuracy-critical":
                t.value_source = ("equal allocation against the spec less the calibration residual, worst case "
                                  f"over {len(q)} configurations (paper 2, eqs. 30-31)")
            else:
                t.value_source = ("equal allocation against the spec without calibration (paper 2, eqs. 30-31); "
                                  "calibration lets it open")
        # contributions: first-order variance at the values (uniform: t^2 / 3)
        rows = pos if pos.shape[1] else rot
        vals = np.array([t.value or 0.0 for t in influential])
        var = np.mean(np.sum(rows**2, axis=1), axis=0) * vals**2 / 3.0
        total = float(var.sum())
        for t, v in zip(influential, var):
            t.contribution = 100.0 * float(v) / total if total > 0 else 0.0
        info["contribution_of"] = "position" if pos.shape[1] else "orientation"
    for t in cl.items:
        if t.cls == "non-influent":
            t.value = None
            t.value_source = "not limited by accuracy (moves nothing the task uses)"
    if assembly:
        from hyperstat.solver.tolerances.clearance import assembly_tolerances

        items = cl.by_class("assembly")
        if items:
            qa = q if assembly_configurations is None else np.atleast_2d(assembly_configurations)
            vals = assembly_tolerances(mechanism, items, decl, qa)
            for t in items:
                v = vals[t.id]
                t.value = v["value"]
                t.evidence["assemblability"] = {k: v[k] for k in ("worst_configuration", "limiting", "at_bound",
                                                                  "configurations")}
                t.value_source = (f"largest violation the joint clearances absorb at every one of {v['configurations']} "
                                  "configurations (worst-case assemblability, linear programme)")
                if v["value"] is None:
                    t.value_source = "the clearances absorb any small violation (no limit to first order)"
    cl.allocation = info
    return cl


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
        machines, ``linear_worst_case`` (triangle-inequality bound over the sample, every
        tolerance at its extreme, mm / rad), and ``contributors`` by tolerance id, sorted
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
    tol = {t.id: float(t.value) for t in drawn}
    res = monte_carlo(mechanism, configurations, tol, samples, distribution, seed, kinematics=kin,
                      directions=(names, matrix, units), task=decl.task)
    out = res.summary(spec_o, spec_p)
    label = {t.id: f"{t.id} {t.statement}" for t in drawn}
    for c in out["contributors"]:
        c["label"] = label.get(c["parameter"], c["parameter"])
    out["contributors"].sort(key=lambda c: -c["position_share"])
    rot, pos = task_maps(mechanism, kin, configurations, decl.task, matrix)
    vals = np.array([tol[n] for n in names])
    out["linear_worst_case"] = {
        "position_mm": float(np.max(np.linalg.norm(pos, axis=1) @ vals)) if pos.shape[1] else None,
        "orientation_rad": float(np.max(np.linalg.norm(rot, axis=1) @ vals)) if rot.shape[1] else None}
    crit = [t for t in drawn if t.cls == "accuracy-critical"]
    calibrated = {}
    if crit:
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
    out["calibrated"] = calibrated
    out["spec"] = {"position_mm": spec_p, "orientation_rad": spec_o}
    out["task"] = list(decl.task)
    return out
