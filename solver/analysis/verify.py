"""Nonlinear confirmation of stationarity verdicts by re-assembly with finite defects.

Units: defects in rad and mm; residuals in mm (rotations multiplied by the length
scale of the mechanism).

A verdict of the linear analysis (paper 1, eq. 3) is a statement about the
first-order behaviour.  Here each one is checked on the full nonlinear closure: the
mechanism is given one finite defect (or a combination), its passive joints are
re-assembled by least squares at several configurations, and the remaining closure
residual is measured, at two defect sizes ``delta`` and ``delta/10``:

* a *forced* defect leaves a residual of order ``delta`` that matches the linear
  prediction ``|P_null(B) A d|`` (the defect's part the passive joints cannot absorb);
* a *free* defect (or a coupled relation satisfied) leaves a residual of order
  ``delta**2`` or round-off;
* a *free influential* defect moves the output frame by order ``delta``, a
  *non-influent* one by order ``delta**2`` at most;
* a *gauge* parameter carries no geometry of its own: the mechanism with a finite
  defect on it is rebuilt from the other parameters (:func:`gauge_equivalent`, from the
  rule that made it a gauge, not from the linear matrices), and both are re-assembled:
  their closure residuals and output poses must agree to round-off at both sizes.

One parameter at a time is not enough (a verdict can hold for every single direction and
fail for their sum, and four configurations can miss a wrong one), so the checks are also
made **in combination**, at *every* analysed configuration (:func:`combination_checks`):

* a random admissible defect vector, all admissible directions at once with every
  component of realistic size (at most ``delta``), re-assembles to round-off or to second
  order in the defect;
* for each relation, the same vector plus a component that violates only that relation
  does not re-assemble: its residual is first order and matches the linear prediction.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.frames import so3_log
from hyperstat.solver.kinematics.model import Joint, Mechanism
from hyperstat.solver.analysis.stationarity import StationarityResult, gauge_parameters

__all__ = ["Check", "verify", "combination_checks", "reassembly_residual", "gauge_equivalent"]


@dataclass
class Check:
    """One nonlinear check.

    Attributes
    ----------
    subject : str
        Parameter name, or relation text.
    kind : str
        ``"parameter"``, ``"gauge"``, ``"relation satisfied"`` or ``"relation violated"``.
    expected : str
        What the linear analysis claims: ``"assembles"``, ``"does not assemble"`` or, for
        a gauge, ``"equivalent"`` (the same mechanism as its equivalent without it).
    delta : float
        Dimensionless defect size (rad, or mm per length scale).
    residual : float
        Largest closure residual after re-assembly over the configurations (mm); for a
        gauge, the largest difference of output pose between the mechanism with the
        gauge defect and its equivalent (mm, rotations times the length scale).
    residual_small : float
        The same with a defect ten times smaller (mm).
    predicted : float
        Linear prediction of the residual for ``delta`` (mm).
    output_change : float
        Largest change of the output pose after re-assembly (mm, rotations times the
        length scale).
    confirmed : bool
        Whether the nonlinear behaviour matches the verdict.
    note : str
        One line of evidence.
    """

    subject: str
    kind: str
    expected: str
    delta: float
    residual: float
    residual_small: float
    predicted: float
    output_change: float
    confirmed: bool
    note: str

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return asdict(self)


def _pose_change(kin: Kinematics, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    rot = np.linalg.norm(so3_log(t1[:, :3, :3] @ np.swapaxes(t0[:, :3, :3], 1, 2)), axis=1)
    pos = np.linalg.norm(t1[:, :3, 3] - t0[:, :3, 3], axis=1)
    return rot * kin.length_scale + pos


def reassembly_residual(kin: Kinematics, q0: np.ndarray, xi: np.ndarray) -> tuple[float, float]:
    """Largest closure residual (mm) after least-squares re-assembly with defects ``xi``,
    and largest change of the output pose (mm, rotations times the length scale)."""
    nominal = kin.evaluate(q0, jacobians=False)
    res = kin.assemble(q0.copy(), xi)
    st = kin.evaluate(res.q, xi, jacobians=False)
    return float(np.max(res.residual)), float(np.max(_pose_change(kin, nominal.output_pose, st.output_pose)))


def gauge_equivalent(mechanism: Mechanism, name: str, size: float) -> np.ndarray:
    """Defects without ``name`` that build the same mechanism as ``size`` on the gauge ``name``.

    Follows the two rules of :func:`hyperstat.solver.analysis.stationarity.gauge_parameters`:

    * normalisation: the tilted axis ``b = (n0 + size e_c) / |n0 + size e_c|`` is reached
      with the component ``c`` at zero by ``dn = t b - n0``, ``t = n0_c / b_c`` (the
      element's matrix depends on the axis only through ``b``);
    * along-axis shift of a revolute origin: ``size e_c = (size e_c - s n0) + s n0`` with
      ``s = size / n0_c``; the along-axis part ``s n0`` commutes with the rotation and
      becomes a shift ``s`` of the next element along the same axis (its ``c``).

    Parameters
    ----------
    mechanism : Mechanism
        Nominal model.
    name : str
        A gauge parameter, e.g. ``"dc2"``.
    size : float
        Defect on it (rad or mm).

    Returns
    -------
    ndarray, (n_xi,)
        The equivalent defect vector (rad / mm), zero on ``name``.

    Raises
    ------
    ValueError
        If ``name`` is not a gauge, or the equivalence needs a component the element
        does not carry.
    """
    if name not in gauge_parameters(mechanism):
        raise ValueError(f"'{name}' is not a gauge parameter of '{mechanism.name}'.")
    index = mechanism.parameter_index
    xi = np.zeros(len(index))

    def put(defects: dict, comp: str, value: float) -> None:
        if comp in defects:
            xi[index[defects[comp]]] += value
        elif abs(value) > 1e-15:
            raise ValueError(f"the equivalent of '{name}' needs component '{comp}', which its element does not carry.")

    for chain in mechanism.chains:
        for ei, el in enumerate(chain.elements):
            defects = {d.component: d.name for d in getattr(el, "defects", ())}
            if name not in defects.values():
                continue
            comp = next(c for c, n in defects.items() if n == name)
            n0 = np.asarray(el.placement.z_axis, dtype=float)
            if comp in "IJK":
                c = "IJK".index(comp)
                raw = n0.copy()
                raw[c] += size
                b = raw / np.linalg.norm(raw)
                dn = n0[c] / b[c] * b - n0
                for k, letter in enumerate("IJK"):
                    if letter != comp:
                        put(defects, letter, dn[k])
            else:
                if not (isinstance(el, Joint) and el.type == "R") or ei + 1 == len(chain.elements):
                    raise ValueError(f"'{name}' is not the shift of a revolute origin followed by an element.")
                c = "abc".index(comp)
                shift = size / n0[c]
                dp = -shift * n0
                dp[c] += size
                for k, letter in enumerate("abc"):
                    if letter != comp:
                        put(defects, letter, dp[k])
                nxt = chain.elements[ei + 1]
                put({d.component: d.name for d in getattr(nxt, "defects", ())}, "c", shift)
            return xi
    raise ValueError(f"'{name}' belongs to no element of '{mechanism.name}'.")


def verify(
    mechanism: Mechanism,
    result: StationarityResult,
    n_configurations: int = 4,
    delta: float = 1e-4,
    kinematics: Kinematics | None = None,
    combinations: bool = True,
    seed: int = 0,
) -> list[Check]:
    """Confirm every verdict and every relation by nonlinear re-assembly, alone and in combination.

    Parameters
    ----------
    mechanism : Mechanism
        Nominal model the result was computed on.
    result : StationarityResult
        Output of :func:`hyperstat.solver.analysis.stationarity.analyze`.
    n_configurations : int
        How many of the analysed configurations to re-assemble at.
    delta : float
        Dimensionless defect size: ``delta`` rad for angles, ``delta * L`` mm for
        lengths (``L`` the length scale of the mechanism).
    kinematics : Kinematics, optional
        Reuse an existing forward model.
    combinations : bool
        Add :func:`combination_checks` at every analysed configuration.
    seed : int
        Seed of the random admissible combination.

    Returns
    -------
    list of Check
    """
    kin = kinematics or Kinematics(mechanism)
    checks = _single_checks(mechanism, result, n_configurations, delta, kin)
    if combinations:
        checks += combination_checks(mechanism, result, delta=delta, kinematics=kin, seed=seed)
    return checks


def _judge(expect_assembly: bool, r1: float, r2: float, pred: float, delta: float, lc: float) -> tuple[bool, str]:
    """Verdict of one nonlinear check from the residuals at ``delta`` and ``delta / 10`` (mm)."""
    floor = 1e-9 * lc
    order = np.log10(r1 / r2) if r2 > floor and r1 > floor else float("nan")
    per_unit = r1 / (delta * lc)
    if expect_assembly:
        ok = r1 < floor or (per_unit < 1e2 * delta and not (0.5 < order < 1.5))
        note = (f"residual {r1:.2e} mm for a defect of {delta:g} (dimensionless): "
                + ("round-off" if r1 < floor else f"order {order:.2f} in the defect"))
    else:
        ok = per_unit > 1e-3 and abs(r1 - pred) <= 0.05 * pred + floor
        note = (f"residual {r1:.3e} mm against {pred:.3e} mm predicted by the linear model "
                f"(order {order:.2f} in the defect)")
    return bool(ok), note


def combination_checks(
    mechanism: Mechanism,
    result: StationarityResult,
    delta: float = 1e-4,
    kinematics: Kinematics | None = None,
    seed: int = 0,
) -> list[Check]:
    """Verdicts checked in combination at every analysed configuration.

    A random vector ``u`` of the admissible subspace (``result.admissible_basis``, all
    directions at once, scaled so that its largest component is ``delta``: ``delta`` rad,
    ``delta * L`` mm) must re-assemble to round-off or to second order; for each relation,
    ``u`` plus ``delta`` times the relation's own (unit, dimensionless) coefficient vector
    violates that relation and must leave a first-order residual matching the linear
    prediction ``|(I - B B^+) A v|`` (paper 1, eq. 3).  Both sizes ``delta`` and
    ``delta / 10`` are re-assembled.

    Parameters
    ----------
    mechanism : Mechanism
        Nominal model.
    result : StationarityResult
        Output of :func:`hyperstat.solver.analysis.stationarity.analyze` (its configurations
        are all used).
    delta : float
        Largest dimensionless component of the defects.
    kinematics : Kinematics, optional
    seed : int
        Seed of the random admissible vector.

    Returns
    -------
    list of Check
        Kinds ``"combination admissible"`` and ``"combination, relation violated"``.
    """
    kin = kinematics or Kinematics(mechanism)
    basis = result.admissible_basis
    q0 = result.configurations
    if basis is None or q0 is None or basis.shape[1] == 0:
        return []
    scale = kin.parameter_scale
    lc = kin.length_scale
    rng = np.random.default_rng(seed)
    u = basis @ rng.normal(size=basis.shape[1])
    u *= delta / np.max(np.abs(u))
    nominal = kin.evaluate(q0)
    a = kin.dimensionless(nominal.closure_xi, scale)
    b = kin.dimensionless(nominal.closure_q[:, :, mechanism.passive], kin.joint_scale[mechanism.passive])
    proj_out = np.eye(a.shape[1])[None] - b @ np.linalg.pinv(b, rcond=1e-8)

    def run(direction: np.ndarray) -> tuple[float, float, float, float]:
        out, change = [], 0.0
        for f in (1.0, 0.1):
            residual, moved = reassembly_residual(kin, q0, direction * f * scale)
            out.append(residual)
            if f == 1.0:
                change = moved
        pred = np.einsum("kij,kj->ki", proj_out, a @ direction)
        return out[0], out[1], float(np.max(np.linalg.norm(pred, axis=1))) * lc, change

    checks = []
    r1, r2, pred, change = run(u)
    size = float(np.max(np.abs(u)))
    ok, note = _judge(True, r1, r2, pred, size, lc)
    checks.append(Check(f"all {basis.shape[1]} admissible directions at once", "combination admissible",
                        "assembles", size, r1, r2, pred, change, ok,
                        f"{note}; {len(q0)} configurations"))
    index = mechanism.parameter_index
    for rel in result.relations:
        coeffs = np.zeros(kin.n_xi)
        for name, c in rel.terms.items():
            coeffs[index[name]] = c * scale[index[name]]
        v = coeffs / np.linalg.norm(coeffs) * delta
        r1, r2, pred, change = run(u + v)
        # the admissible part re-assembles: the residual is the violated part's, first order in delta
        ok, note = _judge(False, r1, r2, pred, delta, lc)
        checks.append(Check(rel.text, "combination, relation violated", "does not assemble", delta, r1, r2, pred,
                            change, ok, f"{note}; with all admissible directions; {len(q0)} configurations"))
    return checks


def _single_checks(mechanism: Mechanism, result: StationarityResult, n_configurations: int, delta: float,
                   kin: Kinematics) -> list[Check]:
    """The one-parameter checks of :func:`verify` on the first ``n_configurations``."""
    q0 = result.configurations[:n_configurations]
    scale = kin.parameter_scale  # physical = dimensionless * scale
    lc = kin.length_scale
    nominal = kin.evaluate(q0)
    a = kin.dimensionless(nominal.closure_xi, scale)
    b = kin.dimensionless(nominal.closure_q[:, :, mechanism.passive], kin.joint_scale[mechanism.passive])
    proj_out = np.eye(a.shape[1])[None] - b @ np.linalg.pinv(b, rcond=1e-8)

    def run(direction: np.ndarray) -> tuple[float, float, float, float]:
        """Residuals at delta and delta/10 (mm), linear prediction (mm), output change (mm)."""
        out = []
        change = 0.0
        for size in (delta, delta / 10.0):
            residual, moved = reassembly_residual(kin, q0, direction * size * scale)
            out.append(residual)
            if size == delta:
                change = moved
        pred = np.einsum("kij,kj->ki", proj_out, a @ direction)
        predicted = float(np.max(np.linalg.norm(pred, axis=1))) * delta * lc
        return out[0], out[1], predicted, change

    def judge(expect_assembly: bool, r1: float, r2: float, pred: float) -> tuple[bool, str]:
        floor = 1e-9 * lc
        order = np.log10(r1 / r2) if r2 > floor and r1 > floor else float("nan")
        per_unit = r1 / (delta * lc)
        if expect_assembly:
            ok = r1 < floor or (per_unit < 1e2 * delta and not (0.5 < order < 1.5))
            note = (f"residual {r1:.2e} mm for a defect of {delta:g} (dimensionless): "
                    + ("round-off" if r1 < floor else f"order {order:.2f} in the defect"))
        else:
            ok = per_unit > 1e-3 and abs(r1 - pred) <= 0.05 * pred + floor
            note = (f"residual {r1:.3e} mm against {pred:.3e} mm predicted by the linear model "
                    f"(order {order:.2f} in the defect)")
        return bool(ok), note

    checks: list[Check] = []
    n_xi = kin.n_xi
    for j, p in enumerate(result.parameters):
        if p.verdict == "gauge":
            checks.append(_gauge_check(kin, q0, p.name, j, delta, scale[j]))
            continue
        e = np.zeros(n_xi)
        e[j] = 1.0
        r1, r2, pred, change = run(e)
        if p.verdict == "forced":
            ok, note = judge(False, r1, r2, pred)
            checks.append(Check(p.name, "parameter", "does not assemble", delta, r1, r2, pred, change, ok, note))
        elif p.verdict == "free":
            ok, note = judge(True, r1, r2, pred)
            moved = change / (delta * lc)
            if p.influential:
                ok = ok and moved > 1e-3
                note += f"; output moves {change:.3e} mm (influential)"
            else:
                ok = ok and moved < 1e2 * delta
                note += f"; output moves {change:.3e} mm (non-influent: second order)"
            checks.append(Check(p.name, "parameter", "assembles", delta, r1, r2, pred, change, ok, note))
        else:  # coupled: alone it must not assemble
            ok, note = judge(False, r1, r2, pred)
            checks.append(Check(p.name, "parameter", "does not assemble", delta, r1, r2, pred, change, ok, note))
    basis = result.admissible_basis
    index = mechanism.parameter_index
    for rel in result.relations:
        coeffs = np.zeros(n_xi)
        for name, c in rel.terms.items():
            coeffs[index[name]] = c * scale[index[name]]  # dimensionless coefficients
        violated = coeffs / np.linalg.norm(coeffs)
        satisfied = np.zeros(n_xi)
        if basis is not None and basis.size:
            # the admissible direction closest to one of the relation's parameters
            candidates = [basis @ basis[j] for j in np.nonzero(coeffs)[0]]
            satisfied = max(candidates, key=np.linalg.norm)
        if np.linalg.norm(satisfied) > 1e-9:
            satisfied /= np.linalg.norm(satisfied)
            r1, r2, pred, change = run(satisfied)
            ok, note = judge(True, r1, r2, pred)
            checks.append(Check(rel.text, "relation satisfied", "assembles", delta, r1, r2, pred, change, ok, note))
        r1, r2, pred, change = run(violated)
        ok, note = judge(False, r1, r2, pred)
        checks.append(Check(rel.text, "relation violated", "does not assemble", delta, r1, r2, pred, change, ok, note))
    return checks


def _gauge_check(kin: Kinematics, q0: np.ndarray, name: str, j: int, delta: float, scale: float) -> Check:
    """Gauge ``name``: the mechanism with a finite defect on it against its rebuilt equivalent."""
    lc = kin.length_scale
    differences, residuals, moved = [], [], 0.0
    for size in (delta, delta / 10.0):
        xi = np.zeros(kin.n_xi)
        xi[j] = size * scale
        try:
            other = gauge_equivalent(kin.mechanism, name, size * scale)
        except ValueError as err:  # the rule's equivalence is not available: the verdict is not confirmed
            return Check(name, "gauge", "equivalent", delta, float("nan"), float("nan"), 0.0, float("nan"), False,
                         f"no equivalent without it: {err}")
        res_a = kin.assemble(q0.copy(), xi)
        res_b = kin.assemble(q0.copy(), other)
        pose_a = kin.evaluate(res_a.q, xi, jacobians=False).output_pose
        pose_b = kin.evaluate(res_b.q, other, jacobians=False).output_pose
        differences.append(float(np.max(_pose_change(kin, pose_a, pose_b))))
        residuals.append(float(np.max(np.abs(res_a.residual - res_b.residual))))
        if size == delta:
            moved = float(np.max(_pose_change(kin, kin.evaluate(q0, jacobians=False).output_pose, pose_a)))
    floor = 1e-9 * lc
    ok = max(differences) < floor and max(residuals) < floor
    note = (f"the same mechanism as its equivalent without it: output poses differ by {differences[0]:.1e} mm, "
            f"closure residuals by {residuals[0]:.1e} mm (round-off below {floor:.1e})")
    return Check(name, "gauge", "equivalent", delta, differences[0], differences[1], 0.0, moved, bool(ok), note)

