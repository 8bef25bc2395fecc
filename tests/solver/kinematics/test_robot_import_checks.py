"""Robot files refused in one sentence (issue 31): malformed URDF graphs, implausible values, declarations twice.

Units: mm and rad inside; the files state theirs (URDF: m and rad; DH tables: as declared).

Every case goes through ``hyperstat import-robot``: exit 2, one sentence naming the file and the
joint, link or field at fault, no traceback, no model file.  The good file of each kind imports.
"""

from __future__ import annotations

import pytest

from tests.conftest import assert_refused, run_cli

URDF = """<?xml version="1.0"?>
<robot name="r3">
  <link name="base"/>
  <link name="l1"/>
  <link name="l2"/>
  <link name="l3"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.3" rpy="0 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="0" velocity="0"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.4 0 0" rpy="0 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="0" velocity="0"/></joint>
  <joint name="j3" type="prismatic"><parent link="l2"/><child link="l3"/><origin xyz="0.3 0 0" rpy="0 0 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.2" effort="0" velocity="0"/></joint>
</robot>
"""

J2 = '<parent link="l1"/><child link="l2"/>'

URDF_CASES = [
    # malformed graphs: never a chain with a joint silently dropped
    ("missing parent link", (J2, '<parent link="lX"/><child link="l2"/>'), "joint 'j2' names parent link 'lX', which the URDF does not declare"),
    ("missing child link", ('<link name="l3"/>', ""), "joint 'j3' names child link 'l3', which the URDF does not declare"),
    ("closed loop (a link with two parents)", ("</robot>", '  <joint name="j4" type="fixed"><parent link="l3"/><child link="l1"/></joint>\n</robot>'),
     "link 'l1' is the child of two joints ('j1' and 'j4'): a closed loop"),
    ("closed loop (no root)", ('<parent link="base"/><child link="l1"/>', '<parent link="l3"/><child link="l1"/>'),
     "links l1, l2, l3 are not reached from the root link 'base': their joints form a closed loop"),
    ("joint onto itself", (J2, '<parent link="l2"/><child link="l2"/>'), "joint 'j2' joins link 'l2' to itself"),
    ("zero axis", ('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>'), "joint 'j2': axis xyz=\"0 0 0\" is not a direction"),
    ("mimic joint on the chain", ('<axis xyz="0 1 0"/>', '<axis xyz="0 1 0"/><mimic joint="j1" multiplier="1"/>'),
     "joint 'j2' mimics another joint; mimic joints are not supported"),
    ("mimic of an unknown joint", ('<axis xyz="0 1 0"/>', '<axis xyz="0 1 0"/><mimic joint="j9"/>'),
     "joint 'j2' mimics joint 'j9', which the URDF does not declare"),
    ("two links of one name", ('<link name="l3"/>', '<link name="l3"/><link name="l3"/>'), "link 'l3' is declared twice"),
    ("two joints of one name", ('<joint name="j3"', '<joint name="j2"'), "joint 'j2' is declared twice"),
    ("unknown joint type", ('type="prismatic"', 'type="sliding"'), "joint 'j3' has type 'sliding'"),
    # non-finite and implausible values
    ("origin not finite", ('xyz="0.4 0 0"', 'xyz="nan 0 0"'), "joint 'j2': origin xyz must be a finite number"),
    ("origin of 1e308 m", ('xyz="0.4 0 0"', 'xyz="1e308 0 0"'), "joint 'j2': origin x = 1e+308 m is not a plausible length"),
    ("origin in mm", ('xyz="0.4 0 0"', 'xyz="400 0 0"'), "origin x = 400 m is not a plausible length (at most 100 m): it looks like millimetres"),
    ("rpy in degrees", ('xyz="0.4 0 0" rpy="0 0 0"', 'xyz="0.4 0 0" rpy="0 0 90"'), "joint 'j2': origin yaw = 90 rad is beyond 2 pi rad (a turn): it looks like degrees"),
    ("limits in degrees", ('lower="-2" upper="2"', 'lower="-170" upper="170"'), "joint 'j2': limit lower = -170 rad is beyond 4 pi rad (two turns): it looks like degrees"),
    ("a joint that cannot move", ('lower="-2" upper="2"', 'lower="1" upper="1"'), "limit lower 1 must be below upper 1"),
    ("not XML", ("</robot>", ""), "cannot read the URDF (not well-formed XML"),
]


@pytest.mark.parametrize("case, edit, message", URDF_CASES, ids=[c[0] for c in URDF_CASES])
def test_malformed_urdf_is_refused(tmp_path, case, edit, message):
    assert edit[0] in URDF, case
    path = tmp_path / "robot.urdf"
    path.write_text(URDF.replace(edit[0], edit[1], 1))
    out = tmp_path / "out.skel.json"
    assert_refused(["import-robot", path, "--out", out], "robot.urdf", message, outputs=(out,))


