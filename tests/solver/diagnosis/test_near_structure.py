"""The near-significant structure rule behind an "understated noise" answer (answer.near_structure).

The expected rate comes from the Bonferroni threshold alone: with ``n`` independent tests on a noise-only
residual, the strongest p-value falls in ``[t, 10 t)`` with probability ``(1 - t)^n - (1 - 10 t)^n``.
"""
from __future__ import annotations

import numpy as np

from hyperstat.solver.diagnosis.answer import NEAR_STRUCTURE_FACTOR, near_structure


def test_on_noise_only_residuals_the_rule_fires_as_often_as_the_threshold_says():
    n, draws = 294, 20000
    threshold = 0.001 / n
    rng = np.random.default_rng(40)
    p_min = rng.uniform(size=(draws, n)).min(axis=1)
    fired = [near_structure({"best": {"p_value": p}, "threshold": threshold, "n_tests": n,
                             "structured": bool(p < threshold)}) is not None for p in p_min]
    expected = (1 - threshold) ** n - (1 - NEAR_STRUCTURE_FACTOR * threshold) ** n  # about 0.9 %
    rate = float(np.mean(fired))
    sd = np.sqrt(expected * (1 - expected) / draws)
    assert abs(rate - expected) < 4 * sd, (rate, expected)


def test_a_significant_structure_is_not_near_and_the_family_wise_p_is_bonferronis():
    s = {"best": {"p_value": 2e-6}, "threshold": 1e-5, "n_tests": 100, "structured": True}
    assert near_structure(s) is None  # already structured: the answer is not "understated noise"
    near = near_structure({**s, "structured": False, "best": {"p_value": 4e-5}})
    assert near["family_wise_p"] == 4e-5 * 100


def test_an_understated_noise_answer_near_anisotropy_has_low_confidence():
    """The tenth blind set's reflector holder sagging with the payload (desktop 6R, out of the library) was answered
    "understated noise" with high confidence: noise factor 1.17, no structure test near its threshold, but Bartlett's
    test of equal variance in x, y, z at p = 0.0029, less than 10x above its 1e-3.  On isotropic noise the rule fires
    on 0.9 % of campaigns (a uniform p-value in [1e-3, 1e-2)); here it lowers the confidence and says why."""
    from hyperstat.solver.diagnosis.answer import near_anisotropy, verdict
    from hyperstat.solver.calibration.measurements import NoiseModel

    rng = np.random.default_rng(41)
    fired = np.mean([near_anisotropy({"isotropy": {"p_value": p}}) is not None for p in rng.uniform(size=20000)])
    assert abs(fired - 0.009) < 4 * np.sqrt(0.009 * 0.991 / 20000)

    class Data:
        noise = NoiseModel(0.01, 0.006)

    def answer(bartlett: float) -> tuple:
        structure = {"best": {"p_value": 0.02}, "structured": False, "isotropy": {"p_value": bartlett},
                     "isotropic": bartlett >= 1e-3, "threshold": 3e-6, "n_tests": 326, "targets_homogeneous": True}
        test = {"identification": {"noise_factor": 1.17, "p_value": 3.2e-4}, "threshold": 5e-4}
        return verdict(Data(), None, True, test, None, [], structure, None, {"black_box_share_of_residual": 0.0},
                       None, None, [], [], [], None, None)

    outcome, words = answer(0.0029)
    assert outcome == "understated noise" and words["near_anisotropy"]["p_value"] == 0.0029
    assert "confidence low" in words["evidence"] and "Bartlett p = 0.0029" in words["evidence"]
    outcome, words = answer(0.3)
    assert outcome == "understated noise" and "near_anisotropy" not in words
