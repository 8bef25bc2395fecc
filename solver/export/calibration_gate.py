"""Whether a calibration may leave hyperstat: no silent export of a fit ``identify`` calls bad.

Units: lengths in mm.

``export-controller``, ``export-urdf`` and ``export-dh`` write what a controller will run. They
refuse, unless ``--force``, a calibration that ``identify`` itself flags:

* **inputs wrong** (identify's ``fit_quality``): the weighted residuals are in the hundreds of
  times the noise the data state, or the residual RMS is beyond 1 % of the machine's size (a
  wrong joint map, wrong units, targets stacked in one column, a moved tracker): the same flag
  as identify's ``ABSURD FIT`` warning;
* **worse than nominal**: on held-out poses (``--validation``) the calibrated model predicts worse
  than the nominal model with only the tracker frame and targets fitted: the same comparison as
  identify's ``CALIBRATION MAKES HELD-OUT POSES WORSE`` warning.

A fit identify flags ``"model misses an effect"`` (residuals a few times the noise, a real
machine with compliance or gear errors) is exported: it is still the best rigid model of the
machine; :func:`export_warning` says so on stderr and points at ``hyperstat diagnose``.
Without validation data the second test cannot be made; :func:`export_refusal` then judges on
the first alone.  This is the one place the exports ask.

Examples
--------
>>> from types import SimpleNamespace as R
>>> ok = R(fit_quality="ok", sigma=1.02, validation={"rms": 0.05}, nominal={"validation": {"rms": 1.3}})
>>> export_refusal(ok) is None
True
>>> bad = R(fit_quality="ok", sigma=1.02, validation={"rms": 6.7}, nominal={"validation": {"rms": 3.9}})
>>> export_refusal(bad)
'it predicts the held-out poses worse than the nominal model (validation RMS 6.7 mm against 3.9 mm with the nominal geometry)'
"""

from __future__ import annotations

__all__ = ["export_refusal", "export_warning"]


def export_refusal(identification) -> str | None:
    """Why the calibration ``identification`` (an :class:`~hyperstat.solver.calibration.identify.IdentificationResult`)
    must not be exported, in words; None when it may."""
    reasons = []
    sigma = identification.sigma
    if getattr(identification, "fit_quality", "ok") == "inputs wrong":
        reasons.append(f"identify calls the fit absurd: the residuals are {sigma:.3g} times the noise the data state "
                       f"(the inputs are wrong: a wrong joint map, wrong units, targets stacked in one column or a "
                       f"moved tracker)")
    nominal = (identification.nominal or {}).get("validation")
    validation = identification.validation
    if nominal is not None and validation is not None and validation["rms"] > nominal["rms"]:
        reasons.append(f"it predicts the held-out poses worse than the nominal model (validation RMS "
                       f"{validation['rms']:.4g} mm against {nominal['rms']:.4g} mm with the nominal geometry)")
    return "; and ".join(reasons) or None


def export_warning(identification) -> str | None:
    """A warning for an exported calibration whose rigid model misses an effect (None otherwise).

    >>> from types import SimpleNamespace as R
    >>> print(export_warning(R(fit_quality="model misses an effect", sigma=6.6)))
    the calibrated rigid model leaves residuals 6.6 times the stated noise: ...(run 'hyperstat diagnose' to find it)
    """
    if getattr(identification, "fit_quality", "ok") != "model misses an effect":
        return None
    return (f"the calibrated rigid model leaves residuals {identification.sigma:.3g} times the stated noise: it is the "
            f"best rigid model of this machine, but an effect it lacks remains (run 'hyperstat diagnose' to find it)")
