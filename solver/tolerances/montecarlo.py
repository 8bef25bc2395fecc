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

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from hyperstat.solver.tolerances.accuracy import geometric_parameters, largest_singular_value, output_twist_maps
from hyperstat.solver.kinematics.closure import Kinematics, batched_lstsq
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
                kinematics: Kinematics | None = None, chunk: int = 10000, workers: int | None = None,
                directions: tuple | None = None, task: tuple | None = None) -> MonteCarloResult:
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
    chunk : int
        Samples per block (memory bound); the draws are made block by block in order.
    workers : int, optional
        Threads that process blocks concurrently (default: the number of CPUs, at most
        4); the result does not depend on it.
    directions : (list of str, ndarray (n_xi, n), list of str), optional
        Named defect directions (rad / mm per unit) and their units to draw instead of the geometric
        parameters, e.g. the tolerances of :mod:`hyperstat.solver.tolerances.classification`
        (``tolerances`` is then keyed by these names).
    task : tuple of str, optional
        Task components (:data:`hyperstat.solver.tolerances.declaration.TASK_COMPONENTS`):
        the errors, bounds and shares are measured on them only (e.g. the tool-axis tilt,
        not the rotation about the spindle); default: full orientation and position.

    Re-assembly is a chord iteration from the nominal configuration with a first-order
    predictor (:class:`_Chord`); the maps, singular values, column norms and task
    selections of the nominal configurations are computed once per configuration, not
    once per sample.
    """
    kin = kinematics or Kinematics(mechanism)
    names, matrix = directions[:2] if directions is not None else geometric_parameters(mechanism, analysis)
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
    # everything that depends on the nominal configuration only, once per configuration (not per sample)
    configurations = np.atleast_2d(np.asarray(configurations, dtype=float))
    nominal = kin.evaluate(configurations, None, jacobians=True)
    k_xi, k_a = output_twist_maps(kin, nominal)
    k_g = k_xi @ matrix
    sel = None
    rows_r, rows_p = slice(0, 3), slice(3, 6)
    if task is not None:  # task components: rotation vector and position in the base frame, selected
        from hyperstat.solver.tolerances.declaration import n_rotation_rows, task_rows

        n_rot = n_rotation_rows(tuple(task))
        sel = task_rows(tuple(task), nominal.output_pose)  # (K, n_task, 6), per configuration
        rows_r, rows_p = slice(0, n_rot), slice(n_rot, sel.shape[1])
        k_a_t, k_g_t = sel @ k_a, sel @ k_g
    else:
        k_a_t, k_g_t = k_a, k_g
    blocks = []  # (columns, the draw it multiplies, top singular values): the classes fP, fR, gP, gR of eq. (18)
    for cols, src, which in ((f_is_p, k_a_t, "f"), (~f_is_p, k_a_t, "f"), (g_is_p, k_g_t, "g"), (~g_is_p, k_g_t, "g")):
        if np.any(cols):
            blocks.append((cols, which, _top_singular(src[:, rows_r][:, :, cols]),
                           _top_singular(src[:, rows_p][:, :, cols])))
    both = np.concatenate([k_a_t, k_g_t], axis=2)
    col_rot = np.sum(both[:, rows_r] ** 2, axis=1)  # squared column norms per configuration (K, n_f + n_g)
    col_pos = np.sum(both[:, rows_p] ** 2, axis=1)
    chord = _Chord(kin, nominal, matrix)
    starts = list(range(0, samples, chunk))
    draws = []
    for s in starts:  # drawn in order, chunk by chunk, so that the samples do not depend on the threads
        m = min(chunk, samples - s)
        draws.append((draw(t_g, (m, len(names))), draw(t_f, (m, len(f_names)))))

    def block(c: int) -> None:
        s = starts[c]
        dg, df = draws[c]
        m = len(dg)
        idx = (np.arange(s, s + m)) % n_cfg
        xi = dg @ matrix.T
        lin6 = k_g[idx] @ dg[:, :, None] + k_a[idx] @ df[:, :, None]
        # re-assembled until the closure residual is a millionth of the sample's first-order error
        size = np.linalg.norm(lin6[:, 3:, 0], axis=1) + kin.length_scale * np.linalg.norm(lin6[:, :3, 0], axis=1)
        ok, real_pose = chord.assemble(configurations, idx, xi, dg, df, tol=1e-6 * size)
        r_nom = nominal.output_pose[idx]
        sl = slice(s, s + m)
        if sel is None:
            r_err = np.swapaxes(r_nom[:, :3, :3], 1, 2) @ real_pose[:, :3, :3]
            out["orientation"][sl] = np.linalg.norm(so3_log(r_err), axis=1)
            out["position"][sl] = np.linalg.norm(real_pose[:, :3, 3] - r_nom[:, :3, 3], axis=1)
            lin = lin6
        else:
            w = so3_log(real_pose[:, :3, :3] @ np.swapaxes(r_nom[:, :3, :3], 1, 2))
            e6 = np.concatenate([w, real_pose[:, :3, 3] - r_nom[:, :3, 3]], axis=1)
            e = (sel[idx] @ e6[:, :, None])[:, :, 0]
            out["orientation"][sl] = np.linalg.norm(e[:, rows_r], axis=1)
            out["position"][sl] = np.linalg.norm(e[:, rows_p], axis=1)
            lin = sel[idx] @ lin6
        converged[sl] = ok
        out["orientation_linear"][sl] = np.linalg.norm(lin[:, rows_r, 0], axis=1)
        out["position_linear"][sl] = np.linalg.norm(lin[:, rows_p, 0], axis=1)
        bound_r = np.zeros(m)
        bound_p = np.zeros(m)
        for cols, which, sv_r, sv_p in blocks:
            norm = np.linalg.norm((df if which == "f" else dg)[:, cols], axis=1)
            bound_r += sv_r[idx] * norm
            bound_p += sv_p[idx] * norm
        out["orientation_bound"][sl] = bound_r
        out["position_bound"][sl] = bound_p

    threads = min(workers or min(os.cpu_count() or 1, 4), len(starts))
    if threads > 1:  # numpy releases the GIL in its array loops; each block writes its own rows
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(block, range(len(starts))))  # list(): re-raises an exception of any block
    else:
        for c in range(len(starts)):
            block(c)
    # first-order variance shares: every configuration weighted by how many samples used it
    uses = np.bincount(np.arange(samples) % n_cfg, minlength=n_cfg).astype(float)
    t_all = np.r_[t_f, t_g]
    factor = 1.0 / 3.0 if distribution == "uniform" else 1.0 / 9.0  # variance of the draw per t^2
    var_rot = (uses @ col_rot) * t_all**2 * factor
    var_pos = (uses @ col_pos) * t_all**2 * factor
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


class _Chord:
    """Re-assembly with defects by a chord (simplified Newton) iteration from the nominal configuration.

    The defects are small, so the nominal configuration's passive Jacobian is a good
    iteration matrix for every sample drawn there: ``B_p^+`` (scaled rows, least squares
    when over-constrained) is computed once per configuration, and the passive joints
    start at the first-order prediction ``-B_p^+ (A xi + B_a dq_a)`` (paper 1, eq. 3).
    Each iteration then costs one forward evaluation with the sample's defects and no
    Jacobian; it contracts the error by about the size of the defects.  Samples that do
    not converge in ``max_iter`` iterations are handed to :meth:`Kinematics.assemble`
    (Gauss-Newton), and count as not assembled if that fails too.
    """

    def __init__(self, kin: Kinematics, nominal, matrix: np.ndarray, max_iter: int = 6) -> None:
        m = kin.mechanism
        self.kin, self.max_iter = kin, max_iter
        self.act, self.pas = np.asarray(m.actuated), np.asarray(m.passive)
        self.w = np.ones(6 * len(m.closures))
        for c in range(len(self.w) // 6):
            self.w[6 * c : 6 * c + 3] = kin.length_scale
        self.solve = None
        if len(self.pas) and len(m.closures):
            b = nominal.closure_q * self.w[None, :, None]
            bp = b[:, :, self.pas]
            eye = np.broadcast_to(np.eye(bp.shape[1]), (len(bp), bp.shape[1], bp.shape[1])).copy()
            self.solve = batched_lstsq(bp, eye)  # (K, n_p, 6L): B_p^+ with the scaled rows
            self.g_xi = self.solve @ (nominal.closure_xi * self.w[None, :, None]) @ matrix  # per unit dg
            self.g_a = self.solve @ b[:, :, self.act]

    def assemble(self, configurations: np.ndarray, idx: np.ndarray, xi: np.ndarray, dg: np.ndarray,
                 df: np.ndarray, tol: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Assembled output poses (K, 4, 4) of the samples (configuration ``idx``, defects ``xi``, actuator errors ``df``).

        ``tol`` (K,): closure residual (mm, rotations times the length scale) at which a sample
        is done, between 1e-14 and 1e-7 length scales (the test of :meth:`Kinematics.assemble`);
        default 1e-10 length scales.
        """
        kin, act, pas = self.kin, self.act, self.pas
        q = configurations[idx].copy()
        q[:, act] += df
        pose = np.empty((len(q), 4, 4))
        ok = np.zeros(len(q), dtype=bool)
        if self.solve is None:
            st = kin.evaluate(q, xi, jacobians=False)
            return np.ones(len(q), dtype=bool), st.output_pose
        q[:, pas] -= np.einsum("kpg,kg->kp", self.g_xi[idx], dg) + np.einsum("kpa,ka->kp", self.g_a[idx], df)
        accept = 1e-7 * kin.length_scale
        tol = np.full(len(q), 1e-10 * kin.length_scale) if tol is None else np.clip(
            tol, 1e-14 * kin.length_scale, accept)
        live = np.arange(len(q))
        prev = np.full(len(q), np.inf)
        for it in range(self.max_iter + 1):
            st = kin.evaluate(q[live], xi[live], jacobians=False)
            r = st.residual * self.w
            rn = np.sqrt(np.einsum("ij,ij->i", r, r))
            done = (rn <= tol[live]) | ((rn <= accept) & ((rn > 0.5 * prev) | (it == self.max_iter)))
            pose[live[done]] = st.output_pose[done]
            ok[live[done]] = True
            keep = ~done & (it < self.max_iter)
            live, r, prev = live[keep], r[keep], rn[keep]
            if not len(live):
                break
            q[np.ix_(live, pas)] -= np.einsum("kpr,kr->kp", self.solve[idx[live]], r)
        rest = np.nonzero(~ok)[0]
        if len(rest):  # slow or failing: Gauss-Newton from the nominal configuration
            q0 = configurations[idx[rest]].copy()
            q0[:, act] += df[rest]
            res = kin.assemble(q0, xi[rest], max_iter=12)
            st = kin.evaluate(res.q, xi[rest], jacobians=False)
            pose[rest] = st.output_pose
            ok[rest] = res.converged
        return ok, pose
