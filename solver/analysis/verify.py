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
* the same kind of vector at realistic magnitudes (1 mrad, 0.1 mm) is made to close
  *exactly* at every configuration by the smallest defect correction, found by Gauss-Newton
  on the defects and all joint variables together (:func:`closing_correction`): the closure
  residual after the correction is round-off, and the correction is second order in the
  defect (``|c| ~ |u|^2``).  That is what "admissible" claims: the admissible subspace is the
  tangent space of a real family of assemblable mechanisms, and a random point of it lies
  within ``O(|u|^2)`` of that family.  A direction that only looks admissible (a forced
  one in the basis) needs a first-order correction and is caught; so does an admissible
  subspace that is the span of several families meeting at the nominal geometry (an
  isogram: planar four-bars of any link lengths, and Bennett linkages, which need equal
  opposite links), where each family assembles but not every combination;
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
from hyperstat.solver.threads import limited_blas

__all__ = ["Check", "Correction", "verify", "combination_checks", "closing_correction", "exact_closure_check",
           "reassembly_residual", "gauge_equivalent"]


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
    correction : float, optional
        Kind ``"combination admissible, closed exactly"`` only: size of the smallest defect
        correction that closes every loop at every configuration, relative to the defect
        (``|c| / |u|``, dimensionless norms); second order means about ``|u|``.
    correction_small : float, optional
        The same with a defect ten times smaller (ten times smaller if second order).
    uncorrected : float, optional
        Closure residual before the correction (mm), for the defect of size ``delta``.
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
    correction: float | None = None
    correction_small: float | None = None
    uncorrected: float | None = None

    def to_dict(self) -> dict:
        """JSON-ready dictionary (a gauge's check is named for what it confirms: ``equivalent``)."""
        out = asdict(self)
        if out["kind"] == "gauge":
            out["kind"] = "equivalent"
        return out


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


@dataclass
class Correction:
    """Result of :func:`closing_correction`.

    Attributes
    ----------
    xi : ndarray, (n_xi,)
        The corrected defects ``xi + c`` (rad / mm).
    q : ndarray, (K, n_q)
        The configurations that close with them (actuated values unchanged).
    correction : float
        ``|c| / |u|``: dimensionless norm of the correction over that of the starting defect
        (angles in rad, lengths in mm per length scale).
    residual : float
        Largest closure residual after the correction (mm, rotations times the length scale),
        measured by an independent least-squares re-assembly from the nominal configurations.
    iterations : int
        Gauss-Newton iterations used.
    """

    xi: np.ndarray
    q: np.ndarray
    correction: float
    residual: float
    iterations: int


def _dimensionless_residual(kin: Kinematics, residual: np.ndarray) -> np.ndarray:
    """Closure residual with the position rows divided by the length scale."""
    r = residual.reshape(residual.shape[0], -1, 6).copy()
    r[:, :, 3:] /= kin.length_scale
    return r.reshape(residual.shape)


@limited_blas
def closing_correction(
    kin: Kinematics,
    q0: np.ndarray,
    xi: np.ndarray,
    max_iter: int = 30,
) -> Correction:
    """Smallest defect correction that makes every loop close exactly at every configuration.

    Solves, for the defects ``u = xi / s`` (dimensionless: rad, mm per length scale ``L``),

    ``min |c|  subject to  r_k(q_k, (u + c) s) = 0  for every configuration k``,

    with the passive joints ``q_k`` of every configuration free and the actuated ones held,
    by Gauss-Newton on ``(c, q_1..q_K)`` together.  Linearised at the current point, the
    passive joints absorb what they can (``dq_k = -B_k^+ (r_k + A_k dc)``) and what remains,
    ``P_k (r_k + A_k dc) = 0`` with ``P_k = I - B_k B_k^+`` (paper 1, eq. 3), is a condition on
    the defects only; the new correction is the minimum-norm solution
    ``c+ = M^+ (M c - P r)`` of the stacked conditions ``M = [P_k A_k]`` (dimensionless), with
    ``M^+`` truncated at ``1e-8`` of the largest singular value (the rank rule of the analysis).
    It is re-evaluated at every iterate, not frozen at the analysis rank: at a finite defect
    the rank can be larger than at the nominal geometry (on an isogram, a combination of the
    spherical and the Bennett modes: the direction that separates the two families gets a
    singular value of the order of the defect), and the correction must be allowed to use it.
    The iteration converges quadratically when the defects are near a real family of
    assemblable mechanisms; ``|c|`` is then about the distance to that family, of second order in
    ``|u|`` when ``u`` lies in the admissible subspace (its tangent space), of first order when
    ``u`` has a forced part.

    Parameters
    ----------
    kin : Kinematics
        Forward model of the nominal mechanism.
    q0 : ndarray, (K, n_q)
        Nominal assembled configurations (the actuated values are kept).
    xi : ndarray, (n_xi,)
        Starting defects (rad / mm).
    max_iter : int
        Largest number of Gauss-Newton iterations.

    Returns
    -------
    Correction
    """
    return _closing_correction(kin, q0, xi, max_iter)


