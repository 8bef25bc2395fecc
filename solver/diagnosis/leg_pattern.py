"""Step 4 of the diagnosis, on a parallel machine: does a named ``leg-thermal`` look like legs growing with heat?

Units: expansion coefficients in 1/degC, leg offsets in mm/degC, chi-squares in units of the noise variance.

``leg-thermal`` (:class:`~hyperstat.solver.diagnosis.effects.LegThermal`) has one coefficient per leg,
``dq_j = kappa_j (T - 20 degC) q_j``, so that the selection can name it on the legs that need it.  Physically it
is the legs of one machine, of one material, at about one temperature, each growing in proportion to its own
length: every leg's coefficient near one common value.  Any leg-length change that follows the temperature fits
one leg's coefficient: a leg seat, a joint or a mounting that moves with the temperature changes that leg's
length by an offset ``r_j (T - 20 degC)`` (mm/degC), and over a leg stroke short against the leg's length
(the Tripteor X7: 300 mm of stroke on 840 mm legs) ``kappa_j q_j`` is nearly a constant ``r_j`` too.  Two
checks keep such an answer honest:

* the family ``leg-temperature-offset`` (:func:`leg_offset_family`): each leg longer by its own offset
  proportional to the temperature, not to its length; it joins a named effect's equivalence set when it
  reproduces that effect's signature within the noise (:mod:`.equivalence`);
* the pattern across the legs (:func:`leg_thermal_pattern`): the coefficients of every leg, fitted together
  with the geometry and the other named effects, against legs that grow alike (each within half of one common
  coefficient: a leg 50 % warmer or cooler than the others).  When the data refuse that (a chi-square p-value
  below 1e-3), the fit is outside leg-thermal's physical prior: the whole change on some legs where leg-thermal
  predicts every leg in proportion to its length.  The answer then keeps the effect that reproduces the data but
  says it is a leg-length change with the temperature whose cause these data cannot name, with ``confidence``
  low.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LEG_OFFSET", "LEG_OFFSET_WORDS", "LEG_SPREAD", "leg_offset_family", "leg_thermal_pattern",
           "prismatic_legs"]

#: the family "a leg's length changes by an offset that follows the temperature (its seat, a joint or a mounting
#: moves), not in proportion to its length"
LEG_OFFSET = "leg-temperature-offset"
#: the measurement that separates it from a leg growing with the temperature
LEG_OFFSET_WORDS = ("a dial gauge (or a reflector) on each leg's seat and base joint through a warm-up, and the same "
                    "poses at two temperatures with each leg over its whole stroke (a leg growing with the temperature "
                    "grows in proportion to its length, a seat or joint that moves with the temperature does not)")
#: how far one leg's coefficient may lie from the common one (a fraction of it) for legs of one material at about
#: one temperature (a leg 50 % warmer or cooler than the others)
LEG_SPREAD = 0.5
P_VALUE = 1e-3  #: the legs-grow-alike prior is refused below this p-value (the structure tests' level)
REFERENCE_DEGC = 20.0


def prismatic_legs(mechanism) -> list[tuple[int, str]]:
    """``(actuator index, joint name)`` of a parallel machine's actuated prismatic joints (its legs); [] otherwise."""
    if not (len(mechanism.chains) > 1 and mechanism.closures):
        return []
    return [(a, mechanism.joints[i].name) for a, i in enumerate(mechanism.actuated) if mechanism.joints[i].type == "P"]


