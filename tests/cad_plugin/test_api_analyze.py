"""``hs.analyze``: two independent samples by default, as the command line, and a way to ask for more."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import hyperstat as hs
from hyperstat.solver.errors import HyperstatError
from hyperstat.solver.kinematics.modelfile import mechanism_from_dict
from tests.solver.kinematics.fourbar import fourbar_document


def test_two_samples_by_default_and_more_on_request():
    mech = hs.load("slider_crank")
    two = hs.analyze(mech)
    assert two.stability["samples"] == 2 and two.stability["seeds"] == [0, 1] and two.stability["stable"]
    assert "stable across 2 independent samples" in two.stability["summary"]
    three = hs.analyze(mech, seed=4, samples=3)
    assert three.stability["seeds"] == [4, 5, 6] and three.stability["stable"]
    assert hs.analyze(mech, samples=1).stability is None
    # the verdicts are the first sample's, whatever the number of samples
    assert [p.verdict for p in two.parameters] == [p.verdict for p in hs.analyze(mech, samples=1).parameters]


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_a_bad_number_of_samples_is_one_clear_error(bad):
    with pytest.raises(HyperstatError, match="samples must be an integer of at least 1"):
        hs.analyze(hs.load("slider_crank"), samples=bad)


def test_a_verdict_that_depends_on_the_sample_is_not_silent():
    # one configuration of the crossed isogram: its admissible subspace depends on which one
    # (docs/assembly-branches.md), so two samples disagree
    mech = mechanism_from_dict(fourbar_document(100.0, 300.0, 100.0, 300.0, -0.2, +1, (-np.pi, 0.0)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = hs.analyze(mech, configurations=1)
    assert not result.stability["stable"]
    messages = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    assert any("depends on the sample" in m for m in messages), messages
