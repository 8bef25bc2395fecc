"""What the worst-case searches share or split for speed (issue 39) gives the numbers computed without it.

Units: mm and rad.

* the structured candidates are computed once per workspace *by value*: every stage builds its own
  ``Workspace`` of the same declaration, and a cache keyed on the object missed them all;
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
