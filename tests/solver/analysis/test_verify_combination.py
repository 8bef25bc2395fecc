"""``--verify`` in combination: all admissible directions at once, and each relation violated inside them.

Units: mm, rad.  Expected orders come from the Taylor expansion of the closure: an admissible
defect leaves a residual of second order (or round-off for an exactly mobile family), a
violated relation a first-order residual equal to the linear prediction.
"""

from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest

from hyperstat.solver.analysis.stationarity import Relation, analyze
from hyperstat.solver.analysis.verify import combination_checks, verify
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.modelfile import mechanism_from_dict
from tests.solver.kinematics.fourbar import fourbar_document

ISOGRAM = (100.0, 300.0, 100.0, 300.0)
CRANK_ROCKER = (40.0, 120.0, 80.0, 100.0)


def _analysed(dims, sigma, crank_range, home):
    m = mechanism_from_dict(fourbar_document(*dims, home, sigma, crank_range))
    kin = Kinematics(m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return m, kin, analyze(m, kinematics=kin)


@pytest.mark.parametrize("dims, sigma, crank_range, home", [
    (ISOGRAM, +1, (-np.pi, 0.0), -0.2),
    (ISOGRAM, -1, (-np.pi, 0.0), -2.9),
    (CRANK_ROCKER, +1, (-np.pi, np.pi), 0.5),
])
def test_combinations_are_confirmed_at_every_configuration(dims, sigma, crank_range, home):
    m, kin, res = _analysed(dims, sigma, crank_range, home)
    delta = 1e-4
    checks = combination_checks(m, res, delta=delta, kinematics=kin, seed=3)
    assert [c.kind for c in checks] == ["combination admissible"] + ["combination, relation violated"] * len(
        res.relations)
    assert all(c.confirmed for c in checks), [(c.subject, c.note) for c in checks if not c.confirmed]
    lc = kin.length_scale
    adm = checks[0]
    assert f"all {res.admissible_basis.shape[1]} admissible directions" in adm.subject
    # second order: at most 100 delta^2 L, and ten times smaller defects leave ~100 times less (or round-off)
    assert adm.residual < 1e2 * delta ** 2 * lc
    assert adm.residual < 1e-9 * lc or adm.residual / adm.residual_small > 50
    for c in checks[1:]:  # first order, as predicted
        assert abs(c.residual - c.predicted) < 0.05 * c.predicted
        assert 8 < c.residual / c.residual_small < 12


def test_a_forced_direction_slipped_into_the_admissible_basis_is_caught():
    m, kin, res = _analysed(CRANK_ROCKER, +1, (-np.pi, np.pi), 0.5)
    wrong = copy.copy(res)
    e = np.zeros((kin.n_xi, 1))
    e[m.parameter_index["dJ3"]] = 1.0  # a twist about the coupler: forced on a crank-rocker
    basis = np.hstack([res.admissible_basis, e])
    wrong.admissible_basis = np.linalg.qr(basis)[0]
    wrong.relations = []
    checks = combination_checks(m, wrong, kinematics=kin)
    assert len(checks) == 1 and not checks[0].confirmed
    assert checks[0].residual > 1e-3 * 1e-4 * kin.length_scale


def test_a_relation_that_does_not_exist_is_caught():
    m, kin, res = _analysed(ISOGRAM, +1, (-np.pi, 0.0), -0.2)
    wrong = copy.copy(res)
    # da1 and db2 are free (in-plane): a relation between them is not a condition of assembly
    wrong.relations = list(res.relations) + [Relation({"da1": 1.0, "db2": -1.0}, "da1 - db2 = 0")]
    checks = verify(m, wrong, kinematics=kin)
    fake = [c for c in checks if c.subject == "da1 - db2 = 0" and c.kind == "combination, relation violated"]
    assert len(fake) == 1 and not fake[0].confirmed
    assert all(c.confirmed for c in checks if c.subject != "da1 - db2 = 0")
