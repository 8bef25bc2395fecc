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
