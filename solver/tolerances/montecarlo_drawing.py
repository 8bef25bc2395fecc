"""Monte Carlo of machines made to the drawing, calibrated as the template declares.

Units: mm and rad.

A drawing carries, for a compensable tolerance, its value *with calibration* when the template declares
its measurements: such a machine is meant to be calibrated.  :func:`calibrated_machines` draws machines
with every accuracy-critical and compensable tolerance within its drawing value (uniform in ``+-value``
along its direction, or normal with ``sigma = value / 3``), calibrates each one from the declared
measurements and compensates it through the nonlinear model
(:func:`hyperstat.solver.tolerances.calibrated.simulate_calibration`: Gauss-Newton over the admissible
coordinates and the declared nuisances, then the actuators solved in the fitted model for the nominal task
poses), and measures the true machine's task error at workspace configurations.  The calibration's 3-sigma
task error from the declared measurement noise is added as a worst case (the simulation itself is
noise-free).  The share of (machine, configuration) pairs out of spec is the rate after calibration.
"""

from __future__ import annotations

import numpy as np

__all__ = ["calibrated_machines", "MACHINES"]

#: machines calibrated by simulation (each one a nonlinear identification and compensation)
MACHINES = 40


def calibrated_machines(cl, mechanism, kin, configurations: np.ndarray, drawn: list, values: dict,
                        machines: int = MACHINES, seed: int = 0, distribution: str = "uniform",
                        spec_p: float | None = None, spec_o: float | None = None) -> dict:
    """Rates out of spec of machines made to the drawing after the declared calibration (module docstring).

    Parameters
    ----------
    drawn : list of Tolerance
        The tolerances drawn (their ``direction``).
    values : dict
        Tolerance id -> the value drawn within (the drawing value).

    Returns
    -------
    dict
        JSON-ready: ``machines``, ``configurations``, ``out_of_spec_position_percent`` /
        ``out_of_spec_orientation_percent`` (of the pairs), ``machines_out_of_spec_percent``, ``position_max_mm``,
        ``orientation_max_rad``, ``not_reached`` (pairs where the compensated model could not reach the nominal pose),
        ``noise_added``, ``method``.
    """
    from hyperstat.solver.tolerances.calibrated import CALIBRATION_POSES, TASK_POSES, regular_task, simulate_calibration

    if cl.analysis is None or not drawn:
        return {}
    rng = np.random.default_rng(seed)
    dirs = np.stack([t.direction for t in drawn])  # (n, n_xi)
    v = np.array([values[t.id] for t in drawn])
    if distribution == "normal":
        u = np.clip(rng.normal(0.0, 1.0 / 3.0, size=(machines, len(drawn))), -1.0, 1.0)
    else:
        u = rng.uniform(-1.0, 1.0, size=(machines, len(drawn)))
    xi = (u * v[None, :]) @ dirs
    q_cal = cl.configurations if cl.configurations is not None else cl.analysis.configurations
    q_cal = q_cal[np.unique(np.linspace(0, len(q_cal) - 1, min(len(q_cal), CALIBRATION_POSES)).round().astype(int))]
    q_all = np.atleast_2d(configurations)
    q_all = q_all[np.unique(np.linspace(0, len(q_all) - 1, min(len(q_all), TASK_POSES)).round().astype(int))]
    q_task = q_all[regular_task(kin, cl.declaration, q_all)]
    pos, rot, reached = simulate_calibration(mechanism, kin, cl.analysis, cl.declaration, xi, q_cal, q_task)
    cal = cl.calibration or {}
    noise_p, noise_o = float(cal.get("position_mm", 0.0)), float(cal.get("orientation_rad", 0.0))
    ok = reached
    out = {"machines": int(machines), "configurations": int(len(q_task)), "calibration_poses": int(len(q_cal)),
           "distribution": distribution, "not_reached": int(np.sum(~ok)),
           "noise_added": {"position_mm": noise_p, "orientation_rad": noise_o},
           "position_max_mm": float(np.max(np.where(ok, pos, 0.0))) if pos.size else None,
           "orientation_max_rad": float(np.max(np.where(ok, rot, 0.0))) if rot.size else None,
           "method": (f"{machines} machines made to the drawing (every accuracy-critical and compensable tolerance "
                      f"drawn within its drawing value, {distribution}), each calibrated from the declared "
                      f"measurements at {len(q_cal)} poses and compensated through the nonlinear model, its task "
                      f"error measured at {len(q_task)} workspace configurations, plus the calibration's 3-sigma "
                      "error from the declared noise")}
    outside = np.zeros_like(ok)
    if spec_p is not None:
        bad = ok & (pos + noise_p > spec_p)
        outside |= bad
        out["out_of_spec_position_percent"] = float(100 * np.sum(bad) / max(int(np.sum(ok)), 1))
    if spec_o is not None and rot.size:
        bad = ok & (rot + noise_o > spec_o)
        outside |= bad
        out["out_of_spec_orientation_percent"] = float(100 * np.sum(bad) / max(int(np.sum(ok)), 1))
    out["machines_out_of_spec_percent"] = float(100 * np.mean(np.any(outside, axis=1))) if outside.size else 0.0
    return out