def _closing_correction(kin: Kinematics, q0: np.ndarray, xi: np.ndarray, max_iter: int) -> Correction:
    """Body of :func:`closing_correction`."""
    passive = kin.mechanism.passive
    scale = kin.parameter_scale
    jscale = kin.joint_scale[passive]
    u = np.asarray(xi, dtype=float) / scale
    c = np.zeros_like(u)
    q = kin.assemble(q0.copy(), xi).q
    it = 0
    while it < max_iter:
        st = kin.evaluate(q, (u + c) * scale)
        r = _dimensionless_residual(kin, st.residual)
        if float(np.max(np.abs(r), initial=0.0)) < 1e-14:  # closed to round-off (dimensionless): no step
            break
        it += 1
        a = kin.dimensionless(st.closure_xi, scale)
        if len(passive):
            b = kin.dimensionless(st.closure_q[:, :, passive], jscale)
            bp = np.linalg.pinv(b, rcond=1e-8)
            proj = np.eye(a.shape[1])[None] - b @ bp
        else:
            bp = None
            proj = np.broadcast_to(np.eye(a.shape[1]), (a.shape[0],) + (a.shape[1],) * 2)
        m = (proj @ a).reshape(-1, a.shape[2])
        rhs = (proj @ r[..., None]).reshape(-1)
        w, sv, vt = np.linalg.svd(m, full_matrices=False)
        keep = int(np.sum(sv > 1e-8 * sv[0])) if sv.size and sv[0] > 0 else 0  # no constraint left: c stays
        target = m @ c - rhs
        c_new = vt[:keep].T @ ((w[:, :keep].T @ target) / sv[:keep])
        dc = c_new - c
        c = c_new
        if bp is not None:
            dq = -(bp @ (r + np.einsum("kij,j->ki", a, dc))[..., None])[..., 0]
            q[:, passive] += dq * jscale
            step = float(np.max(np.abs(dq)))
        else:
            step = 0.0
        step = max(step, float(np.max(np.abs(dc), initial=0.0)))
        if step < 1e-14:  # nothing left to move
            break
    fixed = (u + c) * scale
    final = kin.assemble(q0.copy(), fixed, tol=1e-13, max_iter=60)
    return Correction(fixed, final.q, float(np.linalg.norm(c) / max(np.linalg.norm(u), 1e-300)),
                      float(np.max(final.residual)), it)


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


