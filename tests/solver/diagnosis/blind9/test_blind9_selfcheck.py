"""The cheap part of the eleventh blind generator's self-checks (``selfcheck.py``), no diagnose run.

Units: mm, rad.  The imported robots' kinematics against own DH products written from the robot
files, gravity against -dV/dq, the effects' equations at known points, the case list's counts.
"""
from __future__ import annotations

import collections

from tests.solver.diagnosis.blind9 import selfcheck
from tests.solver.diagnosis.blind9.cases import CASES


def test_kinematics_gravity_and_effect_equations():
    for name, (own, kin) in selfcheck.check_serial_fk(n=5).items():
        assert own < 1e-8 and kin < 1e-8, name
    g, _ = selfcheck.check_gravity()
    for name, v in g.items():
        assert v < 1e-4, name
    for what, ok in selfcheck.check_effects().items():
        assert ok, what


def test_the_case_list_has_the_briefs_counts():
    count = collections.Counter(
        (c["kind"], "parallel" if c["family"] in ("tx7", "hexa") else "serial") for c in CASES)
    assert count[("in", "serial")] == 20 and count[("in", "parallel")] == 20
    assert count[("out", "serial")] + count[("out", "parallel")] == 20
    assert sum(v for (k, _), v in count.items() if k == "none") == 6
    assert sum(v for (k, _), v in count.items() if k == "under") == 6


def test_the_judging_rules_on_hand_written_answers():
    from tests.solver.diagnosis.blind9.score import judge
    case = [c for c in CASES if c["name"] == "lf_harm2_2"][0]
    truth = {"visibility": 1.4}
    named_in_set = {"outcome": "explained", "confidence": "high", "named_effects": ["angle-scale"],
                    "equivalence_sets": [{"members": ["angle-scale", "angle-harmonic-2.0"]}],
                    "ambiguous": True, "effect_joints": {"angle-scale": ["2"]}}
    v = judge(case, truth, named_in_set)
    assert v["ok"] and not v["named_outright"] and not v["confidently_wrong"]
    wrong = dict(named_in_set, equivalence_sets=[{"members": ["angle-scale"]}], ambiguous=False)
    v = judge(case, truth, wrong)
    assert not v["ok"] and v["confidently_wrong"]
    outright = {"outcome": "explained", "confidence": "high", "named_effects": ["angle-harmonic-2"],
                "equivalence_sets": [{"members": ["angle-harmonic-2"]}], "ambiguous": False,
                "effect_joints": {"angle-harmonic-2": ["2"]}}
    v = judge(case, truth, outright)
    assert v["ok"] and v["named_outright"] and v["right_joint"] == "yes"
    out_case = [c for c in CASES if c["kind"] == "out"][0]
    assert judge(out_case, truth, dict(outright, confidence="low"))["ok"]
    assert judge(out_case, truth, outright)["confidently_wrong"]
    assert judge(out_case, truth, {"outcome": "understated noise"})["confidently_wrong"]
    none_case = [c for c in CASES if c["kind"] == "none"][0]
    assert judge(none_case, {}, {"outcome": "no significant gap"})["ok"]
    assert not judge(none_case, {}, {"outcome": "unexplained"})["ok"]
    assert not judge(none_case, {}, None)["ok"]
    assert not judge(case, {"visibility": 0.5}, outright)["counted"]
