"""Library effects the structure tests locate on a joint but the selection's 5 % bar does not take: the words.

Units: lengths in mm (cross-validated RMS quoted in µm), angles in rad, orders in cycles per
revolution, screw periods in mm; BIC in units of the noise variance.

The forward selection (:mod:`.selection`) adds an effect when it lowers the blocked
cross-validated RMS by 5 % and the BIC by 10.  The 5 % is an effect-size bar: a periodic error
whose held-out share is under about 10 % of the residual variance cannot pass it however
significant it is (the KUKA-like arm's 2/rev error of joint 2 at 1.5e-5 rad over 2.8 rad: BIC
down by 17 to 52, cross-validated RMS down by 3 to 4 %).  Two things follow here:

* a periodic candidate that the structure tests already locate (its joint's spectrum has a
  significant peak, its order passes the spectrum's gate) is taken at a 2 % bar, as the first
  effect (:data:`~.selection.LOCATED_CV_DROP`); the answer then says it is below the 5 % and its
  confidence is low (:func:`below_guard_words`, ``verdict.below_guard``);
* an ``unexplained`` answer whose structure tests locate such an effect on a named joint is not
  given with high confidence: it names the effect, the joint, the numbers of its cross-validation
  and the measurement that would settle it (:func:`seen_words`, ``verdict.library_effect_seen``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["below_guard_words", "seen_words", "settling_measurement"]


def _cycles(k: float) -> str:
    return f"{k:g} cycle" + ("" if k == 1 else "s")


def settling_measurement(joint: str, range_rad: float | None, revolute: bool) -> str:
    """What would settle a weak periodic error of ``joint``: a wider range (a revolute that moved less than a turn:
    neighbouring orders alias there) and more poses.

    >>> settling_measurement("2", 2.8, True)
    'poses over more than 6.3 rad of joint 2 (it moved 2.8 rad), and more poses'
    >>> settling_measurement("32", None, False)
    'more poses along the travel of joint 32'
    """
    if revolute and range_rad is not None and range_rad < 2.0 * np.pi:
        return (f"poses over more than {2.0 * np.pi:.2g} rad of joint {joint} (it moved {range_rad:.2g} rad), and more "
                f"poses")
    return f"more poses along the travel of joint {joint}" if not revolute else "more poses"


def below_guard_words(steps: list, selected: list, located: dict) -> tuple[list, str]:
    """``verdict.below_guard`` and its words for the effects taken below the 5 % bar (``steps`` marked
    ``below_guard``, still in ``selected`` after the nonlinear fit); ``located``: key -> the peak that locates it
    (``{"joint", "p_value", "share", "order" or "period_mm", "range_rad"}``).

    >>> steps = [{"added": "angle-harmonic-2@2", "cv_rms_before": 0.0594, "cv_rms_after": 0.0576, "delta_bic": -16.7,
    ...           "below_guard": True}]
    >>> peak = {"joint": "2", "p_value": 2.9e-7, "share": 0.06, "order": 2.0, "range_rad": 2.8, "revolute": True}
    >>> info, words = below_guard_words(steps, ["angle-harmonic-2"], {"angle-harmonic-2@2": peak})
    >>> info[0]["cv_drop"] == round(1 - 0.0576 / 0.0594, 4), "3.0 % lower" in words
    (True, True)
    """
    out, parts = [], []
    for st in steps:
        key = st["added"]
        name, _, joint = key.partition("@")
        if name not in selected:  # removed again by the nonlinear fit: what was added after it was chosen beside it
            out.append({"effect": name, "joint": joint, "removed": True, "cv_rms_before": st["cv_rms_before"],
                        "cv_rms_after": st["cv_rms_after"], "delta_bic": st["delta_bic"]})
            parts.append(f"; confidence low: the selection started from {name} of joint {joint}, taken under the 5 % "
                         f"bar of the cross-validation because the structure tests locate it, and the nonlinear fit "
                         f"removed it again: what is named was chosen beside it")
            continue
        peak = located.get(key, {})
        drop = round(1.0 - st["cv_rms_after"] / st["cv_rms_before"], 4)
        settle = settling_measurement(joint, peak.get("range_rad"), peak.get("revolute", True))
        out.append({"effect": name, "joint": joint, "cv_rms_before": st["cv_rms_before"],
                    "cv_rms_after": st["cv_rms_after"], "cv_drop": drop, "delta_bic": st["delta_bic"],
                    "spectrum_p_value": peak.get("p_value"), "settling_measurement": settle})
        parts.append(f"; confidence low: {name} of joint {joint} is small against the noise: it lowers the "
                     f"cross-validated RMS from {1000 * st['cv_rms_before']:.1f} to {1000 * st['cv_rms_after']:.1f} µm "
                     f"({100 * drop:.1f} % lower, under the 5 % the selection asks of an effect) and the BIC by "
                     f"{-st['delta_bic']:.0f}; it is taken because the structure tests locate it on joint {joint}"
                     + (f" ({_peak_words(peak)})" if peak else "")
                     + (" and its period is the spectrum's" if "period_mm" in peak else
                        " and its order passes the spectrum's gate" if peak.get("revolute", True) else "")
                     + f"; {settle} would size it with confidence")
    return out, "".join(parts)


def _peak_words(peak: dict) -> str:
    if "signature" in peak:
        return (f"the signature test of {peak['signature']}: {100 * peak['share']:.0f} % of the residual variance, "
                f"F-test p = {peak['p_value']:.2g}")
    if "order" in peak:
        what = f"its spectrum's peak at {_cycles(peak['order'])} per revolution"
    else:
        what = f"its spectrum's peak at a period of {peak['period_mm']:.3g} mm"
    return f"{what}, {100 * peak['share']:.0f} % of the residual variance, F-test p = {peak['p_value']:.2g}"


def seen_words(seen: dict) -> str:
    """The words an ``unexplained`` answer adds when its structure tests locate a library effect on a joint (``seen``:
    ``verdict.library_effect_seen``).

    >>> seen = {"effect": "angle-harmonic-2", "joint": "2", "order": 2.0, "p_value": 2.9e-7, "share": 0.06,
    ...         "cv_rms_rigid": 0.0594, "cv_rms_with": 0.0576, "cv_drop": 0.03, "delta_bic": -16.7,
    ...         "why_not": "it lowers the cross-validated RMS by 3.0 %", "settling_measurement": "more poses"}
    >>> print(seen_words(seen))
    ; confidence low: the structure tests locate a library effect, angle-harmonic-2 of joint 2 (its spectrum's peak at 2 cycles per revolution, 6 % of the residual variance, F-test p = 2.9e-07), which was not taken: with it the cross-validated RMS goes from 59.4 to 57.6 µm and the BIC changes by -17, and it lowers the cross-validated RMS by 3.0 %; more poses would settle whether it is that effect
    """
    return (f"; confidence low: the structure tests locate a library effect, {seen['effect']} of joint {seen['joint']} "
            f"({_peak_words(seen)}), which was not taken: with it the cross-validated RMS goes from "
            f"{1000 * seen['cv_rms_rigid']:.1f} to {1000 * seen['cv_rms_with']:.1f} µm and the BIC changes by "
            f"{seen['delta_bic']:+.0f}, and {seen['why_not']}; {seen['settling_measurement']} would settle whether it "
            f"is that effect")
