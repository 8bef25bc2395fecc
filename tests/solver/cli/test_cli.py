"""The command line: analyze on a template and on a model file, JSON contract, errors."""

import json
import subprocess
import sys

import pytest

from hyperstat.cad_plugin.cli import main
from hyperstat.solver import save_model

from tests.conftest import TEMPLATES


def test_analyze_json_contract(tmp_path, capsys):
    out = tmp_path / "a.json"
    assert main(["analyze", str(TEMPLATES / "slider_crank.py"), "--verify", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    params = {p["name"]: p for p in doc["parameters"]}
    assert len(params) == 15
    for p in params.values():
        assert p["verdict"] in ("normalisation", "redundant", "forced", "coupled", "free")
        assert p["influential"] in (True, False, None)
    assert all(set(r) >= {"terms"} for r in doc["relations"])
    assert all(c["confirmed"] for c in doc["verification"])
    text = capsys.readouterr().out
    assert "dJ4" in text and "forced" in text


def test_template_model_file_and_overrides_agree(tmp_path, slider_crank):
    model = save_model(slider_crank, tmp_path / "sc.json")
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    assert main(["analyze", str(TEMPLATES / "slider_crank.py"), "--json", str(a), "--quiet"]) == 0
    assert main(["analyze", str(model), "--json", str(b), "--quiet"]) == 0
    va = [(p["name"], p["verdict"], p["influential"]) for p in json.loads(a.read_text())["parameters"]]
    vb = [(p["name"], p["verdict"], p["influential"]) for p in json.loads(b.read_text())["parameters"]]
    assert va == vb


@pytest.mark.parametrize(
    "args,message",
    [
        (["analyze", "missing.json"], "missing.json: no such file"),
        (["analyze", "x.txt"], "unknown source kind '.txt'"),
        (["analyze", str(TEMPLATES / "slider_crank.py"), "-p", "L9=3"], "unknown parameter 'L9'; valid parameters: L1 [mm]"),
        (["analyze", str(TEMPLATES / "slider_crank.py"), "-p", "L1=abc"], "parameter 'L1': 'abc' is not a number"),
        (["analyze", str(TEMPLATES / "slider_crank.py"), "-p", "L1=-4"], "parameter 'L1' must be > 0 mm"),
    ],
)
def test_user_errors_exit_2_with_one_sentence(args, message, capsys, tmp_path):
    (tmp_path / "x.txt").write_text("")
    args = [str(tmp_path / a) if a == "x.txt" else a for a in args]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert message in err
    assert "Traceback" not in err and err.count("\n") == 1


def test_console_script_runs(tmp_path):
    out = tmp_path / "o.json"
    proc = subprocess.run([sys.executable, "-m", "hyperstat.cad_plugin.cli", "analyze", str(TEMPLATES / "slider_crank.py"),
                           "-p", "L1=50mm", "--json", str(out), "--quiet"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(out.read_text())["source"]["parameters"]["L1"] == 50.0
