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


def monte_carlo(mechanism: Mechanism, configurations: np.ndarray, tolerances: dict, samples: int = 10000,
                distribution: str = "uniform", seed: int = 0, analysis=None,
                kinematics: Kinematics | None = None, chunk: int = 20000) -> MonteCarloResult:
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
    """
    kin = kinematics or Kinematics(mechanism)
    names, matrix = geometric_parameters(mechanism, analysis)
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
    g_kind = np.array(["P" if p.unit == "mm" else "R" for p in mechanism.parameters])
    units = {p.name: p.unit for p in mechanism.parameters}
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
        r_err = np.swapaxes(nominal.output_pose[:, :3, :3], 1, 2) @ real.output_pose[:, :3, :3]
        sl = slice(s, s + m)
        out["orientation"][sl] = np.linalg.norm(so3_log(r_err), axis=1)
        out["position"][sl] = np.linalg.norm(real.output_pose[:, :3, 3] - nominal.output_pose[:, :3, 3], axis=1)
        converged[sl] = res.converged
        k_xi, k_a = output_twist_maps(kin, nominal)
        k_g = k_xi @ matrix
        lin = k_g @ dg[:, :, None] + k_a @ df[:, :, None]
        out["orientation_linear"][sl] = np.linalg.norm(lin[:, :3, 0], axis=1)
        out["position_linear"][sl] = np.linalg.norm(lin[:, 3:, 0], axis=1)
        bound_r = np.zeros(m)
        bound_p = np.zeros(m)
        from hyperstat.solver.tolerances.accuracy import largest_singular_value

        for cols, src, dq in ((f_is_p, k_a, df), (~f_is_p, k_a, df), (g_is_p, k_g, dg), (~g_is_p, k_g, dg)):
            if not np.any(cols):
                continue
            block = src[:, :, cols]
            norm = np.linalg.norm(dq[:, cols], axis=1)
            bound_r += largest_singular_value(block[:, :3]) * norm
            bound_p += largest_singular_value(block[:, 3:]) * norm
        out["orientation_bound"][sl] = bound_r
        out["position_bound"][sl] = bound_p
        both = np.concatenate([k_a, k_g], axis=2)
        t_all = np.r_[t_f, t_g]
        factor = 1.0 / 3.0 if distribution == "uniform" else 1.0 / 9.0  # variance of the draw per t^2
        var_rot += np.sum(np.linalg.norm(both[:, :3], axis=1) ** 2, axis=0) * t_all**2 * factor
        var_pos += np.sum(np.linalg.norm(both[:, 3:], axis=1) ** 2, axis=0) * t_all**2 * factor
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
