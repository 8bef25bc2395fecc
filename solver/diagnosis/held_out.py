"""Choosing an effect on all the poses when the identification poses alone are too few to choose it.

Units: chi-square values of residuals weighted by the file's noise model (dimensionless); the statistic ``F`` is a
ratio of mean squares; RMS in mm.

A rigid fit that spends most of its equations on parameters (a hexapod's 51 parameters on 30 poses of one
reflector: 90 equations) fits its own poses by bending the geometry around a missing effect, so its residuals
show nothing, and a blocked cross-validation, which drops a quarter of those poses, over-fits worse still: the
diagnosis answers ``over-fitting``.  When the held-out poses' excess is also beyond what the fitted model's
average uncertainty accounts for (``verdict.effect_not_excluded``), a missing effect may be there, but those
held-out residuals cannot test a candidate directly: they carry the rigid fit's own extrapolation error (large at
poses of high leverage), which every added parameter changes, so a candidate chosen on them is confirmed on pure
noise (a test on the project's PKM generator: z = 9 on a no-effect hexapod campaign of 20 poses).

What is exact is the nested-model test on all the poses: the identification and the held-out poses are pooled
(42 poses, 126 equations, for the hexapod above), the rigid geometry and the geometry with each candidate are
fitted on them, and

    F = ((chi2_rigid - chi2_with) / (r_with - r_rigid)) / (chi2_with / dof_with)

follows Fisher's F distribution with ``(r_with - r_rigid, dof_with)`` degrees of freedom when the candidate is
not there, whatever the noise's scale (an understated noise model scales both chi-squares alike).  As ``m``
candidates are tried, each must pass ``p < CONFIRM_P / m`` (Bonferroni: family-wise 1 %); the candidates whose
pooled chi-square is within :data:`.periodic.EQUIVALENT_CHI2` of the best one's fit alike and form its set.  The
answer says the choice was made on all the poses, so no pose is held out of it any more, and has low confidence.
"""

from __future__ import annotations

from scipy.special import fdtrc  # scipy.stats.f.sf; scipy.stats costs 0.3 s more to import

from hyperstat.solver.diagnosis.confirmation import CONFIRM_P
from hyperstat.solver.diagnosis.periodic import EQUIVALENT_CHI2

__all__ = ["nested_f_test", "held_out_choice", "held_out_words"]


def _f_sf(f: float, dfn: int, dfd: int) -> float:
    """Fisher's F survival function at ``f >= 0`` as ``scipy.stats.f.sf`` computes it (1 at 0, else ``fdtrc``).

    >>> from scipy.stats import f as fisher_f
    >>> all(_f_sf(x, 3, 40) == float(fisher_f.sf(x, 3, 40)) for x in (0.0, 0.4, 2.5, 74.0))
    True
    """
    return 1.0 if f <= 0.0 else float(fdtrc(dfn, dfd, f))


def nested_f_test(key: str, rigid: dict, with_effect: dict) -> dict | None:
    """The F-test of a candidate fitted with the geometry against the geometry alone, on the same rows.

    Parameters
    ----------
    key : str
        The candidate.
    rigid, with_effect : dict
        ``chi2`` (weighted residual sum of squares), ``dof`` (rows minus rank) and ``rank`` of each fit.

    Returns
    -------
    dict or None
        ``key``, ``f``, ``p_value`` (upper tail), ``chi2_after`` and ``added`` (parameters the candidate adds);
        None when it adds no identifiable parameter.

    Examples
    --------
    >>> t = nested_f_test("screw-pitch@36", {"chi2": 300.0, "dof": 75, "rank": 51}, {"chi2": 150.0, "dof": 74,
    ...                                                                                 "rank": 52})
    >>> round(t["f"], 1), t["p_value"] < 1e-10
    (74.0, True)
    >>> nested_f_test("thermal", {"chi2": 80.0, "dof": 75, "rank": 51}, {"chi2": 79.0, "dof": 74, "rank": 52})["p_value"] > 0.2
    True
    """
    added = with_effect["rank"] - rigid["rank"]
    if added <= 0 or with_effect["dof"] <= 0 or with_effect["chi2"] <= 0.0:
        return None
    f = max(rigid["chi2"] - with_effect["chi2"], 0.0) / added / (with_effect["chi2"] / with_effect["dof"])
    return {"key": key, "f": float(f), "p_value": _f_sf(f, added, with_effect["dof"]),
            "chi2_after": float(with_effect["chi2"]), "added": int(added)}


