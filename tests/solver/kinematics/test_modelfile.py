"""Model file: exact round trip, schema, and messages that name the field at fault."""

import copy
import json

import jsonschema
import pytest

from hyperstat.solver import ModelError, load_model, mechanism_from_dict, mechanism_to_dict, save_model
from hyperstat.solver.kinematics.modelfile import dumps_model, model_schema


def test_round_trip_is_exact(tmp_path, slider_crank):
    path = save_model(slider_crank, tmp_path / "sc.skel.json")
    again = load_model(path)
    assert again == slider_crank
    assert dumps_model(again) == path.read_text()
    jsonschema.validate(json.loads(path.read_text()), model_schema())


def test_schema_is_a_valid_json_schema():
    jsonschema.Draft202012Validator.check_schema(model_schema())


def _doc(slider_crank):
    return copy.deepcopy(mechanism_to_dict(slider_crank))


@pytest.mark.parametrize(
    "mutate,message",
    [
        (lambda d: d.pop("base"), r"field 'base' is missing"),
        (lambda d: d.update(version=2), r"field 'version' is 2, but this hyperstat reads version 1"),
        (lambda d: d.update(format="other"), r"field 'format' must be \"hyperstat-model\""),
        (lambda d: d["units"].update(length="m"), r"field 'units.length' must be \"mm\", got \"m\""),
        (lambda d: d["chains"][0]["elements"][1]["placement"].update(z_axis=[0, 0, 2]),
         r"chains\[0\]\.elements\[1\]\.placement\.z_axis must be a unit vector"),
        (lambda d: d["chains"][0]["elements"][1].update(type="S"), r"chains\[0\]\.elements\[1\]\.type' must be one of"),
        (lambda d: d["chains"][0]["elements"][1]["defects"].append("Q"), r"chains\[0\]\.elements\[1\]\.defects\[6\]"),
        (lambda d: d["chains"][1].update(start="nowhere"), r"chain 'slide' starts at frame 'nowhere'"),
        (lambda d: d.update(output="tool"), r"output frame 'tool' is not reached"),
        (lambda d: d["chains"][0]["elements"][1].update(home=99.0), r"home 99 of joint '2' lies outside its range"),
        (lambda d: d["chains"][1]["elements"][0].update(name="2"), r"name '2' is already used"),
        (lambda d: d["chains"][0]["elements"][1].pop("range"), r"field 'chains\[0\]\.elements\[1\]\.range' is missing"),
    ],
)
def test_malformed_model_names_the_field(slider_crank, mutate, message):
    doc = _doc(slider_crank)
    mutate(doc)
    with pytest.raises(ModelError, match=message):
        mechanism_from_dict(doc, source="m.json")


def test_cycle_in_chains_is_named(slider_crank):
    doc = _doc(slider_crank)
    doc["chains"].append({"name": "a", "start": "X", "end": "Y", "elements": [
        {"kind": "frame", "name": "ta", "placement": {"origin": [0, 0, 0], "z_axis": [0, 0, 1], "x_axis": [1, 0, 0]}}]})
    doc["chains"].append({"name": "b", "start": "Y", "end": "X", "elements": [
        {"kind": "frame", "name": "tb", "placement": {"origin": [0, 0, 0], "z_axis": [0, 0, 1], "x_axis": [1, 0, 0]}}]})
    with pytest.raises(ModelError, match=r"chains form a cycle that never reaches the base frame 'R0'"):
        mechanism_from_dict(doc)


def test_unreadable_files(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{ not json")
    with pytest.raises(ModelError, match=r"bad.json: not valid JSON \(line 1, column 3"):
        load_model(bad)
    with pytest.raises(ModelError, match=r"no such model file"):
        load_model(tmp_path / "missing.json")
