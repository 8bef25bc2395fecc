"""Commands that write several files write all of them or none: each output made unwritable in turn.

Units: lengths in mm, angles in rad.

For ``report``, ``export-linuxcnc-kins`` and ``export-controller`` (and ``identify`` with two
outputs, ``export-urdf`` with its joint-map side file): a first run writes the outputs; then,
for each output file in turn, that file is made unwritable (``chattr +i`` as root, where
permissions do not bind; a directory in its place otherwise) and the command is run again with
inputs that change every output.  It must exit 2 with one sentence naming that file, leave
every output byte for byte as before, and leave no temporary file or directory behind.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from .conftest import TEMPLATES, run_cli

SC = str(TEMPLATES / "slider_crank.py")




def _snapshot(paths: list[Path]) -> dict:
    return {p: p.read_bytes() for p in paths}


@contextlib.contextmanager
def _unwritable(path: Path):
    """``path`` cannot be replaced while the block runs: immutable (root), else a directory stands in its place."""
    if os.geteuid() == 0 and subprocess.run(["chattr", "+i", str(path)], capture_output=True).returncode == 0:
        try:
            yield
        finally:
            subprocess.run(["chattr", "-i", str(path)], check=True)
        return
    keep = path.read_bytes()
    path.unlink()
    (path / "occupied").mkdir(parents=True)
    try:
        yield
    finally:
        shutil.rmtree(path)
        path.write_bytes(keep)


def _leftovers(folders: list[Path]) -> list[str]:
    return [p.name for d in folders for p in d.iterdir() if p.name.startswith(".")]


def _each_output_unwritable_in_turn(first: list, second: list, outputs: list[Path]) -> None:
    code, _, err = run_cli(first)
    assert code == 0, err
    before = _snapshot(outputs)
    for locked in outputs:
        with _unwritable(locked):
            code, out, err = run_cli(second)
        assert code == 2, (locked, err)
        assert len(err.strip().splitlines()) == 1 and locked.name in err and "Traceback" not in err + out, err
        assert "wrote" not in out  # no line announces a file that was not written
        assert _snapshot(outputs) == before, f"{locked.name} locked: an output changed"
        assert _leftovers(sorted({p.parent for p in outputs})) == [], locked
    code, _, err = run_cli(second)  # and unlocked, the second run writes every file anew
    assert code == 0, err
    after = _snapshot(outputs)
    assert all(after[p] != before[p] for p in outputs if not p.name.endswith(".hal")), \
        "the second run must change the outputs, else the test proves nothing"


def test_report(tmp_path):
    out = tmp_path / "rep"
    files = [out / n for n in ("report.json", "report.md", "report.html", "skeleton_views.png")]
    _each_output_unwritable_in_turn(["report", SC, "--out", str(out), "--quiet"],
                                    ["report", SC, "-p", "L1=31mm", "--out", str(out)], files)


def test_export_linuxcnc_kins(tmp_path):
    """The component name carries the geometry's hash: the second export writes a new .comp beside the old one;
    it is checked at the end (its name is known only then) and taken back with the others."""
    out = tmp_path / "kins"
    model = tmp_path / "tx7.json"
    assert run_cli(["build", str(TEMPLATES / "tripteor_x7.py"), "--model", str(model), "--quiet"])[0] == 0
    first = ["export-linuxcnc-kins", str(model), "--out", str(out), "--name", "hs_kins", "--quiet"]
    second = ["export-linuxcnc-kins", str(model), "--out", str(out), "--name", "hs_kins", "--home", "41=900"]
    _each_output_unwritable_in_turn(first, second, [out / "hs_kins.comp", out / "machine.ini", out / "machine.hal"])


def test_export_controller(tmp_path):
    data = tmp_path / "d.csv"
    assert run_cli(["simulate", SC, "--poses", "30", "--validation", "0", "--out", str(data), "--quiet"])[0] == 0
    other = tmp_path / "d2.csv"
    assert run_cli(["simulate", SC, "--poses", "30", "--validation", "0", "--seed", "1", "--out", str(other),
                 "--quiet"])[0] == 0
    ctl = tmp_path / "ctl" / "machine.json"
    _each_output_unwritable_in_turn(["export-controller", SC, str(data), "--out", str(ctl), "--quiet"],
                                    ["export-controller", SC, str(other), "--out", str(ctl)], [ctl])


def test_identify_json_and_residuals(tmp_path):
    data, other = tmp_path / "d.csv", tmp_path / "d2.csv"
    for seed, path in ((0, data), (1, other)):
        assert run_cli(["simulate", SC, "--poses", "30", "--validation", "0", "--seed", str(seed), "--out", str(path),
                     "--quiet"])[0] == 0
    outs = [tmp_path / "o" / "id.json", tmp_path / "o" / "res.csv"]
    tail = ["--json", str(outs[0]), "--residuals", str(outs[1])]
    _each_output_unwritable_in_turn(["identify", SC, str(data), *tail, "--quiet"],
                                    ["identify", SC, str(other), *tail], outs)


def test_a_new_output_directory_appears_whole(tmp_path):
    """A report into a directory that does not exist: the directory appears in one rename, with every file."""
    model = tmp_path / "tx7.json"
    assert run_cli(["build", str(TEMPLATES / "tripteor_x7.py"), "--model", str(model), "--quiet"])[0] == 0
    out = tmp_path / "a" / "b" / "kins"
    code, text, err = run_cli(["export-linuxcnc-kins", str(model), "--out", str(out), "--name", "k"])
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["k.comp", "machine.hal", "machine.ini"]
    assert _leftovers([tmp_path, tmp_path / "a", out]) == []
    assert text.index("wrote") > 0


@pytest.mark.parametrize("command", ["export-controller", "import-robot", "export-linuxcnc-kins", "report"])
def test_an_unwritable_directory_is_refused_before_the_work(tmp_path, command):
    """An output folder that cannot be written (the issue: PermissionError, exit 1): refused at once, in one
    sentence naming it, before any work."""
    data = tmp_path / "d.csv"
    data.write_text("not even read: the output is checked first")
    robot = tmp_path / "r.urdf"
    robot.write_text("<robot/>")
    locked = tmp_path / "locked"
    locked.mkdir()
    argv = {"export-controller": ["export-controller", SC, data, "--out", locked / "machine.json"],
            "import-robot": ["import-robot", robot, "--out", locked / "r.skel.json"],
            "export-linuxcnc-kins": ["export-linuxcnc-kins", SC, "--out", locked / "kins"],
            "report": ["report", SC, "--out", locked / "report"]}[command]
    if os.geteuid() == 0:
        if subprocess.run(["chattr", "+i", str(locked)], capture_output=True).returncode != 0:
            pytest.skip("chattr +i is not available on this file system")
    else:
        locked.chmod(0o555)
    try:
        code, _, err = run_cli(argv)
    finally:
        if os.geteuid() == 0:
            subprocess.run(["chattr", "-i", str(locked)], check=True)
        locked.chmod(0o755)
    assert code == 2 and "locked: the directory cannot be written" in err and len(err.strip().splitlines()) == 1
    assert list(locked.iterdir()) == []


def test_a_device_is_not_an_output(tmp_path):
    """``--json /dev/null`` would have been replaced by a regular file (as root): refused."""
    code, _, err = run_cli(["analyze", SC, "--json", "/dev/null", "--quiet"])
    assert code == 2 and "/dev/null: is not a regular file" in err
