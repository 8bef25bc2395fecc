"""Command-line conventions, run as a user runs them (the real console script, a new process each).

``--quiet`` prints nothing at all on success, for every command; no third-party noise (VTK's
X-display line, library warnings) reaches the terminal; ``--version`` answers.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import TEMPLATES

HYPERSTAT = str(Path(sys.executable).parent / "hyperstat")
SC = str(TEMPLATES / "slider_crank.py")
TX = str(TEMPLATES / "tripteor_x7.py")
HEX = str(TEMPLATES / "hexapod.py")
ROBOT = str(TEMPLATES.parent / "docs" / "examples" / "fanuc_like.dh.yaml")


def _run(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    return subprocess.run([HYPERSTAT, *argv], cwd=cwd, env=env, capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    """A small simulated slider-crank campaign (identification + validation files)."""
    d = tmp_path_factory.mktemp("campaign")
    run = _run("simulate", SC, "--poses", "24", "--validation", "10", "--out", "d.csv", "--quiet", cwd=d)
    assert run.returncode == 0 and run.stdout == run.stderr == "", run
    assert (d / "d.csv").is_file() and (d / "d.validation.csv").is_file()
    # a serial robot from its DH table and joint map, for the robot import and export commands
    run = _run("import-robot", ROBOT, "--out", "r.skel.json", "--quiet", cwd=d)
    assert run.returncode == 0 and run.stdout == run.stderr == "", run
    run = _run("simulate", "r.skel.json", "--poses", "40", "--validation", "0", "--out", "r.csv", "--quiet", cwd=d)
    assert run.returncode == 0 and run.stdout == run.stderr == "", run
    run = _run("export-controller", SC, "d.csv", "--out", "m.json", "--quiet", cwd=d)
    assert run.returncode == 0 and (d / "m.json").is_file(), run
    return d


COMMANDS = {
    "analyze": (["analyze", SC, "--verify", "--json", "a.json"], "a.json"),
    "check-hypotheses": (["check-hypotheses", TX, str(TEMPLATES / "tripteor_x7.hypotheses.yaml"), "--json", "h.json"],
                         "h.json"),
    "compare": (["compare", TX, str(TEMPLATES / "tripteor_x7.paper.yaml"), "--markdown", "c.md"], "c.md"),
    "identify": (["identify", SC, "{d}/d.csv", "--validation", "{d}/d.validation.csv", "--json", "i.json"], "i.json"),
    "diagnose": (["diagnose", SC, "{d}/d.csv", "--validation", "{d}/d.validation.csv", "--json", "g.json"], "g.json"),
    "export-controller": (["export-controller", SC, "{d}/d.csv", "--out", "m.json"], "m.json"),
    "export-linuxcnc": (["export-linuxcnc", HEX, "--hal", "k.hal"], "k.hal"),
    "check-controller": (["check-controller", "{d}/m.json", "--json", "cc.json"], "cc.json"),
    "export-linuxcnc-kins": (["export-linuxcnc-kins", TX, "--out", "kins"], "kins/machine.ini"),
    "check-move": (["check-move", TX, "--from", "X596.783 Y18.262 Z-1143.049 B-22.58 C161.514", "--to",
                    "X576.783 Y-1.738 Z-1138.049 B-21.58 C156.514", "--json", "move.json"], "move.json"),
    "accuracy": (["accuracy", SC, "--workspace-configurations", "60", "--json", "acc.json"], "acc.json"),
    "montecarlo": (["montecarlo", SC, "--workspace-configurations", "20", "--samples", "200", "--json", "mc.json"],
                   "mc.json"),
    "validate-diagnosis": (["validate-diagnosis", SC, "--seeds", "1", "--cases", "none", "--json", "v.json"],
                           "v.json"),
    "build": (["build", SC, "--model", "sc.skel.json"], "sc.skel.json"),
    "view": (["view", SC, "--png", "v.png"], "v.png"),
    "report": (["report", SC, "--out", "rep"], "rep/report.html"),
    "parameters": (["parameters", SC, "--json", "p.json"], "p.json"),
    "sweep": (["sweep", SC, "--grid", "L1=40:60:2", "--out", "s.csv"], "s.csv"),
    "import-robot": (["import-robot", ROBOT, "--out", "robot.skel.json"], "robot.skel.json"),
    "export-urdf": (["export-urdf", "{d}/r.skel.json", "{d}/r.csv", "--out", "r.urdf"], "r.urdf"),
    "export-dh": (["export-dh", "{d}/r.skel.json", "{d}/r.csv", "--out", "r.dh.yaml"], "r.dh.yaml"),
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_quiet_prints_nothing_on_success(command, campaign, tmp_path):
    argv, output = COMMANDS[command]
    argv = [a.replace("{d}", str(campaign)) for a in argv]
    run = _run(*argv, "--quiet", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert run.stdout == "" and run.stderr == "", (run.stdout, run.stderr)
    assert (tmp_path / output).is_file()  # it did its work


def test_every_command_is_covered():
    from hyperstat.cad_plugin.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert set(sub.choices) - {"simulate"} == set(COMMANDS)  # simulate runs in the fixture


@pytest.mark.parametrize("command", ["view", "report"])
def test_no_vtk_line_reaches_the_terminal(command, tmp_path):
    argv, _ = COMMANDS[command]
    run = _run(*argv, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "vtk" not in run.stderr.lower() and "X server" not in run.stderr and "\x1b[33m" not in run.stderr, run.stderr


def test_version_matches_the_package_metadata(tmp_path):
    from importlib.metadata import version

    run = _run("--version", cwd=tmp_path)
    assert run.returncode == 0 and run.stdout.strip() == f"hyperstat {version('hyperstat')}"


def test_a_terminal_gets_a_progress_bar_and_quiet_silences_it(tmp_path):
    """stderr on a pseudo-terminal, as a person at a terminal has it."""
    import pty
    import select

    def stderr_on_a_terminal(*argv: str) -> tuple[int, str]:
        master, slave = pty.openpty()
        proc = subprocess.Popen([HYPERSTAT, *argv], cwd=tmp_path, stdout=subprocess.PIPE, stderr=slave)
        os.close(slave)
        chunks = []
        while True:
            ready, _, _ = select.select([master], [], [], 1.0)
            if ready:
                try:
                    data = os.read(master, 4096)
                except OSError:  # the child closed its side
                    break
                if not data:
                    break
                chunks.append(data)
            elif proc.poll() is not None:
                break
        proc.wait(timeout=300)
        os.close(master)
        return proc.returncode, b"".join(chunks).decode(errors="replace")

    code, err = stderr_on_a_terminal("view", SC, "--png", "v.png")
    assert code == 0 and "view: " in err and "rendering" in err, err
    code, err = stderr_on_a_terminal("view", SC, "--png", "w.png", "--quiet")
    assert code == 0 and err == "", err


def test_quiet_report_of_a_mechanism_whose_sampling_warns_prints_nothing(tmp_path):
    """The corpus' PRS-3 leaves a few workspace draws out of its accuracy sample (a warning the report's stages
    silence): the accuracy coefficients computed by a forked child silence it too."""
    run = _run("report", str(TEMPLATES / "corpus" / "prs_3.py"), "--json-only", "--out", "rep", "--quiet",
               cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert run.stdout == "" and run.stderr == "", (run.stdout, run.stderr)
    assert (tmp_path / "rep" / "report.json").is_file()
