"""Serial robots from DH / modified-DH tables and URDF (units: mm, rad; files in deg and m where stated).

Expected values come from independent forward kinematics: the tables' own matrix products
written out here, and yourdfpy's evaluation of the URDF (not hyperstat's)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.robot_import import import_robot, read_urdf

PUMA_MDH = [  # alpha_{i-1} (deg), a_{i-1} (m), theta_i (deg), d_i (m): Craig's PUMA 560 table
    (0, 0.0, 0, 0.0), (-90, 0.0, 0, 0.2435), (0, 0.4318, 0, -0.0934),
    (90, -0.0203, 0, 0.4331), (-90, 0.0, 0, 0.0), (90, 0.0, 0, 0.0)]


def craig(alpha, a, theta, d):
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    return np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d], [0, 0, 0, 1]])


def test_modified_dh_csv_in_metres_and_degrees(tmp_path):
    lines = ["# name: puma", "# convention: modified-dh",
             "joint,type,alpha[deg],a[m],theta[deg],d[m],min[deg],max[deg]"]
    lines += [f"{i + 1},R,{al},{a},{th},{d},-170,170" for i, (al, a, th, d) in enumerate(PUMA_MDH)]
    path = tmp_path / "puma.csv"
    path.write_text("\n".join(lines) + "\n")
    mech = import_robot(path)
    assert mech.name == "puma" and len(mech.joints) == 6
    assert np.allclose(mech.ranges, np.radians([[-170, 170]] * 6))
    q = np.random.default_rng(0).uniform(-2, 2, (15, 6))
    pose, _ = Kinematics(mech).forward(q)
    for k in range(len(q)):
        t = np.eye(4)
        for (al, a, th, d), qi in zip(PUMA_MDH, q[k]):
            t = t @ craig(math.radians(al), 1000 * a, math.radians(th) + qi, 1000 * d)
        assert np.abs(t - pose[k]).max() < 1e-9


def test_prismatic_row_and_base_tool_frames(tmp_path):
    doc = """format: hyperstat-dh
version: 1
name: rp
convention: dh
units: {length: mm, angle: rad}
base: {origin: [10, 20, 30], rpy: [0.1, 0.2, 0.3]}
tool: {origin: [0, 0, 50], rpy: [0, 0.5, 0]}
joints:
  - {type: R, a: 100, alpha: 0.3, d: 5, theta: 0.2}
  - {type: P, a: 7, alpha: -0.4, d: 40, theta: 0.1, min: 0, max: 200}
"""
    path = tmp_path / "rp.yaml"
    path.write_text(doc)
    mech = import_robot(path)
    assert [j.type for j in mech.joints] == ["R", "P"]
    from hyperstat.solver.kinematics.robot_import import rpy_matrix

    def frame(o, rpy):
        t = np.eye(4)
        t[:3, :3] = rpy_matrix(rpy)
        t[:3, 3] = o
        return t

    def dh(th, d, a, al):
        ct, st, ca, sa = math.cos(th), math.sin(th), math.cos(al), math.sin(al)
        return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])

    q = np.array([[0.3, 20.0], [-1.0, 150.0]])
    pose, _ = Kinematics(mech).forward(q)
    for k in range(2):
        t = frame([10, 20, 30], [0.1, 0.2, 0.3]) @ dh(0.2 + q[k, 0], 5, 100, 0.3) @ dh(0.1, 40 + q[k, 1], 7, -0.4)
        t = t @ frame([0, 0, 50], [0, 0.5, 0])
        assert np.abs(t - pose[k]).max() < 1e-9


URDF = """<?xml version="1.0"?>
<robot name="test_arm">
  <link name="world"/><link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/>
  <link name="l4"/><link name="flange"/><link name="tcp"/>
  <joint name="fix0" type="fixed"><parent link="world"/><child link="base"/>
    <origin xyz="0.1 -0.2 0.05" rpy="0.01 0.02 0.3"/></joint>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.4" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.15 0.0 0.2" rpy="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j3" type="continuous"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.0 0.05 0.7" rpy="0 0.2 0"/><axis xyz="0.6 0 -0.8"/></joint>
  <joint name="j4" type="prismatic"><parent link="l3"/><child link="l4"/>
    <origin xyz="0.3 0 0" rpy="0 0 0.4"/><axis xyz="-1 0 0"/><limit lower="0" upper="0.2" effort="1" velocity="1"/></joint>
  <joint name="fix1" type="fixed"><parent link="l4"/><child link="flange"/>
    <origin xyz="0.05 0 0" rpy="0 1.5707963267948966 0"/></joint>
  <joint name="fix2" type="fixed"><parent link="flange"/><child link="tcp"/>
    <origin xyz="0 0 0.12" rpy="0.1 0 0"/></joint>
</robot>
"""


def test_urdf_chain_with_fixed_joints_matches_yourdfpy(tmp_path):
    import yourdfpy

    path = tmp_path / "arm.urdf"
    path.write_text(URDF)
    mech = read_urdf(path)
    assert [j.name for j in mech.joints] == ["j1", "j2", "j3", "j4"]
    assert [j.type for j in mech.joints] == ["R", "R", "R", "P"]
    assert mech.joints[3].range == (0.0, 200.0)  # m -> mm
    robot = yourdfpy.URDF.load(str(path), load_meshes=False)
    rng = np.random.default_rng(1)
    q = np.c_[rng.uniform(-2, 2, (20, 3)), rng.uniform(0, 200, 20)]
    pose, _ = Kinematics(mech).forward(q)
    for k in range(len(q)):
        robot.update_cfg({"j1": q[k, 0], "j2": q[k, 1], "j3": q[k, 2], "j4": q[k, 3] / 1000.0})
        t = robot.get_transform("tcp", "world")
        assert np.abs(1000 * t[:3, 3] - pose[k, :3, 3]).max() < 1e-9
        assert np.abs(t[:3, :3] - pose[k, :3, :3]).max() < 1e-12


def test_urdf_errors_name_the_file(tmp_path):
    path = tmp_path / "tree.urdf"
    path.write_text(URDF.replace('<link name="tcp"/>', '<link name="tcp"/><link name="cam"/>').replace(
        "</robot>", '<joint name="c" type="revolute"><parent link="l3"/><child link="cam"/><axis xyz="0 0 1"/>'
                    '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>\n</robot>'))
    from hyperstat.solver.errors import ModelError

    with pytest.raises(ModelError, match=r"tree.urdf: several tip links \(.*\); name one with --tip"):
        read_urdf(path)
    assert len(read_urdf(path, tip="tcp").joints) == 4
    with pytest.raises(ModelError, match="tip link 'nope' is not in the URDF"):
        read_urdf(path, tip="nope")


def test_unknown_robot_file_kind(tmp_path):
    path = tmp_path / "robot.txt"
    path.write_text("x")
    with pytest.raises(DataError, match="unknown robot file kind '.txt'"):
        import_robot(path)
