"""``hyperstat simulate`` and ``hyperstat identify``: JSON contract, reproducibility, errors (units: mm, rad)."""

from __future__ import annotations

import json


from hyperstat.cad_plugin.cli import main

from tests.conftest import TEMPLATES


def test_simulate_identify_round_trip(tmp_path, capsys):
    src = str(TEMPLATES / "scara.py")
    data, truth, out = tmp_path / "d.csv", tmp_path / "t.json", tmp_path / "id.json"
    assert main(["simulate", src, "--poses", "50", "--validation", "20", "--out", str(data), "--truth", str(truth),
                 "--seed", "3", "--quiet"]) == 0
    val = tmp_path / "d.validation.csv"
    assert val.exists()
    assert main(["identify", src, str(data), "--validation", str(val), "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert {"rank", "condition_number", "parameters", "identification", "validation", "noise_rms"} <= set(doc)
    for key in ("identification", "validation"):
        assert set(doc[key]) >= {"mean", "max", "rms"}
        assert doc[key]["mean"] <= doc[key]["rms"] <= doc[key]["max"]
    assert all({"name", "estimate", "std"} <= set(p) for p in doc["parameters"])
    assert doc["validation"]["rms"] <= 1.2 * doc["noise_rms"]
    true = json.loads(truth.read_text())["truth"]
    est = {p["name"]: p for p in doc["parameters"]}
    # every base estimate is within 4.5 std of the truth plus what it absorbs (the reported combinations)
    expected = {n: true.get(n, 0.0) for n, p in est.items() if p["identifiable"]}
    for u in doc["unidentifiable"]:
        for n, c in u["combination"].items():
            expected[n] += c * (true.get(u["name"], 0.0) - est[u["name"]]["estimate"])
    for n, value in expected.items():
        assert abs(est[n]["estimate"] - value) < 4.5 * est[n]["std"], n
    text = capsys.readouterr().out
    assert "validation" in text and "µm" in text


def test_simulate_is_reproducible(tmp_path):
    src = str(TEMPLATES / "slider_crank.py")
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    for path in (a, b):
        assert main(["simulate", src, "--poses", "20", "--validation", "0", "--out", str(path), "--quiet"]) == 0
    assert a.read_bytes() == b.read_bytes()
    c = tmp_path / "c.csv"
    assert main(["simulate", src, "--poses", "20", "--validation", "0", "--out", str(c), "--seed", "1",
                 "--quiet"]) == 0
    assert a.read_bytes() != c.read_bytes()


def test_d_optimal_simulation_reports_its_gain(tmp_path, capsys):
    src = str(TEMPLATES / "scara.py")
    truth = tmp_path / "t.json"
    assert main(["simulate", src, "--poses", "20", "--validation", "0", "--select", "d-optimal", "--candidates", "200",
                 "--out", str(tmp_path / "d.csv"), "--truth", str(truth)]) == 0
    sel = json.loads(truth.read_text())["pose_selection"]
    assert sel["condition_number"] < sel["random_condition_number"]
    assert "D-optimal poses: condition number" in capsys.readouterr().out


def test_bad_measurement_file_exits_2_without_output(tmp_path, capsys):
    src = str(TEMPLATES / "slider_crank.py")
    bad = tmp_path / "bad.csv"
    bad.write_text("# hyperstat measurements, version 1\npose,q1[grad],x[mm],y[mm],z[mm]\nP1,1,2,3,4\n")
    out = tmp_path / "id.json"
    assert main(["identify", src, str(bad), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "bad.csv" in err and "q1[grad]" in err and err.count("\n") == 1
    assert not out.exists()
    assert main(["simulate", src, "--noise", "5 um", "--out", str(tmp_path / "x.csv")]) == 2
    assert "--noise" in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()


def test_too_few_rows_is_a_user_error(tmp_path, capsys):
    src = str(TEMPLATES / "scara.py")
    data = tmp_path / "d.csv"
    assert main(["simulate", src, "--poses", "3", "--validation", "0", "--out", str(data), "--quiet"]) == 0
    assert main(["identify", src, str(data)]) == 2
    err = capsys.readouterr().err
    assert "3 poses (9 equations), too few" in err
