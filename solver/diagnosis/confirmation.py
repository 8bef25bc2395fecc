"""Do the held-out poses confirm the effects the selection chose?  A one-sided test along the effects' prediction.

Units: residuals weighted by the file's noise model (dimensionless); the statistic ``z`` is in standard deviations.

The forward selection (:mod:`.selection`) chooses effects by a blocked cross-validation on the identification
poses; among some thirty candidates, the best one lowers the cross-validated RMS of a small campaign by a few per
cent by chance alone (the best of ``K`` chi-square variables with two degrees of freedom is about ``2 ln K``).
When the structure tests of the rigid residuals found nothing (no joint, frequency or metadata trend), that
cross-validation is the only evidence for the effect, and it is evidence chosen from many.  The validation poses,
never used to choose, then give an independent test of the one direction chosen:

* ``e_b`` the weighted validation residuals of the rigid fit, ``e_a`` those of the fit with the effects, and
  ``d = e_b - e_a`` what the effects predict at the held-out poses (fixed by the identification poses alone);
* if the effects are not there, ``e_b`` is noise of variance ``f**2`` per row (``f`` the noise factor, measured
  from ``e_a``: an understated noise model does not make the test liberal), independent of ``d``, and
  ``z = e_b . d / (f |d|)`` is a standard normal variable;
* an effect that is there gives ``z`` about ``|d| / f``: an effect at 0.6 x the noise over 16 poses of three rows
  gives ``z`` near 4.

The effects are confirmed when ``z`` exceeds the normal quantile of :data:`CONFIRM_P` (one-sided 1 %).  This is
the validation's own share of the evidence, beside the rule that refuses an effect that makes the validation
RMS worse (``z`` below ``|d| / 2 f``).
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr  # scipy.stats.norm.sf(z) is ndtr(-z); scipy.stats costs 0.3 s more to import

__all__ = ["validation_confirms", "CONFIRM_P"]

CONFIRM_P = 0.01  #: one-sided p-value below which the held-out poses confirm the effects' prediction


def validation_confirms(before: np.ndarray, after: np.ndarray) -> dict:
    """The one-sided test that the held-out residuals move along the effects' prediction.

    Parameters
    ----------
    before, after : ndarray
        Weighted validation residuals (any shape, the same for both) of the rigid fit and of the fit with the
        effects.

    Returns
    -------
    dict
        ``z`` (standard deviations), ``p_value`` (one-sided), ``noise_factor`` (RMS of ``after``),
        ``prediction`` (``|d| / f``: the effects' predicted change in noise units, about the ``z`` a real effect
        gives) and ``confirmed`` (``p_value < CONFIRM_P``).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> noise = rng.normal(size=48)
    >>> effect = 0.85 * np.sin(np.linspace(0.0, 6.0, 48))         # RMS 0.6 x the noise over 48 rows
    >>> check = validation_confirms(noise + effect, noise)         # the effect is there: predicted and seen
    >>> check["confirmed"], round(check["prediction"], 1)
    (True, 4.8)
    >>> chance = 0.2 * rng.normal(size=48)                          # a direction chosen on other poses
    >>> validation_confirms(noise, noise - chance)["confirmed"]
    False
    """
    eb, ea = np.ravel(before), np.ravel(after)
    d = eb - ea
    f = float(np.sqrt(np.mean(ea**2))) if ea.size else 0.0
    size = float(np.linalg.norm(d))
    if f <= 0.0 or size <= 0.0:
        return {"z": 0.0, "p_value": 1.0, "noise_factor": f, "prediction": 0.0, "confirmed": False}
    z = float(eb @ d / (f * size))
    p = float(ndtr(-z))  # the normal survival function, as scipy.stats.norm.sf computes it
    return {"z": z, "p_value": p, "noise_factor": f, "prediction": size / f, "confirmed": p < CONFIRM_P}