def leg_offset_family(mechanism, data, act_jac: np.ndarray) -> np.ndarray | None:
    """Columns (R, 3, legs) of the family :data:`LEG_OFFSET`: leg ``j`` longer by ``r_j (T - 20 degC)`` mm.

    ``act_jac`` holds ``d row / d q_a`` at the rigid fit (positions, then orientations for 6-D data).  None on a
    serial mechanism, or without a ``temperature[degC]`` column that varies.
    """
    legs = prismatic_legs(mechanism)
    temp = data.metadata.get("temperature")
    if not legs or temp is None or np.ptp(temp) <= 0:
        return None
    dtemp = np.tile(temp - REFERENCE_DEGC, len(act_jac) // len(data))  # the same temperature on an orientation row
    return np.stack([act_jac[:, :, a] * dtemp[:, None] for a, _ in legs], axis=2)


def leg_thermal_pattern(screen, whole: np.ndarray, others: list, legs: list,
                        domain: tuple = (-2e-6, 3e-5)) -> dict:
    """Every leg's ``leg-thermal`` coefficient fitted together, against legs that grow alike (module docstring).

    The coefficients ``kappa`` of every leg are fitted (linearised, with the geometry and the other named effects)
    to the rigid residual, with their covariance ``C`` (scaled by the residual variance when it exceeds the noise).
    Legs that grow alike have coefficients within :data:`LEG_SPREAD` of one common value ``k``: the cost of that
    prior is ``min over k in leg-thermal's domain and over u_j in [k - s |k|, k + s |k|] of
    (kappa - u)^T C^-1 (kappa - u)``, a chi-square
    with ``legs - 1`` degrees of freedom when the legs do grow alike.  Below ``1e-3`` (p-value) the pattern is
    outside leg-thermal's physical prior.

    Parameters
    ----------
    screen : Screen
        Rigid residuals, weights and geometric columns (:mod:`.screening`).
    whole : ndarray, (R, 3, legs)
        The columns of ``leg-thermal`` on every leg (1/degC).
    others : list of ndarray
        Columns of the other named effects (fitted alongside).
    legs : list of str
        The legs' joint names, in the order of ``whole``'s columns.
    domain : (float, float)
        Where the common coefficient may lie (1/degC): leg-thermal's physical domain.

    Returns
    -------
    dict
        ``coefficients`` (leg -> estimate, std, 1/degC), ``common`` (their weighted mean, 1/degC), ``chi2`` (the
        cost of the prior), ``dof``, ``p_value``, ``consistent`` (bool), ``spread`` and ``words``.
    """
    from scipy.optimize import lsq_linear
    from scipy.special import chdtrc

    pre = screen.prepared()
    b = np.concatenate([pre["jw"]] + [screen.weighted(c) for c in others], axis=1)
    qb, _ = np.linalg.qr(b / np.linalg.norm(b, axis=0).clip(min=1e-300))
    x = screen.weighted(whole)
    x = x - qb @ (qb.T @ x)
    y = pre["rw"] - qb @ (qb.T @ pre["rw"])
    cov = np.linalg.pinv(x.T @ x)
    kappa = -cov @ (x.T @ y)  # residual = prediction - measurement: the correction cancels it
    dof_rows = max(len(y) - qb.shape[1] - len(legs), 1)
    scale = max(1.0, float(np.sum((y + x @ kappa) ** 2)) / dof_rows)  # an understated noise widens the intervals
    std = np.sqrt(np.clip(np.diag(cov) * scale, 0.0, None))
    lam, vec = np.linalg.eigh(x.T @ x / scale)  # C^-1 = a^T a with a (legs x legs): the costs below in legs rows
    a = (vec * np.sqrt(np.clip(lam, 0.0, None))) @ vec.T
    target = a @ kappa

    def cost(k: float) -> float:
        lo, hi = k - LEG_SPREAD * abs(k), k + LEG_SPREAD * abs(k)
        if hi - lo <= 1e-300:
            r = target - a @ np.full(len(legs), k)
            return float(r @ r)
        return 2.0 * float(lsq_linear(a, target, bounds=(np.full(len(legs), lo), np.full(len(legs), hi))).cost)

    grid = np.linspace(float(domain[0]), float(domain[1]), 121)
    costs = [cost(k) for k in grid]
    best = int(np.argmin(costs))
    step = grid[1] - grid[0]
    fine = np.linspace(max(grid[best] - step, grid[0]), min(grid[best] + step, grid[-1]), 21)
    costs_fine = [cost(k) for k in fine]
    chi2 = float(min(costs_fine))
    inv = a.T @ a  # C^-1
    ones = np.ones(len(legs))
    common = float(ones @ inv @ kappa / max(float(ones @ inv @ ones), 1e-300))  # the weighted mean of the legs
    dof = max(len(legs) - 1, 1)
    p = float(chdtrc(dof, chi2))
    consistent = bool(p >= P_VALUE)
    coefficients = {leg: {"estimate": float(k), "std": float(sd)} for leg, k, sd in zip(legs, kappa, std)}
    listed = ", ".join(f"leg {leg} {k:.2g} ± {sd:.1g}" for leg, k, sd in zip(legs, kappa, std))
    words = f"leg-thermal's coefficients fitted on every leg: {listed} /°C"
    if not consistent:
        far = sorted(legs, key=lambda leg: -abs(coefficients[leg]["estimate"] - common) / max(coefficients[leg]["std"],
                                                                                               1e-300))[0]
        words += (f"; legs of one material at about one temperature grow alike (within {100 * LEG_SPREAD:.0f} % of "
                  f"one coefficient, each in proportion to its length), and the data refuse that "
                  f"(chi-square {chi2:.3g} with {dof} degree{'s' if dof > 1 else ''} of freedom, p = {p:.2g}; leg "
                  f"{far} furthest from their weighted mean {common:.2g} /°C)")
    return {"coefficients": coefficients, "common": common, "chi2": chi2, "dof": dof, "p_value": p,
            "consistent": consistent, "spread": LEG_SPREAD, "unit": "1/degC", "words": words}
