"""Periodic effects need the residual spectrum's agreement: candidate orders from the spectrum, and the gate.

Units: angles in rad, orders in cycles per revolution; chi-square differences are in
units of the residual variance (:meth:`~hyperstat.solver.diagnosis.where.ResidualField.scale`).

* **Orders from the spectrum** (:func:`spectral_candidates`): for every revolute whose
  residual spectrum has a significant peak, the order is refined around the grid peak
  (steps of 0.05) and named by the simplest order that explains as much (within
  :data:`EQUIVALENT_CHI2`: an integer, else a half, a quarter, a tenth; a two-stage gear
  gives 1.5, :func:`simplest_order`): a general ``angle-harmonic-<k>`` on that joint joins
  the candidates, if at least one period of it fits in the range the joint moved
  (``k >= 2 pi / range``), or if ``k >= 1`` (less than a period seen: the gate must then
  establish the order against its neighbours and against a smooth trend of the joint).
* **The gate** (:func:`periodic_gate`): a periodic effect of order ``k`` is chosen only if,
  on the joint where it is significant,

  1. the spectrum agrees: ``k`` explains the residual within :data:`EQUIVALENT_CHI2` of the
     spectrum's best order (else: "the spectrum peaks at ..., not at k");
  2. the order is established: the neighbouring orders ``k - 1`` and ``k + 1`` (and, for an
     order that is not an integer, the integers around it) explain at least
     :data:`EQUIVALENT_CHI2` less.  Over a short range of the joint they alias (the
     Rayleigh limit ``|k1 - k2| range < 2 pi``) and fit as well: the order is then not
     established and the candidate is refused, with the range that would establish it.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.diagnosis.effects import harmonic_name, harmonic_order
from hyperstat.solver.diagnosis.where import SPECTRUM_ORDERS, ResidualField

__all__ = ["spectral_candidates", "screw_period", "screw_order", "periodic_gate", "refined_order", "simplest_order",
           "aliased_orders", "smooth_orders", "BOUNDED_RESOLUTION",
           "EQUIVALENT_CHI2"]

BOUNDED_RESOLUTION = 3.0  #: cycles per revolution: below it a joint's range bounds an order to its neighbours
EQUIVALENT_CHI2 = 10.0  #: chi-square difference below which the data cannot tell two fits apart (Kass-Raftery 'strong')


def _cycles(k: float) -> str:
    """``1 cycle``, ``2.5 cycles``."""
    return f"{k:g} cycle" + ("" if k == 1 else "s")


def _explained_on_grid(field: ResidualField, col: np.ndarray, qv: np.ndarray, orders: np.ndarray) -> np.ndarray:
    return np.array([field.harmonic(col, qv, float(k)) for k in orders])


def simplest_order(orders: np.ndarray, explained: np.ndarray, scale: float) -> float:
    """The simplest order among those within :data:`EQUIVALENT_CHI2` of the best (explained chi-square / ``scale``).

    Simplest: an integer, else a half, a quarter, a tenth, else the best on the grid (steps of
    0.05): a gear's orders are ratios of tooth counts, and a two-stage gear gives 1.5; among
    equally simple ones, the one that explains most.

    >>> simplest_order(np.array([1.45, 1.5, 1.55]), np.array([100.0, 98.0, 99.0]), 1.0)
    1.5
    >>> simplest_order(np.array([1.9, 1.95, 2.0]), np.array([100.0, 80.0, 60.0]), 1.0)
    1.9
    """
    best = float(explained.max())
    close = [(float(k), float(e)) for k, e in zip(orders, explained) if (best - e) / scale < EQUIVALENT_CHI2 and k > 0]
    for denominator in (1, 2, 4, 10):
        fits = [(e, k) for k, e in close if abs(k * denominator - round(k * denominator)) < 1e-6]
        if fits:
            return float(round(max(fits)[1], 2))
    return float(round(orders[int(np.argmax(explained))], 2))


def refined_order(field: ResidualField, col: np.ndarray, qv: np.ndarray, k0: float) -> tuple[float, float]:
    """The order of a joint's periodic error near ``k0``: refined in steps of 0.05 within 0.25, then the simplest
    within :data:`EQUIVALENT_CHI2` (:func:`simplest_order`).  Returns ``(order, refined grid peak)``."""
    grid = np.round(np.arange(max(k0 - 0.25, 0.3), k0 + 0.2501, 0.05), 2)
    e = _explained_on_grid(field, col, qv, grid)
    return simplest_order(grid, e, field.scale()), float(grid[int(np.argmax(e))])


def spectral_candidates(structure: dict, data, act_jac: np.ndarray) -> dict:
    """``angle-harmonic-<k>`` candidates from the significant peaks of the revolute spectra.

    Returns
    -------
    dict
        Effect name -> ``{"joints": [joint names], "peaks": {joint: refined order}}``;
        orders 1 and 2 are left out (the library tries them on every revolute).
    """
    field: ResidualField = structure["field"]
    out: dict = {}
    for spec in structure["revolute_spectra"]:
        if spec["peak_p_value"] >= structure["threshold"]:
            continue
        a = data.joints.index(spec["joint"])
        order, refined = refined_order(field, act_jac[:, :, a], data.q[:, a], spec["peak_cycles_per_revolution"])
        if order in (1.0, 2.0) or order < min(spec["resolution_cycles_per_revolution"], 1.0):
            continue  # the library tries 1 and 2; below one cycle per revolution and the resolution, a trend
        # an order of 1 or more below the resolution (less than one period seen) joins too: the gate then asks the
        # data to establish it against its neighbours and against a smooth trend of the joint (super-resolution
        # needs the signal, which the chi-square differences measure)
        entry = out.setdefault(harmonic_name(order), {"joints": [], "peaks": {}})
        entry["joints"].append(spec["joint"])
        entry["peaks"][spec["joint"]] = refined
    return out


def _spectrum_of(spec: dict, field: ResidualField | None, col: np.ndarray, qv: np.ndarray) -> tuple:
    """Orders and shares of a joint's spectrum: the rigid residual's (``spec``), or on ``field`` when given (the
    residual left after the effects already chosen: a periodic error is judged on what they leave)."""
    if field is None:
        return np.asarray(spec["cycles_per_revolution"]), np.asarray(spec["share"])
    orders = np.asarray(SPECTRUM_ORDERS)
    total = max(field.total, 1e-300)
    return orders, np.array([field.harmonic(col, qv, float(k)) / total for k in orders])


def screw_period(structure: dict, data, act_jac: np.ndarray, lead: float) -> float | None:
    """The period (mm) of the screws' periodic error when their spectra show another than the declared ``lead``.

    For the strongest significant peak of the screw spectra, the error's order in cycles per turn of
    the screw (``lead / period``) is refined (steps of 0.01 within 10 %) and named as a joint
    harmonic's is: the simplest order within :data:`EQUIVALENT_CHI2` of the best (an integer, else a
    half, a quarter, a tenth: a ball screw's error at twice per turn of its nut is order 2, period
    ``lead / 2``; :func:`simplest_order`).  The period ``lead / order`` is returned when it explains
    clearly more (:data:`EQUIVALENT_CHI2`) than a periodic error at the declared lead on that screw;
    None otherwise (the lead stands).

    >>> from types import SimpleNamespace
    >>> rng = np.random.default_rng(0)
    >>> q = rng.uniform(0.0, 60.0, (80, 1))
    >>> col = np.tile(np.eye(3)[None, :, :1], (80, 1, 1))  # the screw moves the point along x
    >>> resid = 0.01 * np.sin(2 * np.pi * q[:, 0] / 5.0 + 0.3)[:, None] * np.eye(3)[0] + rng.normal(0, 1e-3, (80, 3))
    >>> field = ResidualField(resid, np.full(80, 1e3), np.zeros((240, 0)))
    >>> peak = {"joint": "32", "peak_period_mm": 5.1, "peak_p_value": 1e-9}
    >>> st = {"field": field, "threshold": 1e-4, "spectra": [peak]}
    >>> screw_period(st, SimpleNamespace(joints=["32"], q=q), col, 10.0)  # 2 cycles per turn of a 10 mm lead
    5.0
    """
    field: ResidualField = structure["field"]
    peaks = [(sp["peak_p_value"], sp["joint"], sp["peak_period_mm"]) for sp in structure["spectra"]
             if sp["peak_p_value"] < structure["threshold"]]
    peaks += _fine_screw_peaks(field, structure["spectra"], data, act_jac)
    if not peaks:
        return None
    _, joint, p0 = min(peaks)
    a = data.joints.index(joint)
    col, qv = act_jac[:, :, a], data.q[:, a]

    def explained(period: float) -> float:
        g = np.column_stack([np.sin(2 * np.pi * qv / period), np.cos(2 * np.pi * qv / period)])
        return field.fit(col[:, :, None] * g[:, None, :])[4]

    k0 = lead / p0  # cycles per turn of the screw at the spectrum's peak
    orders = np.round(np.arange(np.floor(90.0 * k0), np.ceil(110.0 * k0) + 1.0) / 100.0, 2)
    orders = orders[orders > 0]
    e = np.array([explained(lead / k) for k in orders])
    order = simplest_order(orders, e, field.scale())
    period = lead / order
    if (explained(period) - explained(lead)) / field.scale() <= EQUIVALENT_CHI2:
        return None
    return float(f"{period:.4g}")


def _fine_screw_peaks(field: ResidualField, spectra: list, data, act_jac: np.ndarray) -> list:
    """Peaks of each screw's spectrum on a grid fine enough for its travel: ``(p-value, joint, period)`` of those
    significant at ``1e-3 / (number of frequencies scanned)`` (Bonferroni over this scan).

    The structure tests' screw spectrum has 40 periods from 2 mm to a third of the travel, evenly
    spaced in period: over a long travel its frequencies are farther apart than the travel resolves
    (``1 / travel`` cycles per mm), and an error at a short period (half a 10 mm lead over 240 mm of a
    Tripteor leg: 48 cycles) falls between two of them and is not seen.  Here the frequencies are
    evenly spaced at a quarter of ``1 / travel``, over the same periods.
    """
    out, scans = [], []
    for sp in spectra:
        a = data.joints.index(sp["joint"])
        qv = data.q[:, a]
        travel = float(np.ptp(qv))
        if travel <= 0:
            continue
        f = np.arange(1.0 / max(4.0, travel / 3.0), 0.5 + 1e-12, 0.25 / travel)  # cycles per mm
        col = act_jac[:, :, a]
        best = (1.0, 0.0)
        for fr in f:
            g = np.column_stack([np.sin(2 * np.pi * qv * fr), np.cos(2 * np.pi * qv * fr)])
            p = field.fit(col[:, :, None] * g[:, None, :])[2]
            best = min(best, (p, fr))
        scans.append((best[0], sp["joint"], 1.0 / best[1] if best[1] > 0 else np.inf, len(f)))
    n = max(sum(s[3] for s in scans), 1)
    return [(p, joint, period) for p, joint, period, _ in scans if p < 1e-3 / n]


def screw_order(period: float, lead: float) -> float:
    """Cycles per turn of the screw of a periodic error of ``period`` mm on a screw of ``lead`` mm.

    >>> screw_order(5.0, 10.0), screw_order(10.0, 10.0), screw_order(20.0, 10.0)
    (2.0, 1.0, 0.5)
    """
    return float(round(lead / period, 2))


def periodic_gate(name: str, effect, entry: dict, structure: dict, data, act_jac: np.ndarray,
                  field: ResidualField | None = None) -> dict | None:
    """Why a periodic candidate must not be chosen (``{"effect", "stage": "spectrum", "reason", ...}``), or None.

    ``entry`` is the candidate's screening entry (estimates and standard deviations of its
    sin and cos parameters per joint); of the joints where its amplitude exceeds 3 standard
    deviations (else the largest), the one whose harmonic alone explains most of the
    residual carries it and is checked against its spectrum.  ``field``: the residual after
    the effects already chosen (default: the rigid residual of ``structure``).
    """
    k = harmonic_order(name)
    if name == "angle-scale":
        return _scale_gate(name, effect, entry, structure, data, act_jac, field)
    if k is None or not hasattr(effect, "axes"):
        return None
    given = field
    field = field or structure["field"]
    est = np.array(list(entry["estimates"].values()))
    std = np.array(list(entry["std"].values()))
    sig = []
    for e in range(len(effect.axes)):
        amp = float(np.hypot(est[2 * e], est[2 * e + 1]))
        spread = float(np.sqrt(np.mean(std[2 * e:2 * e + 2] ** 2))) or 1e-300
        sig.append(amp / spread)
    if not sig:
        return None
    spectra = {s["joint"]: s for s in structure["revolute_spectra"]}
    scale = field.scale()
    # the joint that carries the effect: of those where its amplitude exceeds 3 std, the one
    # whose harmonic alone explains most of the residual (the others' orders are not what is named)
    carried = [e for e, s in enumerate(sig) if s > 3.0] or [int(np.argmax(sig))]
    alone = [field.harmonic(act_jac[:, :, effect.axes[e]], data.q[:, effect.axes[e]], k) for e in carried]
    for e in [carried[int(np.argmax(alone))]]:
        a = effect.axes[e]
        joint = data.joints[a]
        spec = spectra.get(joint)
        if spec is None:
            continue
        col, qv = act_jac[:, :, a], data.q[:, a]
        e_k = field.harmonic(col, qv, k)
        orders, shares = _spectrum_of(spec, given, col, qv)
        best = int(np.argmax(shares))
        e_peak = max(float(shares[best]) * field.total, e_k)
        span, res = spec["range_rad"], spec["resolution_cycles_per_revolution"]
        info = {"effect": name, "stage": "spectrum", "joint": joint, "order": k,
                "peak_cycles_per_revolution": float(orders[best]), "peak_share": float(shares[best]),
                "range_rad": span, "resolution_cycles_per_revolution": res}
        if (e_peak - e_k) / scale > EQUIVALENT_CHI2:
            info["reason"] = (f"the spectrum of joint {joint}'s error peaks at {_cycles(orders[best])} per revolution "
                              f"({100 * shares[best]:.0f} % of the residual variance), where {k:g} explains "
                              f"{(e_peak - e_k) / scale:.0f} less (chi-square): the spectrum does not agree with "
                              f"its order")
            return info
        if k < res and k not in (1.0, 2.0):  # an order from the spectrum seen over less than one period: a smooth
            # trend of the joint must not fit as well (1 and 2, always tried, keep the checks below alone)
            x = (qv - qv.mean()) / max(float(np.std(qv)), 1e-300)
            e_t = field.fit(col[:, :, None] * np.column_stack([x, x**2])[:, None, :])[4]
            if (e_k - e_t) / scale < EQUIVALENT_CHI2:
                info["alias"] = 0.0
                info["reason"] = (f"over the {span:.2g} rad joint {joint} moved, less than one period of {_cycles(k)} "
                                  f"per revolution is seen, and a smooth trend of joint {joint} fits its error as "
                                  f"well (chi-square {e_t / scale:.0f} against {e_k / scale:.0f}): the order is not "
                                  f"established; poses over more than {2.0 * np.pi / k:.2g} rad of joint {joint} "
                                  f"would establish it")
                return info
        rivals = [k - 1.0, k + 1.0]
        if abs(k - round(k)) > 1e-9:  # a gear stage's order must also beat the integer orders around it
            rivals += [float(np.floor(k)), float(np.ceil(k))]
        for k2 in sorted(set(rivals), key=lambda r: abs(r - k)):
            if k2 < 0.5:
                continue
            e2 = field.harmonic(col, qv, k2)
            if (e_k - e2) / scale < EQUIVALENT_CHI2:
                wider = 2.0 * np.pi / abs(k - k2)
                info["alias"] = k2
                info["reason"] = (f"over the {span:.2g} rad joint {joint} moved, {_cycles(k2)} per revolution fit its "
                                  f"error as well as {k:g} (chi-square {e2 / scale:.0f} against {e_k / scale:.0f}; "
                                  f"orders closer than {res:.2g} cycles per revolution alias there): the order is not "
                                  f"established (the spectrum peaks at {orders[best]:g}); poses over more than "
                                  f"{wider:.2g} rad of joint {joint} would establish it")
                return info
    return None


def _scale_gate(name: str, effect, entry: dict, structure: dict, data, act_jac: np.ndarray,
                field: ResidualField | None = None) -> dict | None:
    """A scale error of a joint whose residual the spectrum shows to be periodic is not what is there.

    On the joint that carries the scale error (where its estimate is largest in standard
    deviations), the spectrum's best periodic error must not explain :data:`EQUIVALENT_CHI2`
    more than the scale error does; else the candidate is refused, with the peak.
    """
    given = field
    field = field or structure["field"]
    est = np.array(list(entry["estimates"].values()))
    std = np.array(list(entry["std"].values())).clip(min=1e-300)
    if not len(est):
        return None
    e = int(np.argmax(np.abs(est) / std))
    a = effect.axes[e]
    joint = data.joints[a]
    spec = next((s for s in structure["revolute_spectra"] if s["joint"] == joint), None)
    if spec is None:
        return None
    col, qv = act_jac[:, :, a], data.q[:, a]
    e_scale = field.fit(col[:, :, None] * qv[:, None, None])[4]
    orders, shares = _spectrum_of(spec, given, col, qv)
    best = int(np.argmax(shares))
    gain = (float(shares[best]) * field.total - e_scale) / field.scale()
    if gain <= EQUIVALENT_CHI2:
        return None
    order = orders[best]
    return {"effect": name, "stage": "spectrum", "joint": joint, "peak_cycles_per_revolution": float(order),
            "reason": (f"the error of joint {joint} is periodic-like: its spectrum peaks at {_cycles(order)} per "
                       f"revolution ({100 * shares[best]:.0f} % of the residual variance), which explains {gain:.0f} "
                       f"more (chi-square) than a scale error of that joint")}


def aliased_orders(why: dict, field: ResidualField, col: np.ndarray, qv: np.ndarray) -> list | None:
    """The orders a periodic candidate refused only because its order is not established is one of, or None.

    ``why`` is :func:`periodic_gate`'s refusal with ``alias`` a rival order (not ``0.0``, a smooth trend);
    ``field`` the residual it was judged on, ``col`` and ``qv`` its joint's column and values.  The
    joint's error is periodic (the candidate's order explains :data:`EQUIVALENT_CHI2` more than a
    linear and quadratic trend of the joint) but the range the joint moved cannot tell its order from
    a neighbour's: the candidate's order and the neighbours (``k - 1``, ``k + 1``; for a gear stage's
    order also the integers around it) within :data:`EQUIVALENT_CHI2` of it are returned, when they are
    two, and the spectrum's peak lies between them (within half a cycle per revolution).  Three or
    more orders that fit alike, a peak elsewhere, or a trend that fits as well: None (the order is
    not even bounded; the answer stays "unexplained" with the peak).  The trend check is spared the
    library's orders 1 and 2 (as in the gate) only where the range bounds an order to its neighbours
    (resolution ``2 pi / range`` below :data:`BOUNDED_RESOLUTION`: orders three apart are resolved);
    over a shorter range (a palletiser's joint 2 over 1.9 rad: 3.3 cycles per revolution) a 1 or
    2/rev error is taken only when the data show it periodic, i.e. better than a quadratic trend of
    the joint by :data:`EQUIVALENT_CHI2`, and the rivals are every integer order up to one beyond
    the resolution (not only the neighbours): all those that fit alike are returned (two or more),
    provided the highest order tried does not (the set is bounded by the data).

    >>> rng = np.random.default_rng(1)
    >>> q = rng.uniform(-1.4, 1.4, 200)  # 2.8 rad of the joint: orders closer than 2.2 per revolution alias
    >>> col = np.tile(np.eye(3)[None, :, 0], (200, 1))  # the joint moves the point along x
    >>> resid = 0.01 * np.sin(2.0 * q + 0.4)[:, None] * np.eye(3)[0] + rng.normal(0, 2e-3, (200, 3))
    >>> field = ResidualField(resid, np.full(200, 500.0), np.zeros((600, 0)))
    >>> why = {"order": 2.0, "alias": 1.0, "peak_cycles_per_revolution": 2.0, "resolution_cycles_per_revolution": 2.2}
    >>> aliased_orders({**why, "alias": 0.0}, field, col, q) is None  # a smooth trend fits as well: another case
    True
    >>> q_short = rng.uniform(-0.6, 0.6, 200)  # 1.2 rad: a 1/rev error there is a quadratic trend of the joint
    >>> offset = col.reshape(600, 1) / np.sqrt(200)  # the geometry's joint offset, projected off as in a diagnosis
    >>> trend = ResidualField(0.01 * np.sin(q_short + 0.4)[:, None] * np.eye(3)[0] + rng.normal(0, 2e-3, (200, 3)),
    ...                       np.full(200, 500.0), offset)
    >>> one = {**why, "order": 1.0, "alias": 2.0, "peak_cycles_per_revolution": 1.0}
    >>> aliased_orders({**one, "resolution_cycles_per_revolution": 5.2}, trend, col, q_short) is None  # 2 pi / 1.2
    True
    >>> aliased_orders({**one, "resolution_cycles_per_revolution": 2.0}, trend, col, q_short)  # were the range long
    [1.0, 2.0]
    >>> aliased_orders(why, field, col, q) is None  # a strong 2/rev: 1 explains far less, the order is established
    True
    """
    k, k2 = why.get("order"), why.get("alias")
    if k is None or not k2:
        return None
    short = not why.get("resolution_cycles_per_revolution", np.inf) < BOUNDED_RESOLUTION
    scale = field.scale()
    e_k = field.harmonic(col, qv, k)
    x = (qv - qv.mean()) / max(float(np.std(qv)), 1e-300)
    e_t = field.fit(col[:, :, None] * np.column_stack([x, x**2])[:, None, :])[4]
    if (e_k - e_t) / scale < EQUIVALENT_CHI2 and (short or k not in (1.0, 2.0)):
        return None  # the library's orders 1 and 2 are tried on every revolute without that check (as in the gate),
        # but over a range shorter than BOUNDED_RESOLUTION allows, the data must show a periodic error, not a trend
    gear = {float(np.floor(k)), float(np.ceil(k))} if abs(k - round(k)) > 1e-9 else set()
    if short:  # every integer order up to one beyond the resolution: the set must be bounded by an order that fails
        res = why["resolution_cycles_per_revolution"]
        rivals = {float(o) for o in range(1, int(np.ceil(k + res)) + 1)} | gear
    else:
        rivals = {k - 1.0, k + 1.0} | gear
    fits = sorted({k} | {o for o in rivals if o >= 0.5 and o != k
                         and (e_k - field.harmonic(col, qv, o)) / scale < EQUIVALENT_CHI2})
    peak = why.get("peak_cycles_per_revolution")
    if len(fits) < 2 or (not short and len(fits) != 2) or (short and max(rivals) in fits) or peak is None \
            or not fits[0] - 0.5 <= peak <= fits[-1] + 0.5:
        return None
    return [float(o) for o in fits]


def smooth_orders(why: dict, field: ResidualField, col: np.ndarray, qv: np.ndarray) -> list | None:
    """The periodic orders that fit a joint's error which a smooth trend of the joint fits as well, or None.

    Over a range shorter than one period of the low orders, a joint's error that is a curve of the joint (a
    quadratic trend fits it as well as the candidate's order: :func:`aliased_orders` returns None) is still
    a located error of that joint, and each low periodic order is the library's reading of it.  The orders
    compared are the candidate's (``why["order"]``), every integer order up to one beyond the resolution
    ``2 pi / range`` and, for a gear stage's order, the integers around it; those within
    :data:`EQUIVALENT_CHI2` of the best of them are returned, provided the highest order tried does not
    fit (the set is bounded by the data) and the candidate's own order is among them.  The answer then
    names the set, says a smooth error outside the library fits as well, and has low confidence.

    >>> rng = np.random.default_rng(2)
    >>> q = rng.uniform(-0.8, 0.8, 300)  # 1.6 rad: orders closer than 3.9 cycles per revolution alias
    >>> col = np.tile(np.eye(3)[None, :, 0], (300, 1))
    >>> offset = col.reshape(900, 1) / np.sqrt(300)  # the joint's offset, projected off as in a diagnosis
    >>> resid = 0.01 * np.sin(2.0 * q + 1.0)[:, None] * np.eye(3)[0] + rng.normal(0, 3e-3, (300, 3))
    >>> field = ResidualField(resid, np.full(300, 333.0), offset)
    >>> why = {"order": 2.0, "alias": 1.0, "resolution_cycles_per_revolution": 2 * np.pi / 1.6}
    >>> aliased_orders(why, field, col, q) is None  # a trend of the joint fits as well: not periodic-looking
    True
    >>> orders = smooth_orders(why, field, col, q)
    >>> 2.0 in orders and 5.0 not in orders  # the truth among the low orders, the highest tried refused
    True
    >>> flat = ResidualField(rng.normal(0, 3e-3, (300, 3)), np.full(300, 333.0), offset)
    >>> smooth_orders(why, flat, col, q) is None  # nothing there: every order fits alike, the set is unbounded
    True
    """
    k, res = why.get("order"), why.get("resolution_cycles_per_revolution")
    if k is None or res is None:
        return None
    scale = field.scale()
    x = (qv - qv.mean()) / max(float(np.std(qv)), 1e-300)
    e_t = field.fit(col[:, :, None] * np.column_stack([x, x**2])[:, None, :])[4]
    if (field.harmonic(col, qv, k) - e_t) / scale >= EQUIVALENT_CHI2:
        return None  # periodic-looking: aliased_orders' case, not this one
    gear = {float(np.floor(k)), float(np.ceil(k))} if abs(k - round(k)) > 1e-9 else set()
    rivals = sorted({float(o) for o in range(1, int(np.ceil(k + res)) + 1)} | gear | {float(k)})
    explained = {o: field.harmonic(col, qv, o) for o in rivals}
    best = max(explained.values())
    fits = [o for o in rivals if (best - explained[o]) / scale < EQUIVALENT_CHI2]
    if k not in fits or rivals[-1] in fits:
        return None
    return fits
