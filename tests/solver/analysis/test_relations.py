"""Relations printed from a well-conditioned basis (issue 29 item 6), on a Sarrus linkage and the templates.

Units: coefficients per rad or per mm.  The Sarrus linkage (:mod:`tests.solver.analysis.sarrus`) is
folded steeply with nearly equal links, so that its constraint matrix has a singular-value gap of only
about 1e8: the analysis' relation basis carries round-off near 1e-9, and a pivot taken in parameter
order on round-off (the former rule: any entry above 1e-9, the relation led by its first such entry)
divided it into coefficients up to 8.5e11 on all three seeds (measured before the change).  Expected facts are invariants: the printed relations are as many as
the relation subspace's dimension, independent, with moderate coefficients, and they lie in the
analysis' subspace at their printed digits (the principal angle).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hyperstat.solver.analysis.stationarity import analyze, relations_span
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.modelfile import load_model

from tests.solver.analysis.sarrus import write_sarrus


@pytest.fixture(scope="module")
def sarrus(tmp_path_factory):
    path = write_sarrus(tmp_path_factory.mktemp("sarrus") / "sarrus.json", fold=1.3, upper=119.0, angle=1.2)
    mech = load_model(path)
    kin = Kinematics(mech)
    kin.check_home()
    return mech, kin


def _basis(result, mech, kin):
    """The analysis' relation subspace (rows, dimensionless) over the parameters the relations use."""
    names = [p.name for p in mech.parameters]
    scale = kin.parameter_scale
    null = result.admissible_basis  # admissible defects, full space
    used = sorted({n for r in result.relations for n in r.terms}, key=names.index)
    idx = [names.index(n) for n in used]
    # the relations are the constraints on these coordinates: the orthogonal complement of the admissible
    # subspace restricted to them
    u, s, _ = np.linalg.svd(null[idx], full_matrices=True)
    rank = int(np.sum(s > 1e-6))
    return u[:, rank:].T, used, scale[idx]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sarrus_relations_are_distinct_moderate_and_span_the_analysis(sarrus, seed):
    mech, kin = sarrus
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, kinematics=kin, seed=seed)
    assert result.mobility == 1 and result.gap < 1e10  # the ill-conditioned case (symmetric Sarrus: 1e14)
    rels = result.relations
    assert len(rels) == result.rank  # no forced defect: every constraint is a relation
    coefficients = [abs(c) for r in rels for c in r.terms.values()]
    assert max(coefficients) < 1e3, [r.text for r in rels]
    assert len({r.text for r in rels}) == len(rels)
    basis, used, scale = _basis(result, mech, kin)
    span = relations_span(rels, basis, used, scale, rels[0].digits)
    assert span["rank"] == len(rels) and span["angle"] <= 1e-6, span
    assert not any("printed relations span" in w for w in result.warnings)
    # every printed relation holds on the admissible subspace (as printed: its text's digits)
    names = [p.name for p in mech.parameters]
    for r in rels:
        row = np.zeros(len(names))
        for n, c in r.terms.items():
            row[names.index(n)] = c * kin.parameter_scale[names.index(n)]
        assert np.linalg.norm(row @ result.admissible_basis) <= 1e-6 * np.linalg.norm(row), r.text
