"""import-robot keeps the URDF links' <inertial>: link masses and centres of mass for the gravity loads.

Units: lengths in mm (the URDF's are m), masses in kg, torques in N mm.  Expected values
are closed forms of a planar two-link arm: the body of each joint is the mass-weighted
sum of its links (a fixed child link merged into the body of the joint that carries it),
and the shoulder torque is ``g`` times the moment of the masses beyond it.
"""

from __future__ import annotations

import numpy as np
import pytest

from hyperstat.solver.diagnosis.effects import gravity_loads
from hyperstat.solver.errors import ModelError
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.robot_import import read_urdf

URDF = """<?xml version="1.0"?>
<robot name="two_link">
  <link name="base"><inertial><mass value="50"/><origin xyz="0 0 0.1"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="upper"><inertial><mass value="{m1}"/><origin xyz="0.25 0 0"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="fore"><inertial><mass value="4"/><origin xyz="0.2 0 0"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="tool"><inertial><mass value="1"/><origin xyz="0 0 0.05"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz="0.5 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="fore"/><child link="tool"/><origin xyz="0.4 0 0"/></joint>
</robot>
"""


def test_urdf_inertials_become_link_masses(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(URDF.format(m1=6.0))
    mech = read_urdf(path)
    masses = mech.metadata["masses"]
    assert set(masses) == {"shoulder", "elbow"}  # the base does not move: left out
    assert masses["shoulder"]["mass"] == pytest.approx(6.0)
    np.testing.assert_allclose(masses["shoulder"]["com"], [250.0, 0.0, 500.0], atol=1e-9)
    # the elbow's body: the forearm (4 kg at x = 700 mm) and the tool merged into it (1 kg at 900, 0, 550)
    assert masses["elbow"]["mass"] == pytest.approx(5.0)
    np.testing.assert_allclose(masses["elbow"]["com"], [(4 * 700 + 900) / 5, 0.0, (4 * 500 + 550) / 5], atol=1e-9)
    assert "fore, tool" in masses["elbow"]["source"]
    # the shoulder carries the moment of every mass beyond it about its horizontal axis, at home (arm level)
    tau = gravity_loads(mech, Kinematics(mech), np.zeros((1, 2)), np.zeros(1))[0]
    g = 9.81
    expected_shoulder = g * (6.0 * 250.0 + 4.0 * 700.0 + 1.0 * 900.0)
    expected_elbow = g * (4.0 * 200.0 + 1.0 * 400.0)
    # the sign follows the axis (+y): a mass at +x under gravity -z turns the arm about +y by a positive torque
    np.testing.assert_allclose(tau, [expected_shoulder, expected_elbow], rtol=1e-9)


def test_a_negative_urdf_mass_is_refused(tmp_path):
    path = tmp_path / "bad.urdf"
    path.write_text(URDF.format(m1=-2.0))
    with pytest.raises(ModelError, match=r"link 'upper': <inertial> mass value -2 kg is not a plausible link mass "
                                         r"\(a mass is >= 0"):
        read_urdf(path)
