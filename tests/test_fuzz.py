"""Fuzzing the readers (hypothesis): any input is read or refused with the project's own error.

Units: lengths in mm, angles in rad.  Inputs are random text, random JSON values, and
random mutations of good documents (deleted keys, replaced values, truncated text).
"""

from __future__ import annotations

import copy
import json

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hyperstat.solver.errors import HyperstatError
from hyperstat.solver.analysis.hypotheses import parse_hypotheses
from hyperstat.solver.calibration.measurements import parse_measurements
from hyperstat.solver.kinematics.modelfile import mechanism_from_dict, mechanism_to_dict

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.floats(allow_nan=True) | st.text(max_size=8),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=6), children, max_size=4),
    max_leaves=12,
)


def _paths(doc, prefix=()):
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from _paths(v, prefix + (i,))


def _mutate(doc, data):
    doc = copy.deepcopy(doc)
    paths = [p for p in _paths(doc) if p]
    for _ in range(data.draw(st.integers(1, 3))):
        path = data.draw(st.sampled_from(paths))
        parent = doc
        try:
            for key in path[:-1]:
                parent = parent[key]
            if data.draw(st.booleans()) and isinstance(parent, dict):
                parent.pop(path[-1], None)
            else:
                parent[path[-1]] = data.draw(json_values)
        except (KeyError, IndexError, TypeError):
            pass
    return doc


def _accepts_or_refuses(fn, *args):
    try:
        fn(*args)
    except HyperstatError:
        pass  # a clear refusal; anything else propagates and fails the test


@FUZZ
@given(data=st.data())
def test_model_reader_mutations(slider_crank, data):
    _accepts_or_refuses(mechanism_from_dict, _mutate(mechanism_to_dict(slider_crank), data), "fuzz.json")


@FUZZ
@given(doc=json_values)
def test_model_reader_random_json(doc):
    _accepts_or_refuses(mechanism_from_dict, doc, "fuzz.json")


MEASUREMENT = ("# hyperstat measurements, version 1\n# mechanism: slider_crank\n# noise: 0.005 mm + 0.005 mm/m\n"
               "pose,q1[rad],x[mm],y[mm],z[mm],temperature[degC]\nP1,0.1,1,2,3,20\nP2,0.2,1.5,2,3,21\n")


@FUZZ
@given(cut=st.integers(0, len(MEASUREMENT)), insert=st.text(max_size=12), at=st.integers(0, len(MEASUREMENT)))
def test_measurement_reader_mutations(slider_crank, cut, insert, at):
    text = MEASUREMENT[:at] + insert + MEASUREMENT[at:]
    _accepts_or_refuses(parse_measurements, text[: max(cut, 1)] if cut < len(MEASUREMENT) else text, slider_crank,
                        "fuzz.csv")


@FUZZ
@given(text=st.text(max_size=300))
def test_measurement_reader_random_text(slider_crank, text):
    _accepts_or_refuses(parse_measurements, "# hyperstat measurements, version 1\n" + text, slider_crank, "fuzz.csv")


HYPOTHESES = {"format": "hyperstat-hypotheses", "version": 1,
              "axes": {"a2": {"element": "2"}, "a3": {"element": "3"}},
              "points": {"p2": {"element": "2"}},
              "hypotheses": [{"id": "h1", "parallel": ["a2", "a3"]}, {"id": "h2", "point_on_axis": ["p2", "a3"]}]}


@FUZZ
@given(data=st.data())
def test_hypothesis_reader_mutations(slider_crank, data):
    _accepts_or_refuses(parse_hypotheses, _mutate(HYPOTHESES, data), slider_crank, "fuzz.yaml")


@FUZZ
@given(doc=json_values)
def test_hypothesis_reader_random(slider_crank, doc):
    _accepts_or_refuses(parse_hypotheses, doc, slider_crank, "fuzz.yaml")


def test_the_good_documents_are_accepted(slider_crank):
    """The fuzzing starts from documents the readers accept (else it would only test refusals)."""
    mechanism_from_dict(json.loads(json.dumps(mechanism_to_dict(slider_crank))))
    parse_measurements(MEASUREMENT, slider_crank, "good.csv")
    parse_hypotheses(yaml.safe_load(yaml.safe_dump(HYPOTHESES)), slider_crank, "good.yaml")
