"""Measurement files refused in one sentence (issue 31): conflicting declarations, implausible values.

Units: mm and rad inside; the files state theirs (the FANUC-like files: controller joints in deg,
positions in m, three SMRs per pose).
"""

from __future__ import annotations

import re

import pytest

from hyperstat.solver.calibration.measurements import parse_measurements
from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.robot_import import import_robot
from tests.conftest import TEMPLATES, assert_refused
from tests.solver.calibration.fanuc_like import DH_YAML, Campaign


@pytest.fixture(scope="module")
def robot_file(tmp_path_factory):
    """The FANUC-like robot and 10 poses with three SMRs (priors in the header), positions in m."""
    tmp = tmp_path_factory.mktemp("meas")
    (tmp / "r.dh.yaml").write_text(DH_YAML)
    c = Campaign(5)
    return import_robot(tmp / "r.dh.yaml"), c.csv(c.poses(10), "P")


def _cell(text: str, column: str, value: str, row: int = 0) -> str:
    lines = text.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("pose,"))
    cols = lines[head].split(",")
    cells = lines[head + 1 + row].split(",")
    cells[cols.index(column)] = value
    lines[head + 1 + row] = ",".join(cells)
    return "\n".join(lines) + "\n"


def _header(text: str, line: str) -> str:
    return text.replace("# noise:", f"{line}\n# noise:", 1)


CASES = [
    # the same reflector declared twice, or a declaration that conflicts with the columns
    ("two priors for one reflector", lambda t: _header(t, "# target SMR2: 1 2 3"),
     "header 'target smr2' is already declared in line"),
    ("a prior spelled in another case", lambda t: _header(t, "# target smr2: 1 2 3"),
     "header 'target smr2' is already declared in line"),
    ("a prior for a reflector without columns", lambda t: _header(t, "# target SMR9: 1 2 3"),
     "gives a prior for a target that has no columns (targets: SMR1, SMR2, SMR3)"),
    ("reflectors differing only by case", lambda t: t.replace("x_SMR3", "x_smr1").replace("y_SMR3", "y_smr1")
     .replace("z_SMR3", "z_smr1").replace("# target SMR3", "# other"), "targets 'SMR1' and 'smr1' differ only by case"),
    ("the noise declared twice", lambda t: _header(t, "# noise: 0.5 mm + 0 mm/m"), "header 'noise' is already declared"),
    # implausible values, with their units
    ("a position in mm labelled m", lambda t: _cell(t, "y_SMR2[m]", "1520.5"),
     "row 8, column 'y_SMR2[m]' = 1520.5 m is not a plausible length (at most 100 m): it looks like millimetres"),
    ("a non-finite position", lambda t: _cell(t, "x_SMR1[m]", "inf"), "column 'x_SMR1[m]': the value is infinite"),
    ("a tracker 1e308 mm away", lambda t: _header(t, "# tracker: 1e308 0 0 0 0 0"),
     "header 'tracker' = 1e+308 mm is not a plausible length"),
    ("a tracker turned in degrees", lambda t: _header(t, "# tracker: 1000 0 0 0 0 30"),
     "header 'tracker' = 30 rad is beyond 2 pi rad (a turn): it looks like degrees"),
    ("an absurd noise", lambda t: t.replace("# noise: 0.01 mm", "# noise: 1e6 mm"),
     "header 'noise', constant term = 1e+06 mm is not a plausible tracker noise"),
]


@pytest.mark.parametrize("case, edit, message", CASES, ids=[c[0] for c in CASES])
def test_conflicting_or_implausible_measurements_are_refused(robot_file, case, edit, message):
    mech, text = robot_file
    bad = edit(text)
    assert bad != text, case
    with pytest.raises(DataError) as err:
        parse_measurements(bad, mech, "meas.csv")
    sentence = str(err.value)
    assert sentence.startswith("meas.csv") and message in sentence and "\n" not in sentence, sentence


def test_the_good_file_reads(robot_file):
    mech, text = robot_file
    data = parse_measurements(text, mech, "meas.csv")
    assert data.n_targets == 3 and set(data.target_priors) == {"SMR1", "SMR2", "SMR3"}


SIX_D = ("# hyperstat measurements, version 1\n# mechanism: slider_crank\n# noise: 0.005 mm + 0.005 mm/m\n"
         "# orientation noise: 0.05 mrad\npose,q1[rad],x[mm],y[mm],z[mm],rx[rad],ry[rad],rz[rad],temperature[degC]\n"
         "P1,0.1,1,2,3,0.01,0.02,0.03,20\nP2,0.2,1.5,2,3,0.01,0.02,0.04,21\n")


@pytest.mark.parametrize("old, new, message", [
    ("0.01,0.02,0.03", "0.01,0.02,45", "row 6, column 'rz[rad]' = 45 rad is beyond 2 pi rad (a turn): it looks like degrees"),
    ("0.05 mrad", "5 rad", "header 'orientation noise' = 5 rad is not a plausible orientation noise"),
    (",20\n", ",2000\n", "row 6, column 'temperature[degC]' = 2000 degC is not a plausible workshop temperature"),
    ("P2,0.2", "P2,9", "row 7, column 'q1[rad]': 9 is outside the joint range"),
])
def test_six_d_rows_and_metadata_are_checked(slider_crank, old, new, message):
    parse_measurements(SIX_D, slider_crank, "d.csv")
    with pytest.raises(DataError, match=re.escape(message)):
        parse_measurements(SIX_D.replace(old, new, 1), slider_crank, "d.csv")


def test_a_joint_in_degrees_labelled_rad_is_named_so(tmp_path):
    """Through the command line: exit 2, one sentence, the hint at degrees, no output."""
    text = SIX_D.replace("P2,0.2", "P2,150", 1)
    data = tmp_path / "d.csv"
    data.write_text(text)
    assert_refused(["identify", TEMPLATES / "slider_crank.py", data, "--json", tmp_path / "out.json"],
                   "column 'q1[rad]': 150 is outside the joint range", "it looks like degrees (write 'q1[deg]')",
                   outputs=(tmp_path / "out.json",))