def test_the_good_urdf_imports(tmp_path):
    path = tmp_path / "robot.urdf"
    path.write_text(URDF)
    code, text, err = run_cli(["import-robot", path, "--out", tmp_path / "r.skel.json"])
    assert code == 0 and "2 revolute, 1 prismatic joints" in text, err


DH = """format: hyperstat-dh
version: 1
name: r2
convention: dh
units: {length: mm, angle: deg}
joints:
  - {name: "1", type: R, a: 312, alpha: -90, d: 670, theta: 0, min: -180, max: 180}
  - {name: "2", type: R, a: 1075, alpha: 0, d: 0, theta: -90, min: -60, max: 75}
joint_map:
  units: {angle: deg}
  joints:
    "1": {J1: 1}
    "2": {J2: -1, offset: 0.5}
"""

DH_CSV = """# convention: dh
# name: r2
joint,type,a[mm],alpha[deg],d[mm],theta[deg],min[deg],max[deg]
1,R,312,-90,670,0,-180,180
2,R,1075,0,0,-90,-60,75
"""

DH_CASES = [
    # degrees labelled as radians, absurd magnitudes (YAML and CSV)
    ("yaml", "angles in degrees labelled rad", ("angle: deg}", "angle: rad}"),
     "joints[0].alpha = -90 rad is beyond 2 pi rad (a turn): it looks like degrees"),
    ("yaml", "ranges of +-180 rad", ("alpha: -90, d: 670, theta: 0, min: -180", "alpha: -1.5, d: 670, theta: 0, min: -180"),
     None),
    ("yaml", "a = 1e308", ("a: 1075", "a: 1e308"), "joints[1].a = 1e+308 mm is not a plausible length (at most 100 m)"),
    ("yaml", "a length in metres that is millimetres", ("length: mm", "length: m"),
     "joints[0].a = 312 m is not a plausible length (at most 100 m): it looks like millimetres"),
    ("csv", "angles in degrees labelled rad", ("alpha[deg],d[mm],theta[deg],min[deg],max[deg]",
                                               "alpha[rad],d[mm],theta[rad],min[rad],max[rad]"),
     "row 4, column 'alpha' = -90 rad is beyond 2 pi rad (a turn): it looks like degrees"),
    ("csv", "a = 1e308", ("1075", "1e308"), "row 5, column 'a' = 1e+308 mm is not a plausible length"),
    # declarations twice
    ("yaml", "a key twice in a row", ("a: 1075,", "a: 1075, a: 1076,"), "key 'a' is declared twice (line 8)"),
    ("yaml", "a model joint twice in the joint map", ('    "2": {J2: -1, offset: 0.5}', '    "2": {J2: -1}\n    2: {J2: 1}'),
     "joint_map.joints declares model joint '2' twice"),
    ("csv", "a column twice", ("a[mm],alpha", "a[mm],a[mm],alpha"), "column 'a' appears twice"),
    ("csv", "a header line twice", ("# name: r2", "# name: r2\n# convention: modified-dh"), "header 'convention' is declared twice"),
    # a header the CSV form does not read (the twelfth blind generator's '# tool:' line came out as no tool at all)
    ("csv", "a tool header line", ("# name: r2", "# name: r2\n# tool: 0 0 120 0 0 0"),
     "line 3: header 'tool' is not read from a CSV DH table"),
    # the joint map naming a model joint as a controller joint
    ("yaml", "joint map self-reference", ('"2": {J2: -1, offset: 0.5}', '"2": {"2": -1}'),
     "joint_map.joints.2: '2' is the name of a model joint; the keys of an entry name the controller's joints (e.g. J2)"),
    ("yaml", "joint-map offset beyond a turn", ("offset: 0.5", "offset: 400"),
     "joint_map.joints.2.offset = 400 deg is not a plausible angle"),
]


@pytest.mark.parametrize("kind, case, edit, message", DH_CASES, ids=[f"{c[0]}: {c[1]}" for c in DH_CASES])
def test_implausible_or_doubly_declared_dh_tables_are_refused(tmp_path, kind, case, edit, message):
    text = DH if kind == "yaml" else DH_CSV
    assert edit[0] in text, case
    if message is None:  # the ranges of +-180 in a table whose angles say rad
        text = text.replace("angle: deg}", "angle: rad}").replace("alpha: -90", "alpha: -1.5")
        message = "joints[0].min = -180 rad is beyond 4 pi rad (two turns): it looks like degrees"
    else:
        text = text.replace(edit[0], edit[1], 1)
    path = tmp_path / f"robot.{kind}"
    path.write_text(text)
    out = tmp_path / "out.skel.json"
    assert_refused(["import-robot", path, "--out", out], f"robot.{kind}", message, outputs=(out,))


@pytest.mark.parametrize("kind", ["yaml", "csv"])
def test_the_good_dh_tables_import(tmp_path, kind):
    path = tmp_path / f"robot.{kind}"
    path.write_text(DH if kind == "yaml" else DH_CSV)
    code, _, err = run_cli(["import-robot", path, "--out", tmp_path / "r.skel.json", "--quiet"])
    assert code == 0, err
