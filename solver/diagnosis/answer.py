"""Step 5 of the diagnosis: the answer in words, one of :data:`OUTCOMES`, each with its evidence.

Units: lengths in mm (the words print µm), angles in rad.

* ``inputs wrong``: sigma in the hundreds or residuals of a link's size: the joint map,
  the units or the targets, not a missing effect (nothing else is tried);
* ``no significant gap``: the gap tests and the structure tests pass;
* ``explained``: after adding the named effects the gap test passes on the
  identification and the validation points and no structure is left; when an
  equivalence set has several members the answer names the set ("explained by one of
  ...; these poses cannot separate them") and the measurement that would;
* ``partly explained``: effects were added, a significant gap remains (how much, where);
* ``over-fitting``: nothing fits, and the rigid fit predicts held-out poses far worse
  than the poses it was fitted to;
* ``unexplained``: a significant gap with structure and no candidate within its physical
  domain and prior (where: joint, direction, frequency with the spectrum's resolution);
* ``understated noise``: no structure at all; the noise level that makes the data
  consistent.
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.diagnosis.gap import gap_test, noise_statement
from hyperstat.solver.diagnosis.where import P_THRESHOLD, describe_where, targets_words

__all__ = ["OUTCOMES", "verdict", "format_outcome", "set_words", "BLACK_BOX_NOTHING", "NEAR_STRUCTURE_FACTOR", "near_structure", "near_anisotropy", "near_gap", "weak_signals_together",
           "worst_noise_factor", "row_type_words"]

OUTCOMES = ("no significant gap", "explained", "partly explained", "unexplained", "understated noise",
            "over-fitting", "inputs wrong")
BLACK_BOX_NOTHING = 0.05  # a black-box regression "explains nothing" below this share of the residual variance


def set_words(sets: list) -> str:
    """"X or Y (these poses cannot separate them; <measurement> would)" for the ambiguous sets, "" otherwise."""
    parts = []
    for s in sets:
        if len(s["members"]) > 1:
            parts.append(f"{' or '.join(s['members'])} (these poses cannot separate them; "
                         f"{s['separating_measurement']} would)")
    return "; ".join(parts)


def _cannot_size_words(cannot_size: list) -> str:
    if not cannot_size:
        return ""
    names = ", ".join(c["effect"] for c in cannot_size)
    return f"; {names} could not be sized: the model declares no mass, and no mass is assumed (see cannot_size)"


def _stand_in_words(selected: list, cannot_size: list) -> str:
    """The caveat of an answer reached without the gravity effects (no masses): what was chosen may stand in for them.

    A joint scale error, a low-order harmonic or a joint offset that varies with the pose can mimic a
    gravity load over a pose set; without masses the equivalence check (:mod:`.equivalence`) cannot
    compare the chosen effect with them.

    >>> _stand_in_words(["angle-scale"], [{"effect": "compliance"}])
    '; angle-scale was not compared with compliance (not sized without masses) and may stand in for it: declare the masses before trusting this answer'
    >>> _stand_in_words(["angle-scale"], [])
    ''
    """
    if not cannot_size or not selected:
        return ""
    names = ", ".join(c["effect"] for c in cannot_size)
    return (f"; {' + '.join(selected)} was not compared with {names} (not sized without masses) and may stand in "
            f"for {'it' if len(cannot_size) == 1 else 'them'}: declare the masses before trusting this answer")


def _spectrum_words(rejected: list) -> str:
    """The spectrum's refusals in words, each sentence once (a per-joint candidate and its all-joints effect are
    refused for the same reason, with the same words).

    >>> r = {"effect": "angle-harmonic-2", "stage": "spectrum", "reason": "the order is not established"}
    >>> _spectrum_words([r, dict(r)])
    '; angle-harmonic-2 was not chosen: the order is not established'
    """
    sentences = [f"; {r['effect']} was not chosen: {r['reason']}" for r in rejected if r["stage"] == "spectrum"]
    return "".join(dict.fromkeys(sentences))


NEAR_STRUCTURE_FACTOR = 10.0
"""A structure test whose p-value is within this factor of the threshold (family-wise p under 1 % where the
threshold holds it under 0.1 %) is near-significant: a noise-only residual shows one in about 1 % of campaigns."""


def near_structure(structure: dict) -> dict | None:
    """The strongest structure test when it falls short of the threshold by less than :data:`NEAR_STRUCTURE_FACTOR`.

    The structure tests are judged at a Bonferroni threshold (``threshold = 0.001 / n_tests``); the family-wise
    p-value of the strongest test is ``min(1, p * n_tests)``. An answer that the excess is noise ("understated
    noise") is not stated with high confidence when that family-wise p-value is under 1 %: an effect present on a
    few poses only (an encoder glitch in one sector) looks like this.

    Parameters
    ----------
    structure : dict
        The structure tests' summary (``best`` with its ``p_value``, ``threshold``, ``n_tests``, ``structured``).

    Returns
    -------
    dict or None
        ``{"test", "p_value", "threshold", "family_wise_p"}``, or None when nothing is near the threshold.

    Examples
    --------
    >>> s = {"best": {"p_value": 1.5e-5}, "threshold": 0.001 / 294, "n_tests": 294, "structured": False}
    >>> round(near_structure(s)["family_wise_p"], 4)
    0.0044
    >>> near_structure({**s, "best": {"p_value": 1e-3}}) is None
    True
    """
    best = structure.get("best") or {}
    p, threshold = best.get("p_value"), structure.get("threshold")
    if structure.get("structured") or p is None or not threshold or p >= NEAR_STRUCTURE_FACTOR * threshold:
        return None
    return {"test": best, "p_value": float(p), "threshold": float(threshold),
            "family_wise_p": float(min(1.0, p * structure.get("n_tests", 1)))}


def near_anisotropy(structure: dict) -> dict | None:
    """Bartlett's test of equal variance in x, y and z when it passes by less than :data:`NEAR_STRUCTURE_FACTOR`.

    The residual is called isotropic when Bartlett's p-value is at least ``P_THRESHOLD`` (1e-3); an answer that
    the excess is noise is not stated with high confidence when that p-value is under ten times the threshold: an
    effect along one direction with no joint or metadata pattern the structure tests know (a reflector holder
    sagging along gravity, a scale along one axis) looks like this.  On isotropic noise the rule fires on 0.9 % of
    campaigns (the probability that a uniform p-value falls in ``[1e-3, 1e-2)``).

    >>> near_anisotropy({"isotropy": {"p_value": 0.0029}})["p_value"]
    0.0029
    >>> near_anisotropy({"isotropy": {"p_value": 0.2}}) is None
    True
    """
    p = (structure.get("isotropy") or {}).get("p_value")
    if p is None or not P_THRESHOLD <= p < NEAR_STRUCTURE_FACTOR * P_THRESHOLD:
        return None
    return {"p_value": float(p), "threshold": P_THRESHOLD}


def near_gap(test: dict) -> list[dict]:
    """The tests of a passing gap test that pass by less than :data:`NEAR_STRUCTURE_FACTOR` (a list, maybe empty).

    A ``no significant gap`` answer is not stated with high confidence when a chi-square of the gap test
    (identification or validation rows, pooled or, for 6-D data, by row type) or the strongest structure test
    falls short of its threshold by less than ten times: a small effect (a tracker's scale drifting with the air
    temperature, seen mostly at the held-out poses) looks like this.  On pure noise each such test lands in that
    band with probability ``9 x threshold`` (a uniform p-value): about 2 % of no-effect campaigns over the six
    gap tests of a 6-D file.

    >>> t = {"identification": {"p_value": 0.02}, "validation": {"p_value": 0.0013}, "threshold": 5e-4,
    ...      "structure": {"p_value": 0.2, "threshold": 2.7e-6}}
    >>> [n["test"] for n in near_gap(t)]
    ['validation']
    >>> near_gap({**t, "validation": {"p_value": 0.3}})
    []
    """
    near = []

    def check(name: str, p, threshold) -> None:
        if p is not None and threshold and threshold <= p < NEAR_STRUCTURE_FACTOR * threshold:
            near.append({"test": name, "p_value": float(p), "threshold": float(threshold)})
    for rows in ("identification", "validation"):
        check(rows, (test.get(rows) or {}).get("p_value"), test.get("threshold"))
    kinds = test.get("row_types") or {}
    for kind in ("positions", "orientations"):
        for rows in ("identification", "validation"):
            check(f"{kind} ({rows})", ((kinds.get(kind) or {}).get(rows) or {}).get("p_value"), kinds.get("threshold"))
    st = test.get("structure") or {}
    check("structure", st.get("p_value"), st.get("threshold"))
    return near


def weak_signals_together(near: dict | None, aniso: dict | None) -> dict | None:
    """Fisher's combination of the structure tests' family-wise p-value and Bartlett's isotropy p-value, when both
    fall short of their thresholds by less than :data:`NEAR_STRUCTURE_FACTOR` (:func:`near_structure`,
    :func:`near_anisotropy`): ``-2 (ln p1 + ln p2)`` follows chi-square(4) under pure noise (two independent tests),
    and below ``P_THRESHOLD`` the residual is not noise alone.  None otherwise.  On isotropic noise with no pattern
    both near flags come together on about 1e-4 of campaigns, and the combination rejects a share of those only.

    >>> weak_signals_together({"family_wise_p": 0.0082}, {"p_value": 0.003})["p_value"] < 1e-3
    True
    >>> weak_signals_together({"family_wise_p": 0.05}, {"p_value": 0.009}) is None
    True
    """
    if near is None or aniso is None:
        return None
    from scipy.stats import chi2

    stat = -2.0 * (np.log(max(near["family_wise_p"], 1e-300)) + np.log(max(aniso["p_value"], 1e-300)))
    p = float(chi2.sf(stat, 4))
    if p >= P_THRESHOLD:
        return None
    return {"p_value": p, "threshold": P_THRESHOLD, "family_wise_structure_p": float(near["family_wise_p"]),
            "isotropy_p": float(aniso["p_value"]), "method": "Fisher's combination of two independent p-values"}


def worst_noise_factor(test: dict) -> float:
    """The larger noise factor of a gap test's identification and validation rows (dimensionless).

    A 6-D gap test also holds ``row_types`` (the position and orientation rows tested apart), which is no set of
    rows with one factor of its own: it is not read.

    >>> worst_noise_factor({"identification": {"noise_factor": 1.3}, "validation": {"noise_factor": 1.6},
    ...                     "row_types": {"identification": {}, "significant": False}, "threshold": 5e-4})
    1.6
    """
    return max(test[k]["noise_factor"] for k in ("identification", "validation") if k in test)


def row_type_words(test: dict) -> str:
    """For a 6-D gap test significant only in one kind of rows, which rows and their p-values (else ``""``).

    >>> t = {"identification": {"p_value": 0.21}, "significant_by": "row types",
    ...      "row_types": {"positions": {"validation": {"p_value": 0.89}},
    ...                    "orientations": {"identification": {"p_value": 0.49}, "validation": {"p_value": 1.3e-4}},
    ...                    "threshold": 2.5e-4, "significant": True}}
    >>> row_type_words(t)
    ' (the orientation rows alone: validation p = 0.00013, threshold 0.00025)'
    """
    kinds = test.get("row_types") or {}
    if test.get("significant_by") != "row types" or not kinds.get("significant"):
        return ""
    parts = [f"the {kind[:-1]} rows alone: {rows} p = {entry[rows]['p_value']:.2g}"
             for kind in ("positions", "orientations") for rows in ("identification", "validation")
             if rows in (entry := kinds.get(kind, {})) and entry[rows]["p_value"] < kinds["threshold"]]
    return f" ({'; '.join(parts)}, threshold {kinds['threshold']:.2g})" if parts else ""


def verdict(data, validation, significant: bool, test: dict, final, selected: list, structure: dict, rest: dict | None,
            ceiling: dict, noise: float | None, share, sets: list, rejected: list, cannot_size: list,
            overfit: dict | None, wrong_inputs: dict | None) -> tuple[str, dict]:
    """The honest answer among :data:`OUTCOMES` and its evidence (a dict with ``evidence`` in words)."""
    tail = _cannot_size_words(cannot_size)
    if wrong_inputs is not None:
        return "inputs wrong", {"evidence": wrong_inputs["evidence"], **{k: v for k, v in wrong_inputs.items()
                                                                         if k != "evidence"}}
    if not significant:
        out = {"evidence": "the gap test passes: identification p = "
                           f"{test['identification']['p_value']:.2g}"
                           + (f", validation p = {test['validation']['p_value']:.2g}" if "validation" in test else "")
                           + f" (threshold {test['threshold']:.1g}); no structure in the residuals "
                           f"(smallest of {test['structure']['tests']} F-test p-values "
                           f"{test['structure']['p_value']:.2g}, threshold {test['structure']['threshold']:.1g})"
                           + tail}
        near = near_gap(test)
        if near:
            out["near_gap"] = near
            out["evidence"] += ("; confidence low: " + ", ".join(f"the {n['test']} test (p = {n['p_value']:.2g}, "
                                                                 f"threshold {n['threshold']:.2g})" for n in near)
                                + f" passes by less than {NEAR_STRUCTURE_FACTOR:g}x: a small effect is not excluded; "
                                  "more poses (held-out ones spread over the workspace) would tell it from noise")
        return "no significant gap", out
    if selected and final is not None:
        after = gap_test(final, data, validation)
        out = {"effects": list(selected), "gap_test_after": after, "share_explained": share}
        val = final.validation
        ambiguous = set_words(sets)
        if ambiguous:
            out["indistinguishable"] = [s for s in sets if len(s["members"]) > 1]
        passes = ", ".join(f"{k} p = {after[k]['p_value']:.2g}" for k in ("identification", "validation")
                           if k in after) + f" (threshold {after['threshold']:.1g})"
        if not after["significant"] and not rest["structured"]:
            out["evidence"] = (f"after adding {' + '.join(selected)} the gap test passes: {passes}, and no structure "
                               f"is left in the residuals (smallest of {rest['n_tests']} F-test p-values "
                               f"{rest['best']['p_value']:.2g}, threshold {rest['threshold']:.1g})")
            if ambiguous:
                out["evidence"] += f"; explained by one of {ambiguous}"
            notes = [f"{e.name} stands for {e.also_explains}" for e in final.model.effects if e.also_explains]
            if notes:
                out["same_signature"] = notes
                out["evidence"] += "; " + "; ".join(notes)
            out["evidence"] += tail + _stand_in_words(selected, cannot_size)
            if cannot_size:
                out["unchecked_against"] = [c["effect"] for c in cannot_size]
            return "explained", out
        remaining = None
        if val is not None and noise is not None:
            remaining = float(np.sqrt(max(val["rms"] ** 2 - noise**2, 0.0)))
        out["remaining_rms_above_noise"] = remaining
        out["where"] = describe_where(rest["best"], structure["revolute_spectra"]) if rest["structured"] else None
        out["remaining_structure"] = {k: rest[k] for k in ("best", "structured", "isotropy", "isotropic",
                                                           "threshold", "n_tests")}
        factor = worst_noise_factor(after)
        out["evidence"] = (f"a gap remains after adding {' + '.join(selected)}: "
                           + ", ".join(f"{k} p = {after[k]['p_value']:.2g}" for k in ("identification", "validation")
                                       if k in after)
                           + row_type_words(after)
                           + (f"; validation RMS {1000 * val['rms']:.1f} µm against a noise RMS {1000 * noise:.1f} µm "
                              f"({1000 * remaining:.1f} µm above it in quadrature)" if remaining is not None else ""))
        if ambiguous:
            out["evidence"] += f"; what was added is one of {ambiguous}"
        if rest["structured"]:
            out["evidence"] += "; what remains follows " + out["where"]
        elif not rest.get("targets_homogeneous", True):
            out["where"] = targets_words(rest["targets"])
            out["evidence"] += "; what remains is in " + out["where"]
        elif rest["isotropic"]:
            out["evidence"] += ("; what remains has no structure (no joint, frequency or metadata trend, equal in "
                                "every direction): consistent with a noise model of "
                                + noise_statement(data, factor)["text"])
            out["noise_consistent"] = noise_statement(data, factor)
        out["evidence"] += _spectrum_words(rejected) + tail + _stand_in_words(selected, cannot_size)
        if cannot_size:
            out["unchecked_against"] = [c["effect"] for c in cannot_size]
        return "partly explained", out
    # nothing selected: over-fitting, structure or noise?
    factor = test["identification"]["noise_factor"]  # 3K - rank degrees of freedom: the sharper estimate
    bb_share = ceiling["black_box_share_of_residual"]
    out = {"structure": {k: structure[k] for k in ("best", "structured", "isotropy", "isotropic", "threshold",
                                                   "n_tests")},
           "black_box_share": bb_share}
    homogeneous = structure.get("targets_homogeneous", True)
    if not homogeneous:
        out["structure"]["targets"] = structure["targets"]
    if overfit is not None:
        out["overfitting"] = overfit
        out["evidence"] = overfit["evidence"] + tail
        held = test.get("validation")
        if held is not None and held["p_value"] < test["threshold"]:
            # the validation gap test already whitens by the fitted model's own uncertainty (gap.prediction_covariance):
            # an excess beyond it is more than over-fitting predicts, and a missing effect is not excluded
            out["effect_not_excluded"] = {"validation_p_value": held["p_value"], "threshold": test["threshold"],
                                          "variance_inflation": held.get("variance_inflation")}
            out["evidence"] += (f"; confidence low: the held-out excess is more than the fitted model's own "
                                f"uncertainty accounts for (validation p = {held['p_value']:.2g} with the noise "
                                f"inflated {held.get('variance_inflation', 1.0):.2f} x on average, threshold "
                                f"{test['threshold']:.1g}), so a missing effect is not excluded: with more poses "
                                f"(or fewer parameters) diagnose again")
        return "over-fitting", out
    if not structure["structured"] and structure["isotropic"] and homogeneous and bb_share < BLACK_BOX_NOTHING:
        out["noise_consistent"] = noise_statement(data, factor)
        if "validation" in test:
            out["noise_consistent"]["factor_validation"] = test["validation"]["noise_factor"]
        out["evidence"] = (f"the excess (noise factor {factor:.2f}) has no structure: no F-test of "
                           f"{structure['n_tests']} (joint errors following any joint or metadata column, "
                           f"harmonics per revolution and per screw period, base- and tool-frame trends) below "
                           f"{structure['threshold']:.1g}, equal variance in x, y, z "
                           f"(Bartlett p = {structure['isotropy']['p_value']:.2g}), a black-box regression on joints "
                           f"and metadata explains {100 * max(bb_share, 0.0):.0f} % of the residual variance under "
                           f"cross-validation. A noise of {out['noise_consistent']['text']} would make the data "
                           f"consistent." + tail)
        near = near_structure(structure)
        if near is not None:
            out["near_structure"] = near
            out["evidence"] += (f"; confidence low: the strongest pattern, {describe_where(near['test'])}, has "
                                f"p = {near['p_value']:.2g}, short of the threshold {near['threshold']:.2g} by less "
                                f"than {NEAR_STRUCTURE_FACTOR:g}x (family-wise p = {near['family_wise_p']:.2g}): an "
                                f"effect on some poses only looks like this; more poses where it shows would tell it "
                                f"from noise")
        aniso = near_anisotropy(structure)
        if aniso is not None:
            out["near_anisotropy"] = aniso
            out["evidence"] += (f"; confidence low: the residual's variance differs between x, y and z at Bartlett "
                                f"p = {aniso['p_value']:.2g}, short of the threshold {aniso['threshold']:.1g} by less "
                                f"than {NEAR_STRUCTURE_FACTOR:g}x: an effect along one direction (a holder sagging "
                                f"along gravity, a scale along one axis) looks like this; the same poses with "
                                f"another payload or tool orientation would tell it from noise")
        both = weak_signals_together(near, aniso)
        if both is not None:  # two independent tests of "noise only", each short of its threshold, reject it together
            out["weak_signals_together"] = both
            out.pop("noise_consistent")  # not noise: no noise model is offered that "would make the data consistent"
            out["where"] = (f"{describe_where(near['test'])} (family-wise p = {near['family_wise_p']:.2g}), and "
                            f"a variance unequal between x, y and z (Bartlett p = {aniso['p_value']:.2g})")
            out["evidence"] = ("the excess is not noise alone: the strongest pattern of the structure tests and "
                               "Bartlett's test of equal variance in x, y and z each fall short of their thresholds, "
                               f"but together (Fisher's combination of the two p-values) they reject pure noise at "
                               f"p = {both['p_value']:.2g} (threshold {both['threshold']:.1g}); no candidate effect "
                               f"fits; the residual follows {out['where']}; confidence low: an effect on some poses "
                               f"only, or along one direction, outside the library; more poses where it shows, or the "
                               f"same poses with another payload or tool orientation, would locate it" + tail)
            return "unexplained", out
        return "understated noise", out
    if structure["structured"] and not homogeneous:
        out["where"] = (targets_words(structure["targets"]) + "; and "
                        + describe_where(structure["best"], structure["revolute_spectra"]))
    elif structure["structured"]:
        out["where"] = describe_where(structure["best"], structure["revolute_spectra"])
    elif not homogeneous:
        out["where"] = targets_words(structure["targets"])
    elif not structure["isotropic"]:
        s2 = structure["isotropy"]["weighted_variance"]
        axis = max(s2, key=s2.get)
        out["where"] = (f"mostly along {axis} of the base frame (weighted variance "
                        + ", ".join(f"{k} {v:.2f}" for k, v in s2.items())
                        + f", Bartlett p = {structure['isotropy']['p_value']:.2g})")
    else:
        out["where"] = (f"no single joint, frequency or direction; a black-box regression on joints and metadata "
                        f"explains {100 * bb_share:.0f} % of the residual variance under cross-validation")
    out["evidence"] = ("no candidate effect fits (none lowers the cross-validated error by 5 % within its physical "
                       "domain and magnitude prior); the residual follows " + out["where"])
    best = structure["best"]
    if structure["structured"] and best["family"] == "candidate signature":
        out["evidence"] += (f"; '{best['variable']}' fits it in sample but was not added: it does not predict "
                            f"held-out blocks of the cross-validation, or its estimate is implausible (see rejected)")
    out["evidence"] += _spectrum_words(rejected) + tail
    return "unexplained", out


def format_outcome(diag) -> str:
    """The answer in words, with its evidence and the rejected candidates (text output of ``diagnose``)."""
    lines = []
    st = diag.where.get("structure")
    if st:
        lines += ["", f"Structure of the rigid residuals ({st['n_tests']} F-tests, threshold {st['threshold']:.1g}; "
                      f"isotropy: Bartlett p = {st['isotropy']['p_value']:.2g})"]
        lines += [f"  {describe_where(t)}" for t in st["tests"][:3]]
        for sp in diag.where.get("revolute_spectra", []):
            lines.append(f"  spectrum of joint {sp['joint']}'s error: peak at {sp['peak_cycles_per_revolution']:g} "
                         f"cycles per revolution ({100 * sp['peak_share']:.0f} % of the residual variance, "
                         f"p = {sp['peak_p_value']:.2g}; resolution {sp['resolution_cycles_per_revolution']:.2g} "
                         f"cycles per revolution over the {sp['range_rad']:.2g} rad it moved)")
    lines += ["", "The answer"]
    o = diag.outcome
    v = diag.verdict
    if o in ("explained", "partly explained"):
        joints = getattr(diag, "effect_joints", {}) or {}
        named = [e + (f" (joint{'s' if len(joints[e]) > 1 else ''} {', '.join(joints[e])})" if joints.get(e) else "")
                 for e in v["effects"]]
        lines.append(f"  {o} by {' + '.join(named)}: " + v["evidence"])
    elif o == "understated noise":
        lines.append("  consistent with an understated noise model: " + v["evidence"])
    else:
        lines.append(f"  {o}: " + v["evidence"])
    if getattr(diag, "confidence", "high") == "low":
        lines.append("  confidence: low (see the words above)")
    for s in diag.equivalence_sets:
        if len(s["members"]) > 1:
            lines.append(f"  equivalence set of {s['effect']}: {', '.join(s['members'])}; separated by "
                         f"{s['separating_measurement']}")
    if diag.cannot_size:
        lines.append(f"  cannot size {', '.join(c['effect'] for c in diag.cannot_size)}: "
                     f"{diag.cannot_size[0]['reason']}")
    if diag.per_target:
        lines.append("  per target: " + "; ".join(
            f"{t['target']}: {t['outcome']}" + (f" by {' + '.join(t['named_effects'])}" if t["named_effects"] else "")
            for t in diag.per_target))
        lines.append(f"  {diag.targets_evidence}")
    for r in diag.rejected:
        lines.append(f"  rejected {r['effect']} ({r['stage']}): {r['reason']}")
    return "\n".join(lines) + "\n"
