"""Monte Carlo tolerance analysis through the full nonlinear model.

Units: lengths in mm, angles in rad.

Defects are drawn within their tolerances (uniform in +-t, or normal with sigma = t/3),
only for the admissible defects when a stationarity analysis is given (the forced ones
are assembly conditions, not accuracy inputs), at configurations drawn from the
workspace; the mechanism is re-assembled with the defects (Gauss-Newton, warm-started
at the nominal configuration) and the platform's orientation error (angle of
``R_nominal^T R``) and position error (``O_p``) are compared with the linear worst-case
bounds of paper 2, eqs. (18) at the same configuration.  Contributors are ranked by
their first-order share of the position error variance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hyperstat.solver.tolerances.accuracy import COEFFICIENT_NAMES, accuracy_maps, geometric_parameters, output_twist_maps
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.frames import so3_log
from hyperstat.solver.kinematics.model import Mechanism

__all__ = ["MonteCarloResult", "monte_carlo"]


@dataclass
class MonteCarloResult:
    """Pose errors of the samples and what bounds them.

    Attributes
    ----------
    orientation, position : ndarray, (N,)
        |dphi| (rad) and ||dO_p|| (mm) from the nonlinear model.
    orientation_bound, position_bound : ndarray, (N,)
        Linear worst-case bounds (eqs. 18) for each sample's defects.
    orientation_linear, position_linear : ndarray, (N,)
        First-order predictions ``|D dq|``, ``|E dq|``.
    contributors : list of dict
        Parameter, its share of the position and orientation error variance (first order).
    converged : ndarray of bool
    """

    orientation: np.ndarray
    position: np.ndarray
    orientation_bound: np.ndarray
    position_bound: np.ndarray
    orientation_linear: np.ndarray
    position_linear: np.ndarray
    contributors: list
    converged: np.ndarray
    distribution: str
    tolerances: dict

    def summary(self, orientation_spec: float | None = None, position_spec: float | None = None) -> dict:
        """Distribution statistics, worst case against the bound, share out of spec (JSON-ready)."""
        ok = self.converged

        def stats(v):
            v = v[ok]
            return {"mean": float(v.mean()), "std": float(v.std()), "p95": float(np.quantile(v, 0.95)),
                    "p99": float(np.quantile(v, 0.99)), "max": float(v.max())}

        out = {
            "samples": int(ok.sum()), "not_assembled": int((~ok).sum()), "distribution": self.distribution,
            "orientation_rad": stats(self.orientation), "position_mm": stats(self.position),
            "worst_over_bound": {"orientation": float(np.max(self.orientation[ok] / np.maximum(
                self.orientation_bound[ok], 1e-300))), "position": float(np.max(self.position[ok] / np.maximum(
                    self.position_bound[ok], 1e-300)))},
            "largest_excess_over_bound": {
                "orientation_rad": float(np.max(self.orientation[ok] - self.orientation_bound[ok])),
                "position_mm": float(np.max(self.position[ok] - self.position_bound[ok]))},
            "contributors": self.contributors,
            "tolerances": self.tolerances,
        }
        if orientation_spec is not None:
            out["out_of_spec_orientation_percent"] = float(100 * np.mean(self.orientation[ok] > orientation_spec))
        if position_spec is not None:
            out["out_of_spec_position_percent"] = float(100 * np.mean(self.position[ok] > position_spec))
        return out


def _top_singular(block: np.ndarray) -> np.ndarray:
    """Largest singular value of each matrix of a stack (K, r, n); closed form when r = 3."""
    from hyperstat.solver.tolerances.accuracy import largest_singular_value

    if block.shape[1] == 3:
        return largest_singular_value(block)
    if block.shape[1] == 0 or block.shape[2] == 0:
        return np.zeros(block.shape[0])
    return np.linalg.svd(block, compute_uv=False)[:, 0]


def monte_carlo(mechanism: Mechanism, configurations: np.ndarray, tolerances: dict, samples: int = 10000,
                distribution: str = "uniform", seed: int = 0, analysis=None,
                kinematics: Kinematics | None = None, chunk: int = 20000, directions: tuple | None = None,
                task: tuple | None = None) -> MonteCarloResult:
    """Sample defects within ``tolerances`` and measure the platform's pose error (see module docstring).

    Parameters
    ----------
    configurations : ndarray, (K, n_q)
        Nominal assembled configurations; sample ``i`` uses configuration ``i mod K``.
    tolerances : dict
        Geometric parameter (as :func:`hyperstat.solver.tolerances.accuracy.geometric_parameters` names it) -> tolerance
        (rad or mm), and optionally actuated joint name -> tolerance.
    distribution : {"uniform", "normal"}
        Uniform in +-t, or normal with sigma = t / 3.
    directions : (list of str, ndarray (n_xi, n), list of str), optional
        Named defect directions (rad / mm per unit) and their units to draw instead of the geometric
        parameters, e.g. the tolerances of :mod:`hyperstat.solver.tolerances.classification`
        (``tolerances`` is then keyed by these names).
    task : tuple of str, optional
        Task components (:data:`hyperstat.solver.tolerances.declaration.TASK_COMPONENTS`):
        the errors, bounds and shares are measured on them only (e.g. the tool-axis tilt,
        not the rotation about the spindle); default: full orientation and position.
    """
    kin = kinematics or Kinematics(mechanism)
    names, matrix = directions[:2] if directions is not None else geometric_parameters(mechanism, analysis)
    if task is not None:
        from hyperstat.solver.tolerances.declaration import n_rotation_rows, task_rows

        n_rot = n_rotation_rows(tuple(task))
    act = mechanism.actuated
    f_names = [mechanism.joints[i].name for i in act]
    t_g = np.array([float(tolerances.get(n, 0.0)) for n in names])
    t_f = np.array([float(tolerances.get(n, 0.0)) for n in f_names])
    rng = np.random.default_rng(seed)
    draw = (lambda t, size: rng.uniform(-1, 1, size) * t) if distribution == "uniform" else \
        (lambda t, size: rng.normal(0, 1, size) * t / 3.0)
    n_cfg = len(configurations)
    out = {k: np.zeros(samples) for k in ("orientation", "position", "orientation_bound", "position_bound",
                                          "orientation_linear", "position_linear")}
    converged = np.zeros(samples, dtype=bool)
    units = {p.name: p.unit for p in mechanism.parameters}
    if directions is not None:
        g_is_p = np.array([u == "mm" for u in directions[2]], dtype=bool)
    else:
        g_is_p = np.array([units[n] == "mm" for n in names]) if names else np.zeros(0, bool)
    f_is_p = np.array([mechanism.joints[i].type == "P" for i in act])
    var_rot = np.zeros(len(f_names) + len(names))
    var_pos = np.zeros(len(f_names) + len(names))
    for s in range(0, samples, chunk):
        m = min(chunk, samples - s)
        idx = (np.arange(s, s + m)) % n_cfg
        q0 = configurations[idx]
        dg = draw(t_g, (m, len(names)))
        df = draw(t_f, (m, len(f_names)))
        xi = dg @ matrix.T
        nominal = kin.evaluate(q0, None, jacobians=True)
        q = q0.copy()
        q[:, act] += df
        res = kin.assemble(q, xi)
        real = kin.evaluate(res.q, xi, jacobians=False)
        sl = slice(s, s + m)
        k_xi, k_a = output_twist_maps(kin, nominal)
        k_g = k_xi @ matrix
        if task is None:
            r_err = np.swapaxes(nominal.output_pose[:, :3, :3], 1, 2) @ real.output_pose[:, :3, :3]
            rot_err = so3_log(r_err)[:, :, None]
            pos_err = (real.output_pose[:, :3, 3] - nominal.output_pose[:, :3, 3])[:, :, None]
            rows_r, rows_p = slice(0, 3), slice(3, 6)
        else:  # task components: rotation vector and position in the base frame, selected
            sel = task_rows(tuple(task), nominal.output_pose)
            w = so3_log(real.output_pose[:, :3, :3] @ np.swapaxes(nominal.output_pose[:, :3, :3], 1, 2))
            e6 = np.concatenate([w, real.output_pose[:, :3, 3] - nominal.output_pose[:, :3, 3]], axis=1)
            e = sel @ e6[:, :, None]
            rot_err, pos_err = e[:, :n_rot], e[:, n_rot:]
            k_g, k_a = sel @ k_g, sel @ k_a
            rows_r, rows_p = slice(0, n_rot), slice(n_rot, sel.shape[1])
        out["orientation"][sl] = np.linalg.norm(rot_err[:, :, 0], axis=1)
        out["position"][sl] = np.linalg.norm(pos_err[:, :, 0], axis=1)
        converged[sl] = res.converged
        lin = k_g @ dg[:, :, None] + k_a @ df[:, :, None]
        out["orientation_linear"][sl] = np.linalg.norm(lin[:, rows_r, 0], axis=1)
        out["position_linear"][sl] = np.linalg.norm(lin[:, rows_p, 0], axis=1)
        bound_r = np.zeros(m)
        bound_p = np.zeros(m)
        for cols, src, dq in ((f_is_p, k_a, df), (~f_is_p, k_a, df), (g_is_p, k_g, dg), (~g_is_p, k_g, dg)):
            if not np.any(cols):
                continue
            block = src[:, :, cols]
            norm = np.linalg.norm(dq[:, cols], axis=1)
            bound_r += _top_singular(block[:, rows_r]) * norm
            bound_p += _top_singular(block[:, rows_p]) * norm
        out["orientation_bound"][sl] = bound_r
        out["position_bound"][sl] = bound_p
        both = np.concatenate([k_a, k_g], axis=2)
        t_all = np.r_[t_f, t_g]
        factor = 1.0 / 3.0 if distribution == "uniform" else 1.0 / 9.0  # variance of the draw per t^2
        var_rot += np.sum(np.linalg.norm(both[:, rows_r], axis=1) ** 2, axis=0) * t_all**2 * factor
        var_pos += np.sum(np.linalg.norm(both[:, rows_p], axis=1) ** 2, axis=0) * t_all**2 * factor
    all_names = f_names + names
    contributors = []
    for j, n in enumerate(all_names):
        contributors.append({"parameter": n, "position_share": float(var_pos[j] / max(var_pos.sum(), 1e-300)),
                             "orientation_share": float(var_rot[j] / max(var_rot.sum(), 1e-300)),
                             "tolerance": float(np.r_[t_f, t_g][j])})
    contributors.sort(key=lambda c: -(c["position_share"] + c["orientation_share"]))
    return MonteCarloResult(out["orientation"], out["position"], out["orientation_bound"], out["position_bound"],
                            out["orientation_linear"], out["position_linear"], contributors, converged,
                            distribution, {n: float(t) for n, t in zip(all_names, np.r_[t_f, t_g])})