@limited_blas
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
    realistic: tuple[float, float] = (1e-3, 0.1),
) -> list[Check]:
    """Verdicts checked in combination at every analysed configuration.

    A random vector ``u`` of the admissible subspace (``result.admissible_basis``, all
    directions at once, scaled so that its largest component is ``delta``: ``delta`` rad,
    ``delta * L`` mm) must re-assemble to round-off or to second order; for each relation,
    ``u`` plus ``delta`` times the relation's own (unit, dimensionless) coefficient vector
    violates that relation and must leave a first-order residual matching the linear
    prediction ``|(I - B B^+) A v|`` (paper 1, eq. 3).  Both sizes ``delta`` and
    ``delta / 10`` are re-assembled.  A second random admissible vector, at realistic
    magnitudes, is closed exactly by the smallest correction (:func:`exact_closure_check`).

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
        Seed of the random admissible vectors.
    realistic : (float, float)
        Largest angle (rad) and largest length (mm) of the vector closed exactly.

    Returns
    -------
    list of Check
        Kinds ``"combination admissible"``, ``"combination admissible, closed exactly"`` and
        ``"combination, relation violated"``.
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
    checks.append(exact_closure_check(mechanism, kin, q0, basis @ rng.normal(size=basis.shape[1]), realistic,
                                      f"all {basis.shape[1]} admissible directions"))
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


def exact_closure_check(
    mechanism: Mechanism,
    kin: Kinematics,
    q0: np.ndarray,
    direction: np.ndarray,
    realistic: tuple[float, float] = (1e-3, 0.1),
    subject: str = "admissible directions",
) -> Check:
    """An admissible defect vector made to close exactly at every configuration (:func:`closing_correction`).

    ``direction`` (dimensionless, in the admissible subspace) is scaled so that its largest
    angle is ``realistic[0]`` rad and its largest length ``realistic[1]`` mm (whichever is
    reached first), then ten times smaller.  At both sizes the smallest correction ``c`` that
    closes every loop at every configuration is computed, with every configuration's passive
    joints re-solved.  Confirmed when the closure residual after the correction is round-off
    (below ``1e-12 L``) and ``|c| / |u|`` falls about tenfold with the defect (``|c| ~ |u|^2``:
    second order, so the admissible subspace is tangent to a real family of assemblable
    mechanisms), or ``|c|`` is round-off itself.  A correction of first order (``|c| / |u|``
    the same at both sizes) means that the admissible directions do not all belong to one
    assemblable family: the note names the parameters the correction is on.

    Parameters
    ----------
    mechanism : Mechanism
    kin : Kinematics
    q0 : ndarray, (K, n_q)
        Nominal assembled configurations.
    direction : ndarray, (n_xi,)
        Dimensionless admissible direction (rad, mm per length scale).
    realistic : (float, float)
        Largest angle (rad) and length (mm) of the larger defect.
    subject : str
        What ``direction`` combines (for the check's subject).

    Returns
    -------
    Check
        Kind ``"combination admissible, closed exactly"``: ``residual`` (mm) after the
        correction, ``correction`` and ``correction_small`` (``|c| / |u|``), ``uncorrected``
        (mm, the closure residual of the plain least-squares re-assembly).

    Raises
    ------
    ValueError
        If ``direction`` is zero.
    """
    scale = kin.parameter_scale
    lc = kin.length_scale
    is_length = np.array([p.unit == "mm" for p in mechanism.parameters])
    phys = direction * scale
    limits = []
    if np.any(~is_length) and np.max(np.abs(phys[~is_length])) > 0:
        limits.append(realistic[0] / np.max(np.abs(phys[~is_length])))
    if np.any(is_length) and np.max(np.abs(phys[is_length])) > 0:
        limits.append(realistic[1] / np.max(np.abs(phys[is_length])))
    if not limits:
        raise ValueError("exact_closure_check: the direction is zero.")
    xi = phys * min(limits)
    size = float(np.max(np.abs(xi / scale)))
    uncorrected = reassembly_residual(kin, q0, xi)[0]
    big = closing_correction(kin, q0, xi)
    small = closing_correction(kin, q0, xi / 10.0)
    floor = 1e-12 * lc
    closed = big.residual < floor and small.residual < floor
    roundoff = big.correction < 1e-9
    order = np.log10(big.correction / small.correction) if small.correction > 1e-12 else float("nan")
    second = roundoff or order > 0.7
    angle = float(np.max(np.abs(xi[~is_length]))) if np.any(~is_length) else 0.0
    length = float(np.max(np.abs(xi[is_length]))) if np.any(is_length) else 0.0
    note = (f"defects up to {angle * 1e3:.3g} mrad and {length:.3g} mm ({len(q0)} configurations): "
            f"closure residual {uncorrected:.2e} mm by least-squares re-assembly, {big.residual:.2e} mm "
            f"({small.residual:.2e} mm at a tenth) after the smallest correction, which is "
            f"{big.correction:.2e} of the defect ({small.correction:.2e} at a tenth): ")
    if roundoff:
        note += "round-off: the combination assembles as it is"
    elif second:
        note += f"second order (order {order + 1:.2f} in the defect): the admissible subspace is tangent to a real family"
    else:
        corr = big.xi / scale - xi / scale
        names = [p.name for p in mechanism.parameters]
        top = [names[i] for i in np.argsort(-np.abs(corr))[:4] if abs(corr[i]) > 0.1 * np.max(np.abs(corr))]
        note += (f"FIRST order (order {order + 1:.2f}), on {', '.join(top)}: these admissible directions are "
                 "each assemblable but not in every combination (several assemblable families meet at the nominal "
                 "geometry and the admissible subspace is their span)")
    if not closed:
        note += "; NOT closed to round-off"
    return Check(f"{subject} at once, closed exactly by the smallest correction",
                 "combination admissible, closed exactly", "closes after a second-order correction", size,
                 big.residual, small.residual, 0.0, 0.0, bool(closed and second), note,
                 correction=big.correction, correction_small=small.correction, uncorrected=uncorrected)


class _Reassembly:
    """Re-assembly of many defect vectors at the same configurations, in one batched call.

    Each defect vector is given the configurations ``q0``; all of them are stacked into one
    batch for :meth:`Kinematics.assemble` (a Gauss-Newton per configuration, independent of
    the others), which gives the same residuals as one call per vector without the Python
    overhead of hundreds of small calls.
    """

    def __init__(self, kin: Kinematics, q0: np.ndarray) -> None:
        self.kin, self.q0 = kin, q0
        self.xis: list[np.ndarray] = []

    def add(self, xi: np.ndarray) -> int:
        """Queue the defects ``xi`` (rad / mm); returns the index of their results."""
        self.xis.append(np.asarray(xi, dtype=float))
        return len(self.xis) - 1

    def run(self) -> None:
        """Assemble everything queued: ``residual`` (D, K) in mm, ``pose`` (D, K, 4, 4), ``change`` (D,) in mm."""
        kin, k = self.kin, len(self.q0)
        d = len(self.xis)
        nominal = kin.evaluate(self.q0, jacobians=False).output_pose
        if d == 0:
            self.residual, self.pose, self.change = np.zeros((0, k)), np.zeros((0, k, 4, 4)), np.zeros(0)
            return
        xi = np.repeat(np.array(self.xis), k, axis=0)
        res = kin.assemble(np.tile(self.q0, (d, 1)), xi)
        pose = kin.evaluate(res.q, xi, jacobians=False).output_pose
        self.residual = res.residual.reshape(d, k)
        self.pose = pose.reshape(d, k, 4, 4)
        self.change = _pose_change(kin, np.tile(nominal, (d, 1, 1)), pose).reshape(d, k).max(axis=1)


def _single_checks(mechanism: Mechanism, result: StationarityResult, n_configurations: int, delta: float,
                   kin: Kinematics) -> list[Check]:
    """The one-parameter checks of :func:`verify` on the first ``n_configurations``.

    Every defect of every check is queued first and re-assembled in one batch (:class:`_Reassembly`).
    """
    q0 = result.configurations[:n_configurations]
    scale = kin.parameter_scale  # physical = dimensionless * scale
    lc = kin.length_scale
    nominal = kin.evaluate(q0)
    a = kin.dimensionless(nominal.closure_xi, scale)
    b = kin.dimensionless(nominal.closure_q[:, :, mechanism.passive], kin.joint_scale[mechanism.passive])
    proj_out = np.eye(a.shape[1])[None] - b @ np.linalg.pinv(b, rcond=1e-8)
    batch = _Reassembly(kin, q0)

    def queue(direction: np.ndarray) -> tuple[int, int, float]:
        """Queue the direction at delta and delta/10; the linear prediction of the residual (mm)."""
        i1 = batch.add(direction * delta * scale)
        i2 = batch.add(direction * delta / 10.0 * scale)
        pred = np.einsum("kij,kj->ki", proj_out, a @ direction)
        return i1, i2, float(np.max(np.linalg.norm(pred, axis=1))) * delta * lc

    def results(job: tuple[int, int, float]) -> tuple[float, float, float, float]:
        """Residuals at delta and delta/10 (mm), linear prediction (mm), output change (mm)."""
        i1, i2, pred = job
        return float(np.max(batch.residual[i1])), float(np.max(batch.residual[i2])), pred, float(batch.change[i1])

    def judge(expect_assembly: bool, r1: float, r2: float, pred: float) -> tuple[bool, str]:
        return _judge(expect_assembly, r1, r2, pred, delta, lc)

    n_xi = kin.n_xi
    plan: list = []  # (kind, payload) in the order of the checks
    for j, p in enumerate(result.parameters):
        if p.verdict == "gauge":
            plan.append(("gauge", _queue_gauge(batch, kin, p.name, j, delta, scale[j])))
            continue
        e = np.zeros(n_xi)
        e[j] = 1.0
        plan.append(("parameter", (p, queue(e))))
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
            plan.append(("relation satisfied", (rel, queue(satisfied))))
        plan.append(("relation violated", (rel, queue(violated))))
    batch.run()

    checks: list[Check] = []
    for kind, payload in plan:
        if kind == "gauge":
            checks.append(_gauge_check(batch, kin, delta, *payload))
            continue
        subject, job = payload
        r1, r2, pred, change = results(job)
        if kind == "relation satisfied":
            ok, note = judge(True, r1, r2, pred)
            checks.append(Check(subject.text, kind, "assembles", delta, r1, r2, pred, change, ok, note))
        elif kind == "relation violated":
            ok, note = judge(False, r1, r2, pred)
            checks.append(Check(subject.text, kind, "does not assemble", delta, r1, r2, pred, change, ok, note))
        elif subject.verdict == "free":
            ok, note = judge(True, r1, r2, pred)
            moved = change / (delta * lc)
            if subject.influential:
                ok = ok and moved > 1e-3
                note += f"; output moves {change:.3e} mm (influential)"
            else:
                ok = ok and moved < 1e2 * delta
                note += f"; output moves {change:.3e} mm (non-influent: second order)"
            checks.append(Check(subject.name, "parameter", "assembles", delta, r1, r2, pred, change, ok, note))
        else:  # forced, or coupled: alone it must not assemble
            ok, note = judge(False, r1, r2, pred)
            checks.append(Check(subject.name, "parameter", "does not assemble", delta, r1, r2, pred, change, ok, note))
    return checks


def _queue_gauge(batch: _Reassembly, kin: Kinematics, name: str, j: int, delta: float, scale: float) -> tuple:
    """Queue the gauge ``name`` with a finite defect and its rebuilt equivalent, at delta and delta/10."""
    pairs = []
    for size in (delta, delta / 10.0):
        xi = np.zeros(kin.n_xi)
        xi[j] = size * scale
        try:
            other = gauge_equivalent(kin.mechanism, name, size * scale)
        except ValueError as err:  # the rule's equivalence is not available: the verdict is not confirmed
            return name, str(err)
        pairs.append((batch.add(xi), batch.add(other)))
    return name, pairs


def _gauge_check(batch: _Reassembly, kin: Kinematics, delta: float, name: str, pairs) -> Check:
    """Gauge ``name``: the mechanism with a finite defect on it against its rebuilt equivalent."""
    lc = kin.length_scale
    if isinstance(pairs, str):
        return Check(name, "gauge", "equivalent", delta, float("nan"), float("nan"), 0.0, float("nan"), False,
                     f"no equivalent without it: {pairs}")
    differences, residuals = [], []
    for ia, ib in pairs:
        differences.append(float(np.max(_pose_change(kin, batch.pose[ia], batch.pose[ib]))))
        residuals.append(float(np.max(np.abs(batch.residual[ia] - batch.residual[ib]))))
    moved = float(batch.change[pairs[0][0]])
    floor = 1e-9 * lc
    ok = max(differences) < floor and max(residuals) < floor
    note = (f"the same mechanism as its equivalent without it: output poses differ by {differences[0]:.1e} mm, "
            f"closure residuals by {residuals[0]:.1e} mm (round-off below {floor:.1e})")
    return Check(name, "gauge", "equivalent", delta, differences[0], differences[1], 0.0, moved, bool(ok), note)
