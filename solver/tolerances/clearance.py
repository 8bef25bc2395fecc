"""Assembly tolerances from joint clearances: worst-case assemblability over the workspace.

Units: clearances and violations in mm and rad.

An assembly condition (a forced defect or a relation, :mod:`hyperstat.solver.tolerances.classification`)
must hold for the loops to close without deforming the parts; real joints have play,
and the play lets the loops close with a small violation.  Following the tolerance
analysis of over-constrained mechanisms with gaps, where assemblability is the
quantified statement "for every configuration there exist gap displacements, each
within its clearance, that close the loops" (Dantan & Qureshi, *Worst-case and
statistical tolerance analysis based on quantified constraint satisfaction problems
and Monte Carlo simulation*, Computer-Aided Design 41(1), 2009, 1-12; Ballu, Plantec
& Mathieu, *Geometrical reliability of overconstrained mechanisms with gaps*, CIRP
Annals 57(1), 2008, 159-162), the tolerance of a condition is the largest violation
``t`` such that at every sampled configuration

    U0^T (A d t + C g) = 0,   |g_i| <= c_i,

has a solution: ``A d`` is the closure motion (paper 1, eq. 3) of one unit of violation,
``U0`` spans the left null space of the passive joints' closure Jacobian ``B_p`` (their
motion is free), ``C`` holds the closure motions of the clearance displacements (radial
shifts and tilts of each joint's frame, its axial shift, a prismatic joint's twist) and
``c`` the clearances.  At one configuration, ``t(q) = 1 / s*`` with ``s*`` the linear
programme ``min s`` subject to ``U0^T C diag(c) y = -U0^T A d`` and ``|y| <= s`` (HiGHS,
through :func:`scipy.optimize.linprog`); the tolerance is the smallest ``t(q)`` over the
configurations, found as one block-diagonal programme with a common ``t`` and one
displacement vector per configuration (:func:`_min_violation`), so a workspace sample of
a few hundred configurations costs about one programme per condition.  Each condition
is taken alone (the others held).

:func:`confirm_nonlinear` checks a value with the full nonlinear model: the
clearances become bounded extra variables of each joint's frame (small prismatic and
revolute joints), and the loops are re-assembled by bounded least squares at the
worst configuration just below and just above the tolerance.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Defect, FixedTransform, Joint, Mechanism
from hyperstat.solver.tolerances.declaration import Declaration

__all__ = ["ClearanceModel", "clearance_model", "assembly_tolerances", "confirm_nonlinear"]


@dataclasses.dataclass
class ClearanceModel:
    """The mechanism with a full set of frame displacements per joint, and the clearance directions.

    Attributes
    ----------
    mechanism : Mechanism
        Every joint carries ``I J K a b c`` (and ``G`` for a prismatic joint); the original
        defects keep their names, the added components are named ``g<component><joint>``.
    columns : ndarray, (n_xi_aug, n_g)
        Defect vector (rad / mm) of one clearance displacement of size 1 in each direction.
    bounds : ndarray, (n_g,)
        Clearance of each direction (mm or rad).
    labels : list of str
        ``"joint 21 radial x"`` and so on.
    index_of : dict
        Original parameter name -> index in the augmented mechanism.
    sources : dict
        Joint -> clearance entry used (with its source).
    """

    mechanism: Mechanism
    columns: np.ndarray
    bounds: np.ndarray
    labels: list
    index_of: dict
    sources: dict


def clearance_model(mechanism: Mechanism, declaration: Declaration) -> ClearanceModel:
    """Augment every joint with frame displacements and list the clearance directions."""
    chains = []
    for ch in mechanism.chains:
        els = []
        for el in ch.elements:
            if isinstance(el, Joint):
                have = {d.component: d for d in el.defects}
                comps = "IJKabc" + ("G" if el.type == "P" else "")
                defects = tuple(have.get(c, Defect(c, f"g{c}{el.name}")) for c in comps)
                defects += tuple(d for c, d in have.items() if c not in comps)
                els.append(dataclasses.replace(el, defects=defects))
            else:
                els.append(el)
        chains.append(dataclasses.replace(ch, elements=tuple(els)))
    aug = dataclasses.replace(mechanism, chains=tuple(chains))
    index = aug.parameter_index
    cols, bounds, labels, sources = [], [], [], {}
    n = len(aug.parameters)
    for ch in aug.chains:
        for el in ch.elements:
            if not isinstance(el, Joint):
                continue
            c = declaration.clearance(el.name, el.type)
            sources[el.name] = c
            names = {d.component: d.name for d in el.defects}
            n0 = np.asarray(el.placement.z_axis, float)
            u1 = np.asarray(el.placement.x_axis, float)
            u2 = np.cross(n0, u1)

            def add(letters: str, vec: np.ndarray, bound: float, label: str) -> None:
                if bound <= 0:
                    return
                col = np.zeros(n)
                for k, letter in enumerate(letters):
                    col[index[names[letter]]] = vec[k]
                cols.append(col)
                bounds.append(bound)
                labels.append(f"joint {el.name} {label}")

            add("abc", u1, c["radial_mm"], "radial (x)")
            add("abc", u2, c["radial_mm"], "radial (y)")
            add("abc", n0, c["axial_mm"], "axial")
            add("IJK", u1, c["tilt_rad"], "tilt (x)")
            add("IJK", u2, c["tilt_rad"], "tilt (y)")
            if el.type == "P":
                col_g = np.zeros(n)
                if c["twist_rad"] > 0:
                    col_g[index[names["G"]]] = 1.0
                    cols.append(col_g)
                    bounds.append(c["twist_rad"])
                    labels.append(f"joint {el.name} twist")
    index_of = {p.name: index[p.name] for p in mechanism.parameters}
    columns = np.array(cols).T if cols else np.zeros((n, 0))
    return ClearanceModel(aug, columns, np.asarray(bounds, float), labels, index_of, sources)


def _lift(model: ClearanceModel, direction: np.ndarray) -> np.ndarray:
    out = np.zeros(len(model.mechanism.parameters))
    out[list(model.index_of.values())] = direction  # index_of follows the original parameter order
    return out


def _constraint_blocks(model: ClearanceModel, q: np.ndarray, kin: Kinematics | None = None):
    """Per configuration: ``U0^T C diag(c)`` and ``U0^T A`` (scaled rows: rotations times the length scale)."""
    kin = kin or Kinematics(model.mechanism)
    st = kin.evaluate(q, None, jacobians=True)
    a = kin.scaled_rows(st.closure_xi)  # (K, m, n_aug)
    bp = kin.scaled_rows(st.closure_q)[:, :, model.mechanism.passive]
    out = []
    for k in range(len(q)):
        if bp.shape[2]:
            u, s, _ = np.linalg.svd(bp[k], full_matrices=True)
            r = int(np.sum(s > 1e-9 * s[0])) if s.size and s[0] > 0 else 0
        else:
            u, r = np.eye(a.shape[1]), 0
        u0 = u[:, r:]
        out.append((u0.T @ a[k] @ model.columns * model.bounds[None, :], u0.T @ a[k]))
    return out


def _max_violation(cg: np.ndarray, av: np.ndarray) -> tuple[float, np.ndarray | None]:
    """Largest ``t`` with ``cg y = -t av``, ``|y| <= 1`` (linear programme); returns ``t`` and ``y``."""
    from scipy.optimize import linprog

    scale = max(float(np.max(np.abs(cg))) if cg.size else 0.0, float(np.max(np.abs(av))), 1e-300)
    if float(np.linalg.norm(av)) <= 1e-12 * scale:
        return float("inf"), None  # the condition is not felt here (absorbed without play)
    mat = np.concatenate([cg, av[:, None]], axis=1)
    u, s, vt = np.linalg.svd(mat, full_matrices=False)
    r = int(np.sum(s > 1e-10 * s[0]))
    eq = (s[:r, None] * vt[:r]) / scale
    m = cg.shape[1]
    # variables (y, t): maximise t subject to eq @ (y, t) = 0, -1 <= y <= 1
    res = linprog(np.r_[np.zeros(m), -1.0], A_eq=eq, b_eq=np.zeros(r),
                  bounds=[(-1.0, 1.0)] * m + [(0.0, None)], method="highs")
    if res.status == 3:  # unbounded: the play absorbs any violation to first order
        return float("inf"), None
    if not res.success:
        return 0.0, None
    return float(res.x[-1]), res.x[:m]


def _min_violation(blocks: list, d: np.ndarray) -> tuple:
    """Smallest ``t(q)`` over the configurations, in one linear programme.

    ``t(q)`` is the largest violation absorbed at ``q``; the violations absorbed at ``q`` form
    the interval ``[0, t(q)]`` (the feasible set is convex and holds ``t = 0, y = 0``), so the
    largest ``t`` absorbed at every configuration at once, each with its own displacements
    ``y_q`` (``|y_q| <= 1``), is ``min_q t(q)``: one block-diagonal programme (HiGHS, sparse)
    instead of one per configuration.  The worst configuration is the block whose
    constraints carry the largest dual values; its own programme is then solved for the
    displacements and checked against the common value.

    Returns
    -------
    tuple
        ``(t, worst index or None, y at the worst or None, extra)``; ``extra``:
        ``own_programme_value``, ``t(q)`` of the worst configuration's own programme (equal
        to ``t`` up to the solver's tolerance).
    """
    from scipy.optimize import linprog
    from scipy.sparse import coo_matrix

    rows, cols, vals, felt = [], [], [], []
    n_rows, n_var = 0, 0
    m = blocks[0][0].shape[1] if blocks else 0
    for k, (cg, a) in enumerate(blocks):
        av = a @ d
        scale = max(float(np.max(np.abs(cg))) if cg.size else 0.0, float(np.max(np.abs(av))), 1e-300)
        if float(np.linalg.norm(av)) <= 1e-12 * scale:
            continue  # not felt at this configuration
        mat = np.concatenate([cg, av[:, None]], axis=1)
        _, s, vt = np.linalg.svd(mat, full_matrices=False)
        r = int(np.sum(s > 1e-10 * s[0]))
        eq = (s[:r, None] * vt[:r]) / scale
        rr, cc = np.nonzero(np.abs(eq) > 0)
        rows.append(rr + n_rows)
        cols.append(np.where(cc < m, cc + n_var, -1))
        vals.append(eq[rr, cc])
        felt.append((k, n_rows, r))
        n_rows += r
        n_var += m
    if not felt:
        return float("inf"), None, None, {}
    cols = np.concatenate(cols)
    cols[cols < 0] = n_var  # the common violation t is the last variable
    a_eq = coo_matrix((np.concatenate(vals), (np.concatenate(rows), cols)), shape=(n_rows, n_var + 1)).tocsr()
    res = linprog(np.r_[np.zeros(n_var), -1.0], A_eq=a_eq, b_eq=np.zeros(n_rows),
                  bounds=[(-1.0, 1.0)] * n_var + [(0.0, None)], method="highs")
    if res.status == 3:
        return float("inf"), None, None, {}
    if not res.success:
        return 0.0, None, None, {}
    t = float(res.x[-1])
    duals = np.asarray(res.eqlin.marginals) if res.eqlin is not None else np.zeros(n_rows)
    weight = np.array([float(np.linalg.norm(duals[r0:r0 + r])) for _, r0, r in felt])
    for j in np.argsort(-weight)[:4]:  # the binding blocks first
        k = felt[j][0]
        cg, a = blocks[k]
        tk, yk = _max_violation(cg, a @ d)
        if tk <= t * (1 + 1e-6) + 1e-300:
            return t, k, yk, {"own_programme_value": tk}
    return t, None, None, {}  # no block reproduced the common value: the value without a location


def assembly_tolerances(mechanism: Mechanism, items: list, declaration: Declaration, configurations: np.ndarray,
                        model: ClearanceModel | None = None, reference: int | None = None) -> dict:
    """Tolerance of every assembly condition from the clearances (see the module docstring).

    Parameters
    ----------
    items : list of Tolerance
        Assembly conditions (``direction``: one unit of violation, rad / mm).
    configurations : ndarray, (K, n_q)
        Assembled configurations of the workspace.
    reference : int, optional
        The first ``reference`` configurations form a reference set (e.g. the analysis'
        configurations) whose own worst case is reported beside the value
        (``reference_value``), to show what the rest of the sample changed.

    Returns
    -------
    dict
        Tolerance id -> {"value", "worst_configuration", "limiting" (the four clearances at their
        bound with the largest effect at the worst configuration), "at_bound" (how many are at
        their bound), "configurations", "reference_value" (with ``reference``)}.
    """
    model = model or clearance_model(mechanism, declaration)
    kin = Kinematics(model.mechanism)
    blocks = _constraint_blocks(model, np.atleast_2d(configurations), kin)
    out = {}
    for it in items:
        d = _lift(model, it.direction)
        best, worst, y_worst, margins = _min_violation(blocks, d)
        if reference:
            ref = _min_violation(blocks[:reference], d)[0]
            margins["reference_value"] = None if not np.isfinite(ref) else ref
            margins["reference_configurations"] = min(reference, len(blocks))
        limiting, at_bound = [], 0
        if y_worst is not None:
            cg = blocks[worst][0]
            weight = np.linalg.norm(cg, axis=0) * (np.abs(y_worst) > 0.999)  # plays at their bound, by effect
            at_bound = int(np.sum(np.abs(y_worst) > 0.999))
            limiting = [model.labels[j] for j in np.argsort(-weight)[:4] if weight[j] > 0]
        out[it.id] = {"value": None if not np.isfinite(best) else best, "worst_configuration": worst,
                      "limiting": limiting, "at_bound": at_bound, "configurations": len(blocks), **margins}
    return out


def _closure(kin: Kinematics, model: ClearanceModel, qq: np.ndarray, d: np.ndarray, t: float, y: np.ndarray):
    """Scaled residual and Jacobians (passive joints, clearance displacements, violation) at one configuration."""
    xi = t * d + model.columns @ (y * model.bounds)
    st = kin.evaluate(qq, xi, jacobians=True)
    ja = kin.scaled_rows(st.closure_xi)[0]
    return (kin.scaled(st.residual)[0], kin.scaled_rows(st.closure_q)[0][:, model.mechanism.passive],
            ja @ model.columns * model.bounds[None, :], ja @ d)


def confirm_nonlinear(mechanism: Mechanism, direction: np.ndarray, value: float, q: np.ndarray,
                      declaration: Declaration, model: ClearanceModel | None = None, margin: float = 0.01,
                      iterations: int = 40) -> dict:
    """Check a linear assembly tolerance with the full nonlinear model, clearances as extra small joints.

    The clearances become bounded extra variables of each joint's frame (small prismatic
    and revolute joints: radial and axial shifts, tilts, a slide's twist), ``|y_i| <= 1`` in
    units of the clearance.  Two checks at the configuration ``q``:

    * **below**: at ``(1 - margin) value`` the loops are closed by Newton steps on the
      passive joints and the clearance displacements (minimum-norm corrections), starting
      from the linear programme's displacements; the residual must fall to round-off with
      every displacement within its clearance;
    * **maximum**: the largest violation for which the loops close is found by sequential
      linear programming (the closure linearised at the current point, ``max t`` with
      ``|y| <= 1`` and a shrinking trust region on ``y``), then the loops are re-assembled
      there with the passive joints alone.

    Returns
    -------
    dict
        ``linear`` (the value given), ``below`` {``violation``, ``closure_residual_mm``,
        ``largest_clearance_use``}, ``value`` (nonlinear maximum), ``relative_difference``,
        ``closure_residual_mm`` (re-assembled at the nonlinear maximum), ``iterations``.
    """
    from scipy.optimize import linprog

    model = model or clearance_model(mechanism, declaration)
    kin = Kinematics(model.mechanism)
    passive = model.mechanism.passive
    d = _lift(model, direction)
    q0 = np.array(q, dtype=float)[None]
    n_g = model.columns.shape[1]

    def step_lp(qq, t, y, radius):
        r, jq, jy, jt = _closure(kin, model, qq, d, t, y)
        u, sv, _ = np.linalg.svd(jq, full_matrices=True)
        rank = int(np.sum(sv > 1e-9 * sv[0])) if sv.size and sv[0] > 0 else 0
        u0 = u[:, rank:]
        a_eq = u0.T @ np.concatenate([jy, jt[:, None]], axis=1)
        b_eq = -(u0.T @ (r - jy @ y - jt * t))
        scale = max(float(np.max(np.abs(a_eq))), 1e-300)
        bounds = [(max(-1.0, yi - radius), min(1.0, yi + radius)) for yi in y] + [(0.0, None)]
        res = linprog(np.r_[np.zeros(n_g), -1.0], A_eq=a_eq / scale, b_eq=b_eq / scale, bounds=bounds, method="highs")
        if not res.success:
            return None
        y_new, t_new = res.x[:n_g], float(res.x[-1])
        dq = -np.linalg.lstsq(jq, r + jy @ (y_new - y) + jt * (t_new - t), rcond=1e-12)[0]
        return dq, y_new, t_new

    # below: linear displacements at (1 - margin) value, then Newton (minimum-norm corrections)
    qq = q0.copy()
    first = step_lp(qq, 0.0, np.zeros(n_g), 1.0)
    below = {"violation": (1 - margin) * value, "closure_residual_mm": None, "largest_clearance_use": None}
    if first is not None and first[2] > 0:
        y = first[1] * (1 - margin) * value / first[2]
        qq[0, passive] += first[0] * (1 - margin) * value / first[2]
        t = (1 - margin) * value
        for _ in range(20):
            r, jq, jy, _ = _closure(kin, model, qq, d, t, y)
            if np.linalg.norm(r) < 1e-12 * kin.length_scale:
                break
            step = -np.linalg.lstsq(np.concatenate([jq, jy], axis=1), r, rcond=1e-12)[0]
            qq[0, passive] += step[: len(passive)]
            y = y + step[len(passive):]
        r = _closure(kin, model, qq, d, t, y)[0]
        below.update(closure_residual_mm=float(np.linalg.norm(r)), largest_clearance_use=float(np.max(np.abs(y))))

    # maximum: sequential linear programming with a shrinking trust region
    qq = q0.copy()
    t, y, radius, steps = 0.0, np.zeros(n_g), 1.0, 0
    for steps in range(1, iterations + 1):
        out = step_lp(qq, t, y, radius)
        if out is None:
            break
        dq, y_new, t_new = out
        qq[0, passive] += dq
        change = abs(t_new - t)
        t, y = t_new, y_new
        radius = max(radius * 0.6, 1e-9) if steps > 1 else 0.2
        if change <= 1e-9 * max(abs(t), 1e-300) and steps > 3:
            break
    xi = t * d + model.columns @ (y * model.bounds)
    closed = kin.assemble(qq, xi, tol=1e-13)
    return {"linear": float(value), "below": below, "value": t,
            "relative_difference": abs(t - value) / max(abs(value), 1e-300),
            "closure_residual_mm": float(closed.residual[0]), "largest_clearance_use": float(np.max(np.abs(y))) if n_g else 0.0,
            "iterations": steps}
