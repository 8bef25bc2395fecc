"""Measurement files: exact round trip and one clear error per kind of bad file (units: mm, rad)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hyperstat.solver.errors import DataError
from hyperstat.solver.calibration.measurements import MeasurementSet, NoiseModel, parse_noise, read_measurements, write_measurements


@pytest.fixture()
def good(tmp_path, slider_crank):
    rng = np.random.default_rng(0)
    k = 5
    lo, hi = slider_crank.ranges[slider_crank.actuated].T
    q = lo + rng.random((k, len(lo))) * (hi - lo)
    data = MeasurementSet([f"P{i}" for i in range(k)], ["1"], q, rng.normal(size=(k, 3)) * 100,
                          metadata={"temperature": 20 + rng.random(k), "dir1": np.array([1.0, -1, 1, -1, 1])},
                          noise=NoiseModel(0.005, 0.005), tracker=np.array([1.0, 2, 3, 0, 0, 0.1]),
                          target=np.array([0.0, 0, -10]))
    path = write_measurements(tmp_path / "m.csv", data, slider_crank)
    return path, data


def test_round_trip(good, slider_crank):
    path, data = good
    back = read_measurements(path, slider_crank)
    assert back.pose == data.pose
    np.testing.assert_allclose(back.q, data.q, rtol=1e-11)
    np.testing.assert_allclose(back.position, data.position, rtol=1e-11)
    np.testing.assert_allclose(back.metadata["temperature"], data.metadata["temperature"], rtol=1e-11)
    assert back.noise == data.noise
    np.testing.assert_array_equal(back.tracker, data.tracker)
    assert "q1[rad]" in path.read_text() and "x[mm]" in path.read_text()


def edit(path, old, new, count=1):
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, count))
    return path


def data_line(path, row):
    return path.read_text().splitlines()[row - 1]


@pytest.mark.parametrize("mutation, message", [
    (lambda p: edit(p, "x[mm],", ""), r"column 'x\[mm\]' \(measured position\) is missing"),
    (lambda p: edit(p, "q1[rad]", "q1[grad]"), r"column 'q1\[grad\]' must be in rad or deg"),
    (lambda p: edit(p, "z[mm]", "z[cm]"), r"column 'z\[cm\]' must be in mm or m"),
    (lambda p: edit(p, "temperature[degC]", "temperature[K]"), r"'temperature\[K\]' must be in degC"),
    (lambda p: edit(p, "# hyperstat measurements, version 1", "pose,x"), r"first line must be"),
    (lambda p: edit(p, "pose,", "id,"), r"'id' is not part of the format|column 'pose' is missing"),
    # six comment lines and the column line: P0 is file line 8, P1 line 9, P3 line 11
    (lambda p: edit(p, "P3", "P1"), r"row 11, column 'pose': pose 'P1' already appears in row 9"),
    (lambda p: edit(p, "noise: 0.005 mm", "noise: 5 um"), r"header 'noise' must read"),
    (lambda p: edit(p, "mechanism: slider_crank", "mechanism: tripteor_x7"), r"for mechanism 'tripteor_x7'"),
    (lambda p: edit(p, "tracker: 1 2 3 0 0 0.1", "tracker: 1 2 3"), r"header 'tracker' needs 6 numbers"),
])
def test_bad_header_or_columns(good, slider_crank, mutation, message):
    path, _ = good
    mutation(path)
    with pytest.raises(DataError, match=message):
        read_measurements(path, slider_crank)


def test_bad_values_name_row_and_column(good, slider_crank):
    path, _ = good
    lines = path.read_text().splitlines()
    header = lines.index(next(line for line in lines if line.startswith("pose,")))
    columns = lines[header].split(",")
    row = header + 3  # second data row, 1-based file line
    cases = [
        ("x[mm]", "nan", r"row %d, column 'x\[mm\]': the value is NaN" % row),
        ("y[mm]", "inf", r"row %d, column 'y\[mm\]': the value is infinite" % row),
        ("z[mm]", "1,2mm", None),
        ("q1[rad]", "abc", r"row %d, column 'q1\[rad\]': 'abc' is not a number" % row),
        ("q1[rad]", "99", r"row %d, column 'q1\[rad\]': 99 is outside the joint range" % row),
        ("dir1", "0", r"row %d, column 'dir1': an approach direction is -1 or \+1" % row),
    ]
    original = path.read_text()
    for column, value, message in cases:
        fields = lines[row - 1].split(",")
        fields[columns.index(column)] = value
        new = list(lines)
        new[row - 1] = ",".join(fields)
        path.write_text("\n".join(new) + "\n")
        with pytest.raises(DataError, match=message or r"row %d: \d+ values for %d columns" % (row, len(columns))):
            read_measurements(path, slider_crank)
        path.write_text(original)


def test_repeated_pose_and_empty_file(good, slider_crank):
    path, _ = good
    lines = path.read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("pose,"))
    dup = lines[header + 1].split(",")
    dup[0] = "P99"
    path.write_text("\n".join(lines + [",".join(dup)]) + "\n")
    with pytest.raises(DataError, match=r"rows \d+ and \d+ repeat the same pose"):
        read_measurements(path, slider_crank)
    path.write_text("\n".join(lines[: header + 1]) + "\n")
    with pytest.raises(DataError, match="no data rows"):
        read_measurements(path, slider_crank)
    with pytest.raises(DataError, match="no such measurement file"):
        read_measurements(path.with_name("absent.csv"), slider_crank)


@pytest.mark.parametrize("text", ["5 um", "-1 mm + 0 mm/m", "0 mm + 0 mm/m", "nan mm + 1 mm/m"])
def test_bad_noise_text(text):
    with pytest.raises(DataError, match="noise"):
        parse_noise(text, "--noise")


def test_noise_model_text_round_trip():
    n = NoiseModel(0.007, 0.003)
    assert parse_noise(n.text()) == n
    assert n.sigma(np.array([2000.0]))[0] == pytest.approx(0.007 + 0.003 * 2)


def test_units_deg_and_m_are_converted_explicitly(good, slider_crank):
    """The same file in deg and m reads to the same rad and mm values (factors pi/180 and 1000)."""
    path, data = good
    lines = path.read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("pose,"))
    cols = lines[header].split(",")
    cols = [c.replace("q1[rad]", "q1[deg]").replace("[mm]", "[m]") for c in cols]
    out = lines[:header] + [",".join(cols)]
    for line in lines[header + 1:]:
        vals = line.split(",")
        for i, c in enumerate(cols):
            if c == "q1[deg]":
                vals[i] = repr(float(vals[i]) * 180.0 / np.pi)
            elif c.endswith("[m]"):
                vals[i] = repr(float(vals[i]) / 1000.0)
        out.append(",".join(vals))
    path.write_text("\n".join(out) + "\n")
    back = read_measurements(path, slider_crank)
    np.testing.assert_allclose(back.q, data.q, rtol=1e-11)
    np.testing.assert_allclose(back.position, data.position, rtol=1e-11)


def test_several_targets_one_row_per_observation(tmp_path, slider_crank):
    """Columns x_<T> per target: one row per seen (pose, target); an empty group is an unseen target."""
    text = ("# hyperstat measurements, version 1\n# target A: 1 2 3\n# target B: 4 5 6 m\n"
            "pose,q1[rad],x_A[mm],y_A[mm],z_A[mm],x_B[m],y_B[m],z_B[m]\n"
            "P1,0.1,1,2,3,0.004,0.005,0.006\nP2,0.2,7,8,9,,,\n")
    path = tmp_path / "t.csv"
    path.write_text(text)
    d = read_measurements(path, slider_crank)
    assert d.target_names == ["A", "B"] and d.pose == ["P1/A", "P1/B", "P2/A"] and d.pose_id == ["P1", "P1", "P2"]
    np.testing.assert_array_equal(d.target_index, [0, 1, 0])
    np.testing.assert_allclose(d.position, [[1, 2, 3], [4, 5, 6], [7, 8, 9]], rtol=1e-12)
    np.testing.assert_allclose(d.target_priors["B"], [4000, 5000, 6000])
    path.write_text(text.replace("P2,0.2,7,8,9,,,", "P2,0.2,7,8,9,1,,"))
    with pytest.raises(DataError, match=r"row 6, column 'y_B\[m\]'"):
        read_measurements(path, slider_crank)


def test_orientation_as_quaternion_or_rotation_vector(tmp_path, slider_crank):
    """A quaternion (w, x, y, z) and the rotation vector in deg read to the same rotation vector (rad)."""
    axis = np.array([1.0, -2.0, 2.0]) / 3.0
    angle = 0.7
    quat = [math.cos(angle / 2), *(float(v) for v in math.sin(angle / 2) * axis)]
    rv_deg = np.degrees(angle * axis)
    head = "# hyperstat measurements, version 1\n# orientation noise: 0.1 mrad\n"
    a, b = tmp_path / "q.csv", tmp_path / "r.csv"
    a.write_text(head + "pose,q1[rad],x[mm],y[mm],z[mm],quat_w,quat_x,quat_y,quat_z\nP1,0.1,1,2,3,"
                 + ",".join(repr(v) for v in quat) + "\n")
    b.write_text(head + "pose,q1[rad],x[mm],y[mm],z[mm],rx[deg],ry[deg],rz[deg]\nP1,0.1,1,2,3,"
                 + ",".join(repr(float(v)) for v in rv_deg) + "\n")
    ra, rb = read_measurements(a, slider_crank), read_measurements(b, slider_crank)
    np.testing.assert_allclose(ra.rotation[0], angle * axis, rtol=1e-12)
    np.testing.assert_allclose(rb.rotation[0], angle * axis, rtol=1e-12)
    assert ra.rotation_noise == pytest.approx(1e-4)
    b.write_text(b.read_text().replace("# orientation noise: 0.1 mrad\n", ""))
    with pytest.raises(DataError, match="orientation columns need a header line '# orientation noise"):
        read_measurements(b, slider_crank)
