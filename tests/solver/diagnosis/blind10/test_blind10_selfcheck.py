"""The cheap part of the twelfth blind generator's self-checks, and its judging rules on hand-written
answers (no diagnose run).  Units: mm, rad."""
import numpy as np

from tests.solver.diagnosis.blind10 import score, selfcheck


def test_imported_robots_match_own_dh_products_and_effects_hold():
    fk = selfcheck.check_fk(np.random.default_rng(3), n=10)
    assert max(fk.values()) < 1e-9, fk
    assert all(selfcheck.check_effects().values())


def test_judging_rules_on_hand_written_answers():
    t_in = {"name": "a", "kind": "in", "family": "stan", "model": "stan", "visibility": 1.2,
            "effect": "angle-harmonic-1", "joints": ["1"]}
    ans = {"outcome": "explained", "named_effects": ["angle-harmonic-1.0"], "equivalence_sets": [],
           "confidence": "high", "ambiguous": False, "effect_joints": {"angle-harmonic-1": ["1", "2"]}}
    v = score.judge(t_in, ans)
    assert v["success"] and v["named_outright"] and v["right_joint"] == "part"
    wrong = dict(ans, named_effects=["compliance"], effect_joints={})
    v = score.judge(t_in, wrong)
    assert not v["success"] and v["confidently_wrong"]
    t_out = dict(t_in, kind="out", effect="screw-hotspot")
    assert score.judge(t_out, dict(ans, confidence="low"))["success"]
    assert score.judge(t_out, ans)["confidently_wrong"]
    assert not score.judge(t_out, {"outcome": "understated noise"})["success"]
    t_none = dict(t_in, kind="none", effect=None, visibility=None)
    assert score.judge(t_none, {"outcome": "no significant gap"})["success"]
    assert not score.judge(t_none, None)["success"]  # a diagnose failure is a miss
    t_low = dict(t_in, visibility=0.5)
    assert not score.judge(t_low, ans)["counted"]
