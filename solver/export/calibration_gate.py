"""Whether a calibration may leave hyperstat: no silent export of a fit ``identify`` calls bad.

Units: lengths in mm.

``export-controller``, ``export-urdf`` and ``export-dh`` write what a controller will run. They
refuse, unless ``--force``, a calibration that ``identify`` itself flags:

* **absurd**: the weighted residuals are more than :data:`~hyperstat.solver.calibration.identify.SIGMA_WARN`
  times the noise the data state (a wrong joint map, wrong units, targets stacked in one column,
  a moved tracker): the same test as identify's ``ABSURD FIT`` warning;
* **worse than nominal**: on held-out poses (``--validation``) the calibrated model predicts worse
  than the nominal model with only the tracker frame and targets fitted: the same comparison as
  identify's ``CALIBRATION MAKES HELD-OUT POSES WORSE`` warning.

Without validation data the second test cannot be made; :func:`export_refusal` then judges on
the first alone.  This is the one place the exports ask; when ``identify`` reports a fit-quality
flag of its own, this function reads it.

Examples
--------
>>> from types import SimpleNamespace as R
>>> ok = R(noise_rms=0.01, sigma=1.02, validation={"rms": 0.05}, nominal={"validation": {"rms": 1.3}})
>>> export_refusal(ok) is None
True
>>> bad = R(noise_rms=0.01, sigma=1.02, validation={"rms": 6.7}, nominal={"validation": {"rms": 3.9}})
>>> export_refusal(bad)
'it predicts the held-out poses worse than the nominal model (validation RMS 6.7 mm against 3.9 mm with the nominal geometry)'
"""

from __future__ import annotations

__all__ = ["export_refusal"]


def export_refusal(identification) -> str | None:
    """Why the calibration ``identification`` (an :class:`~hyperstat.solver.calibration.identify.IdentificationResult`)
    must not be exported, in words; None when it may."""
    from hyperstat.solver.calibration.identify import SIGMA_WARN

    reasons = []
    sigma = identification.sigma
    if identification.noise_rms is not None and sigma > SIGMA_WARN:
        reasons.append(f"identify calls the fit absurd: the residuals are {sigma:.3g} times the noise the data state "
                       f"(above {SIGMA_WARN:g}: a wrong joint map, wrong units, targets stacked in one column or a "
                       f"moved tracker)")
    nominal = (identification.nominal or {}).get("validation")
    validation = identification.validation
    if nominal is not None and validation is not None and validation["rms"] > nominal["rms"]:
        reasons.append(f"it predicts the held-out poses worse than the nominal model (validation RMS "
                       f"{validation['rms']:.4g} mm against {nominal['rms']:.4g} mm with the nominal geometry)")
    return "; and ".join(reasons) or None
