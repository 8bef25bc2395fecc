"""The assembly conditions' values together (:mod:`hyperstat.solver.tolerances.whole_drawing`) where a core is idle.

Units: mm and rad.  The planar 3-RRR leaves more than three closure rows to the plays: its values together come from
the decision rule's linear programmes at several configurations, half of them solved by a forked child when a core
is idle (:func:`hyperstat.solver.forked.beside`).  The same programmes give the same bits wherever they are solved.
"""

from __future__ import annotations

import copy
import json
import warnings

import numpy as np
import pytest

from hyperstat.cad_plugin.templates import build_template
from hyperstat.solver import forked
from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.tolerances.classification import classify
from hyperstat.solver.tolerances.clearance import _constraint_blocks, _lift, assembly_tolerances, clearance_model
from hyperstat.solver.tolerances.whole_drawing import _decision_rule, allocate_together

from tests.conftest import TEMPLATES
from tests.solver.tolerances.common import recorded_forks


@pytest.fixture(scope="module")
def rrr3():
    mech = build_template(TEMPLATES / "planar_3rrr.py").mechanism()
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, kinematics=kin)
    cl = classify(mech, result, kin)
    items = cl.by_class("assembly")
    q = result.configurations[:4]
    single = assembly_tolerances(mech, items, cl.declaration, q, search=False)  # the single values at q
    for t in items:
        t.value = single[t.id]["value"]
        t.evidence.setdefault("assemblability", {})["worst_configuration"] = np.asarray(single[t.id]["worst_q"]).tolist()
    return mech, kin, cl, q


def test_the_values_together_are_the_same_bits_with_a_child_solving_half_the_programmes(rrr3, monkeypatch):
    mech, kin, cl, q = rrr3
    started = recorded_forks(monkeypatch)
    out = {}
    for idle in (False, True):
        monkeypatch.setattr(forked, "idle_core", lambda idle=idle: idle)
        c = copy.deepcopy(cl)
        evidence = allocate_together(c, mech, kin, q)
        out[idle] = (json.dumps(evidence, sort_keys=True), [(t.id, t.value, t.value_source) for t in c.items])
        if not idle:
            assert not started
    assert "more than three closure rows" in json.loads(out[True][0])["method"]  # the decision rule's path
    assert json.loads(out[True][0])["solved"] >= 2
    # children: the decision rule's programmes and the blocks of each condition alone (clearance._solve)
    assert len(started) >= 2 and all(pid is not None for _, pid in started)
    assert out[True] == out[False]
    # what it says, from the programme itself: the need stated is the decision rule's at the configuration it names
    # (each programme put back with its own configuration), and the values are the single ones scaled by 1 / need
    evidence = json.loads(out[True][0])
    model = clearance_model(mech, cl.declaration)
    items = [t for t in cl.items if t.cls == "assembly"]
    f, ua = _constraint_blocks(model, np.array([evidence["worst"]["configuration"]]), Kinematics(model.mechanism))[0]
    dirs = np.stack([_lift(model, t.direction) for t in items], axis=1)
    alone = np.array([evidence["values_alone"][t.id] for t in items])
    need = _decision_rule(model, f, ua @ dirs, alone)
    assert need == pytest.approx(evidence["single_condition_need"], rel=1e-9)
    assert {i: v for i, v, _ in out[True][1] if i in evidence["values"]} == \
        pytest.approx({t.id: a / max(need, 1.0) for t, a in zip(items, alone)}, rel=1e-9)
