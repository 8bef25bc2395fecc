"""Joint maps: controller values to model joints (units: rad, mm; controller values in deg and m here)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.joint_map import joint_map_from_dict


def test_sign_offset_ratio_and_coupling():
    m = joint_map_from_dict({"units": {"angle": "deg", "length": "m"}, "joints": {
        "1": {"M1": 1, "ratio": 100},          # motor angle through a 100:1 gear
        "2": {"J2": -1, "offset": 90},         # sign and zero offset
        "3": {"J3": 1, "J2": 1},               # FANUC coupling
        "4": {"Z": 1, "offset": 0.01}},        # prismatic, metres
    }, {"1": "R", "2": "R", "3": "R", "4": "P"})
    assert m.controller == ["M1", "J2", "J3", "Z"]
    ctrl = np.array([[3600.0, 10.0, 25.0, 0.2]])  # deg, deg, deg, m
    si = ctrl * [math.pi / 180, math.pi / 180, math.pi / 180, 1000.0]
    q = m.apply(si)[0]
    np.testing.assert_allclose(q, [math.radians(36.0), math.radians(80.0), math.radians(35.0), 210.0], rtol=1e-12)
    np.testing.assert_allclose(m.inverse(q[None]), si, rtol=1e-12)


@pytest.mark.parametrize("doc, message", [
    ({"joints": {"1": {"J1": 1}}}, "units must state the controller units"),
    ({"units": {"angle": "grad"}, "joints": {"1": {"J1": 1}}}, "unit 'grad' is not a angle unit"),
    ({"units": {"angle": "deg"}, "joints": {"1": {"J1": 1, "ratio": 0}}}, r"joints.1.ratio must be a finite non-zero"),
    ({"units": {"angle": "deg"}, "joints": {"1": {"J1": "one"}}}, r"joints.1.J1 must be a finite number"),
    ({"units": {"angle": "deg"}, "joints": {"9": {"J1": 1}}}, "no entry for model joint '1'"),
])
def test_bad_maps_name_the_field(doc, message):
    with pytest.raises(DataError, match=message):
        joint_map_from_dict(doc, {"1": "R"}, "map.yaml")


def test_mixed_joint_types_are_refused():
    with pytest.raises(DataError, match="cannot be driven by controller joint 'J1' of the other type"):
        joint_map_from_dict({"units": {"angle": "deg"}, "joints": {"1": {"J1": 1}, "2": {"J1": 1, "Z": 1}}},
                            {"1": "R", "2": "P"})
