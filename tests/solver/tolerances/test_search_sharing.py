"""What the worst-case searches share or split for speed (issue 39) gives the numbers computed without it.

Units: mm and rad.

* the structured candidates are computed once per workspace *by value*: every stage builds its own
  ``Workspace`` of the same declaration, and a cache keyed on the object missed them all; and once whatever
  sample the caller gives (they start from the workspace's fixed checkpoints): the configurations the
  continuation from the caller's own sample reaches, to its tolerance;
* the bounds' search evaluates each path's own function (``LinearWorstCase.pick``): the same bits as
  the values of both functions;
* the assembly programmes are solved a few blocks at a time (``clearance.LP_GROUP``): the same
  optimum as each block alone, to the solver's tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest

from hyperstat.solver.tolerances import clearance as clr
from hyperstat.solver.tolerances.accuracy import sample_workspace
from hyperstat.solver.tolerances.bounds import LinearWorstCase
from hyperstat.solver.tolerances.workspace import workspace_of
from hyperstat.solver.tolerances.worst_case import workspace_candidates

from tests.solver.tolerances.common import classified


@pytest.fixture(scope="module")
def slider():
    mech, kin, result, cl = classified("slider_crank")
    return mech, kin, result, cl


def test_candidates_are_shared_by_equal_workspaces_and_computed_again_for_another(slider):
    mech, kin, _, _ = slider
    q = sample_workspace(mech, 24, seed=3, kinematics=kin)
    first = workspace_candidates(kin, workspace_of(mech), q)
    again = workspace_candidates(kin, workspace_of(mech), q.copy())  # another Workspace object, the same bounds
    assert again is first  # read from the cache, not computed again
    narrower = workspace_of(mech)
    act = mech.actuated[0]
    narrower.lower = narrower.lower.copy()
    narrower.upper = narrower.upper.copy()
    if not np.isfinite(narrower.upper[act] - narrower.lower[act]) or narrower.upper[act] - narrower.lower[act] >= 6.28:
        narrower.lower[act], narrower.upper[act] = -1.0, 1.0  # a full turn has no corners: give it a box
    else:
        narrower.upper[act] = narrower.lower[act] + 0.5 * (narrower.upper[act] - narrower.lower[act])
    other = workspace_candidates(kin, narrower, q)
    assert other is not first
    # what the cache returns is what a computation gives: the same candidates from a fresh cache
    from hyperstat.solver.tolerances import worst_case

    saved = dict(worst_case._CANDIDATES)
    worst_case._CANDIDATES.clear()
    try:
        fresh = workspace_candidates(kin, workspace_of(mech), q)
    finally:
        worst_case._CANDIDATES.clear()
        worst_case._CANDIDATES.update(saved)
    assert fresh is not first
    assert np.array_equal(fresh[0], first[0]) and fresh[1] == first[1]


@pytest.mark.parametrize("name", ["tripteor_x7", "planar_3rrr"])
def test_candidates_are_the_same_whatever_the_sample_and_those_the_samples_own_starts_reach(name, monkeypatch):
    from hyperstat.solver.tolerances import worst_case

    mech, kin, _, _ = classified(name)
    ws = workspace_of(mech)
    monkeypatch.setattr(worst_case, "_CANDIDATES", {})
    first = sample_workspace(mech, 40, seed=5, kinematics=kin)
    other = sample_workspace(mech, 120, seed=9, kinematics=kin)
    shared = workspace_candidates(kin, ws, first)
    assert workspace_candidates(kin, ws, other) is shared  # another sample: the same candidates, not computed again
    assert len(shared[0]) > 0
    # the second method: continued from the caller's sample (the starts before issue 39's change), a fresh cache
    for sample in (first, other):
        monkeypatch.setattr(worst_case, "_CANDIDATES", {})
        monkeypatch.setattr(worst_case, "_start_pool", lambda kin, workspace: None)
        own_q, own_labels = workspace_candidates(kin, ws, sample)
        monkeypatch.undo()
        assert own_labels == shared[1]
        scale = kin.joint_scale[None, :]
        assert np.max(np.abs(own_q - shared[0]) / scale) < 1e-9


def test_a_passive_joint_a_line_does_not_move_has_no_dead_centre_on_it(monkeypatch):
    """The Tripteor's symmetric lines leave some passive joints still (velocity 1e-20, round-off): the signs of
    that round-off are not dead centres (there were 150-170 of them, depending on the starts)."""
    from hyperstat.solver.kinematics.continuation import continue_nearest
    from hyperstat.solver.tolerances import worst_case

    mech, kin, _, _ = classified("tripteor_x7")
    ws = workspace_of(mech)
    q = sample_workspace(mech, 200, seed=0, kinematics=kin)
    pas, act = np.asarray(mech.passive), np.asarray(mech.actuated)
    lo, hi = ws.actuated_box(mech)
    names = {mech.joints[j].name: i for i, j in enumerate(pas)}, {mech.joints[j].name: i for i, j in enumerate(act)}

    def moving(qd: np.ndarray, label: str) -> bool:
        """Does the dead centre's joint move along its line?  Five points of the line assembled from the dead
        centre, the velocities of paper 1, eq. (3) by least squares (not the candidates' LU path)."""
        joint, axis = label.removeprefix("dead centre of joint ").split(" along joint ")
        p, a = names[0][joint], names[1][axis]
        targets = np.tile(qd[act], (5, 1))
        targets[:, a] = np.linspace(lo[a], hi[a], 5)
        line, cert = continue_nearest(kin, targets, None, mech.home, pool=qd[None, :])
        rows = kin.scaled_rows(kin.evaluate(line[cert.certified], None, "joints").closure_q)
        vel = np.stack([-np.linalg.lstsq(r[:, pas], r[:, act[a]], rcond=None)[0] for r in rows])
        scaled = np.abs(vel) * kin.joint_scale[act[a]] / kin.joint_scale[pas][None, :]
        return bool(scaled[:, p].max() > 1e-9 * scaled.max())

    def dead_centres() -> list:
        monkeypatch.setattr(worst_case, "_CANDIDATES", {})
        cq, labels = workspace_candidates(kin, ws, q)
        return [(qd, lab) for qd, lab in zip(cq, labels) if lab.startswith("dead centre")]

    kept = dead_centres()
    assert kept and all(moving(qd, lab) for qd, lab in kept)
    # without the rule, round-off signs of still joints are taken as dead centres: the check above can fail
    monkeypatch.setattr(worst_case, "NOT_MOVING", 0.0)
    every = dead_centres()
    still = [lab for qd, lab in every if not moving(qd, lab)]
    assert len(still) > 100 and len(every) - len(still) == len(kept)


def test_the_bounds_search_picks_each_paths_own_function_with_the_same_bits():
    rng = np.random.default_rng(7)
    m = rng.normal(size=(4, 3 * 12))

    def rows(q: np.ndarray) -> np.ndarray:  # a smooth function of the configuration, 3 rows, 12 tolerances
        return np.sin(q @ m).reshape(len(q), 3, 12)

    objective = LinearWorstCase(rows, rng.uniform(0.5, 2.0, size=12))
    q = rng.normal(size=(40, 4))
    which = list(rng.choice(["attainable", "triangle"], size=40))
    both = objective.values(q)
    picked = objective.pick(q, which)
    expected = np.array([both[w][k] for k, w in enumerate(which)])
    assert np.array_equal(picked, expected)


def test_grouped_programmes_give_each_blocks_own_optimum(slider):
    mech, kin, result, cl = slider
    items = cl.by_class("assembly")
    model = clr.clearance_model(mech, cl.declaration)
    objective = clr.AssemblyConditions(model, items)
    blocks = clr._constraint_blocks(model, result.configurations[:3], objective.kin)
    pairs = [(cg, ua @ objective.d[n]) for cg, ua in blocks for n in objective.names]
    assert len(pairs) > clr.LP_GROUP  # several groups
    grouped, plays = clr._solve(model, pairs)
    alone = np.array([clr._solve_group(model, [p])[0][0] for p in pairs])
    finite = np.isfinite(alone)
    assert np.array_equal(finite, np.isfinite(grouped))
    assert np.allclose(grouped[finite], alone[finite], rtol=1e-9, atol=1e-12)
    assert len(plays) == len(pairs)