def held_out_choice(trials: list, alpha: float = CONFIRM_P) -> dict | None:
    """The candidate the pooled F-tests confirm best, with those that fit alike, or None.

    Parameters
    ----------
    trials : list of dict or None
        :func:`nested_f_test` of each candidate tried (None for a candidate that could not be fitted within its
        physical domain: it still counts among those tried).
    alpha : float
        Family-wise level over the candidates tried.

    Returns
    -------
    dict or None
        ``chosen`` (the key with the lowest pooled chi-square among those confirmed), ``alike`` (the other
        confirmed keys within :data:`EQUIVALENT_CHI2` of it), ``threshold`` (``alpha / m``), ``tried`` (``m``),
        ``confirmed`` (how many passed) and ``best`` (the chosen trial).  None when no candidate passes.

    Examples
    --------
    >>> trials = [{"key": "screw-pitch@36", "f": 74.0, "p_value": 6e-13, "chi2_after": 150.0},
    ...           {"key": "leg-thermal", "f": 60.0, "p_value": 1e-9, "chi2_after": 157.0},
    ...           {"key": "thermal", "f": 5.0, "p_value": 0.028, "chi2_after": 290.0}]
    >>> c = held_out_choice(trials + [None] * 17)   # 20 tried: 0.01 / 20 = 5e-4 needed
    >>> c["chosen"], c["alike"], c["tried"], c["confirmed"]
    ('screw-pitch@36', ['leg-thermal'], 20, 2)
    >>> held_out_choice([trials[2]] + [None] * 19) is None   # p = 0.028: chance among 20 candidates
    True
    """
    tried = len(trials)
    if not tried:
        return None
    threshold = alpha / tried
    passed = sorted((t for t in trials if t is not None and t["p_value"] < threshold), key=lambda t: t["chi2_after"])
    if not passed:
        return None
    best = passed[0]
    alike = [t["key"] for t in passed[1:] if t["chi2_after"] - best["chi2_after"] < EQUIVALENT_CHI2]
    return {"chosen": best["key"], "alike": alike, "threshold": threshold, "tried": tried, "confirmed": len(passed),
            "best": best}


def held_out_words(choice: dict, rank: int, n_equations: int, poses_pooled: int) -> str:
    """The answer's words for an effect chosen on the pooled poses.

    >>> c = {"chosen": "screw-pitch@36", "alike": [], "threshold": 5e-4, "tried": 20, "confirmed": 1,
    ...      "best": {"f": 74.0, "p_value": 6e-13}}
    >>> held_out_words(c, 51, 90, 42)[:57]
    '; confidence low: chosen on all 42 poses (identification '
    """
    best = choice["best"]
    return (f"; confidence low: chosen on all {poses_pooled} poses (identification and held-out pooled), not on the "
            f"identification poses alone: the rigid fit has {rank} parameters for {n_equations} equations, too few "
            f"for a cross-validation to choose; of the {choice['tried']} candidates fitted with the geometry on the "
            f"pooled poses, an F-test against the geometry alone confirms {choice['confirmed']} at the family-wise "
            f"1 % (p < {choice['threshold']:.2g} each), this one best (F = {best['f']:.3g}, p = "
            f"{best['p_value']:.2g}); no pose was held out of that choice, so the validation figures above are not "
            f"independent of it: with more poses spread over the workspace, diagnose again")
