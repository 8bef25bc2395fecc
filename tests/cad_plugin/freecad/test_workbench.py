"""The FreeCAD workbench in the real FreeCAD 0.20 (Debian ``freecad-python3``), headless (``freecadcmd``).

Units: lengths in mm, angles in rad.

FreeCAD runs as subprocesses with ``HOME`` in a temporary folder, the workbench
installed there by the real installer.  All FreeCAD runs start together (a
module fixture) so that they share the two cores; each test waits for its own:

* one ``freecadcmd`` scenario per template (``fc_scenario.py``): insert, analyse,
  save, close, reopen; the classes, counts, colours and callouts compared here with the
  solver run in-process on the template (a second path: no STEP, no model file, no
  FreeCAD) and with the solver's own JSON;
* ``freecadcmd -t TestHyperstatWorkbench``: the workbench's registered unit tests.

The GUI, clicked for real under Xvfb, is tested in ``test_gui_clicks.py``.

``make test`` sets ``HYPERSTAT_REQUIRE_FREECAD=1`` after installing FreeCAD and Xvfb,
so that a missing FreeCAD fails these tests there instead of skipping them.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from ...conftest import ROOT, TEMPLATES

WORKBENCH = ROOT / "cad_plugin" / "freecad"
SCENARIO = Path(__file__).resolve().parent / "fc_scenario.py"
SHIPPED = ["slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod", "five_bar"]
#: corpus members inserted and analysed by name too (issue 38): a spatial loop and a parallel robot
CORPUS = ["bennett", "tsai_3upu"]
#: a Bennett linkage and a planar 3-RRR written from docs/authoring.md alone by an author who read no source (issue 38)
GUIDE = {name: ROOT / "docs" / "validation" / "guide_authoring" / f"{name}.py" for name in ("bennett_user", "rrr3_user")}
NAMES = SHIPPED + CORPUS + list(GUIDE)


def template_file(name: str) -> Path:
    """A shipped template's, a corpus template's or a guide-written template's file."""
    if name in GUIDE:
        return GUIDE[name]
    return TEMPLATES / f"{name}.py" if name in SHIPPED else TEMPLATES / "corpus" / f"{name}.py"
REQUIRED = os.environ.get("HYPERSTAT_REQUIRE_FREECAD") == "1"
TIMEOUT_S = 900

sys.path.insert(0, str(WORKBENCH))  # the workbench's pure modules (no FreeCAD import) and installer
from hyperstat_freecad.classes import CLASS_RGB as WB_RGB  # noqa: E402
from hyperstat_freecad.classes import callout_text as wb_callout_text  # noqa: E402
from hyperstat_freecad.classes import element_classes as wb_element_classes  # noqa: E402

import hyperstat_palette  # noqa: E402,F401 - the workbench's copy of the classes, as FreeCAD imports it

sys.path.pop(0)


def _require(*tools: str) -> dict[str, str]:
    found = {t: shutil.which(t) for t in tools}
    missing = [t for t, p in found.items() if p is None]
    if missing:
        message = (f"{', '.join(missing)} not found: 'make test' installs them (Debian freecad-python3, xvfb, xauth)")
        if REQUIRED:
            pytest.fail(message)
        pytest.skip(message)
    return found


def _cli() -> str:
    cli = Path(sys.executable).parent / "hyperstat"
    assert cli.is_file(), f"no hyperstat command next to {sys.executable}"
    return str(cli)


def _install(home: Path, *extra: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "HOME": str(home)}
    return subprocess.run([sys.executable, str(WORKBENCH / "install.py"), "--cli", _cli(), *extra],
                          capture_output=True, text=True, env=env, timeout=300)


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> dict:
    """A throwaway HOME with the workbench installed by the real installer."""
    _require("freecadcmd")
    home = tmp_path_factory.mktemp("fc_home")
    proc = _install(home)
    assert proc.returncode == 0, proc.stderr
    spec = importlib.util.spec_from_file_location("hyperstat_freecad_install", WORKBENCH / "install.py")
    installer = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(installer)
    user_dir = installer.user_app_data_dir("freecadcmd", env={**os.environ, "HOME": str(home)})
    return {"home": home, "user_dir": user_dir, "dest": user_dir / "Mod" / "Hyperstat", "stdout": proc.stdout}


@dataclass
class Job:
    """A FreeCAD subprocess started by the fixture."""

    name: str
    proc: subprocess.Popen
    out: Path
    log: Path

    def wait(self) -> tuple[int, str]:
        try:
            code = self.proc.wait(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            pytest.fail(f"{self.name}: FreeCAD did not finish within {TIMEOUT_S} s")
        return code, self.log.read_text(encoding="utf-8", errors="replace")


def _start(name: str, command: list[str], env: dict, out: Path) -> Job:
    out.mkdir(parents=True, exist_ok=True)
    log = out / "log.txt"
    with open(log, "w", encoding="utf-8") as fh:
        # a session of its own, so that xvfb-run's Xvfb and FreeCAD's hyperstat children can be stopped with it
        proc = subprocess.Popen(command, stdout=fh, stderr=subprocess.STDOUT, env=env, cwd=out, start_new_session=True)
    return Job(name, proc, out, log)


@pytest.fixture(scope="module")
def jobs(installed, tmp_path_factory):
    """Start every FreeCAD run at once (scenarios, registered unit tests); tests wait for theirs."""
    tools = _require("freecadcmd")
    root = tmp_path_factory.mktemp("fc_runs")
    env = {**os.environ, "HOME": str(installed["home"])}
    env.pop("HYPERSTAT_CLI", None)  # the workbench must find the command line through its install record
    started: dict[str, Job] = {}
    for name in NAMES:
        started[name] = _start(name, [tools["freecadcmd"], str(SCENARIO)],
                               {**env, "HYPERSTAT_SCENARIO_TEMPLATE": str(GUIDE.get(name, name)),
                                "HYPERSTAT_SCENARIO_OUT": str(root / name)},
                               root / name)
    started["unit"] = _start("unit", [tools["freecadcmd"], "-t", "TestHyperstatWorkbench"], env, root / "unit")
    yield started
    for job in started.values():
        try:
            os.killpg(job.proc.pid, signal.SIGKILL)  # whatever is left of that run (Xvfb after xvfb-run...)
        except ProcessLookupError:
            pass
        job.proc.wait()


@pytest.fixture(scope="module")
def expected(jobs, request) -> dict:
    """Per template, from the solver in this process (template -> mechanism -> analysis), not through FreeCAD.

    Computed while the FreeCAD runs of ``jobs`` are under way; reuses the session's analyses.
    """
    import warnings

    from hyperstat.cad_plugin.assembly import sidecar
    from hyperstat.cad_plugin.templates import build_template
    from hyperstat.solver.analysis.stationarity import analyze

    from hyperstat.solver.cli import jsonable
    from hyperstat.solver.tolerances.classification import classify

    shared = {"slider_crank": "slider_crank_analysis", "tripteor_x7": "tripteor_analysis", "scara": "scara_analysis"}
    out = {}
    for name in NAMES:
        skeleton = build_template(template_file(name))
        if name in shared:
            result = request.getfixturevalue(shared[name])
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                result = analyze(skeleton.mechanism(), n_configurations=24, seed=0)
        nodes = sidecar(skeleton)["nodes"]
        poses = {node: skeleton.poses[info.get("element") or info.get("frame")] for node, info in nodes.items()}
        analysis = jsonable({**result.to_dict(), "tolerances": classify(skeleton.mechanism(), result).to_dict()})
        out[name] = {"analysis": analysis, "poses": poses, "marker_size": skeleton.marker_size}
    return out


def _template_parameters(name: str) -> list[dict]:
    from hyperstat.cad_plugin import describe, load_template

    return describe(load_template(template_file(name)).Parameters)


def _check_sphere_places(spheres: dict, want: dict) -> None:
    """On its joint, or, where joints coincide, on a ring around the shared point with no two spheres touching."""
    radius = 0.35 * want["marker_size"]
    poses = {el: want["poses"][f"m_{el}"][:3, 3] for el in spheres}
    for element, sphere in spheres.items():
        shared = [e for e in spheres if e != element and np.allclose(poses[e], poses[element], atol=1e-6)]
        offset = np.linalg.norm(np.subtract(sphere["center"], poses[element]))
        if not shared:
            assert offset == pytest.approx(0.0, abs=1e-6), element
            continue
        n = len(shared) + 1
        assert offset == pytest.approx(1.15 * radius / np.sin(np.pi / n), rel=1e-9), element
        for other in shared:
            gap = np.linalg.norm(np.subtract(sphere["center"], spheres[other]["center"]))
            assert gap >= 2.0 * radius * (1 + 1e-9), (element, other, gap)


def _verdicts(analysis: dict) -> dict[str, tuple]:
    return {p["name"]: (p["element"], p["verdict"], p.get("influential")) for p in analysis["parameters"]}


def _classes(tolerances: dict) -> dict[str, str]:
    return {n: e["class"] for n, e in tolerances["parameters"].items()}


# --------------------------------------------------------------------------- install
def test_the_workbench_reads_the_one_definition_of_the_classes():
    """FreeCAD's Python imports the palette from the installed workbench, the project from this checkout: one file."""
    import hyperstat_palette as wb

    from hyperstat.cad_plugin import palette

    assert Path(wb.DEFINITION).resolve() == Path(palette.DEFINITION).resolve()
    assert WB_RGB == palette.CLASS_RGB and set(WB_RGB) == set(palette.CLASS_ORDER)


def test_install_puts_the_workbench_where_freecad_looks_and_records_the_cli(installed):
    dest = installed["dest"]
    # FreeCAD 0.20 on Debian: the user data folder under HOME
    assert installed["user_dir"] == installed["home"] / ".local" / "share" / "FreeCAD"
    for item in ("Init.py", "InitGui.py", "package.xml", "TestHyperstatWorkbench.py", "Resources/icons/analyze.svg",
                 "Resources/ui/preferences.ui", "hyperstat_freecad/operations.py"):
        assert (dest / item).is_file(), item
    assert (dest / "hyperstat_palette.py").read_bytes() == (WORKBENCH / "hyperstat_palette.py").read_bytes()
    assert (dest / "classes.json").read_bytes() == (WORKBENCH / "classes.json").read_bytes()
    assert not (dest / "install.py").exists() and not (dest / "tools").exists()
    record = json.loads((dest / "hyperstat_freecad" / "install.json").read_text())
    assert record["cli"] == str(Path(_cli()).resolve())
    assert Path(record["templates"]) == TEMPLATES.resolve()
    assert str(dest) in installed["stdout"]


def test_install_again_replaces_and_a_bad_cli_is_one_sentence(installed):
    dest = installed["dest"]
    marker = dest / "stale.txt"
    marker.write_text("from an older install")
    proc = _install(installed["home"])
    assert proc.returncode == 0, proc.stderr
    assert not marker.exists()
    assert sorted(p.name for p in dest.parent.iterdir()) == ["Hyperstat"]  # no staging left behind
    before = (dest / "hyperstat_freecad" / "install.json").read_text()
    bad = _install(installed["home"], "--cli", "/nonexistent/hyperstat")
    assert bad.returncode == 2
    assert bad.stderr.count("\n") == 1 and "/nonexistent/hyperstat" in bad.stderr
    assert (dest / "hyperstat_freecad" / "install.json").read_text() == before


# --------------------------------------------------------------------------- headless
def _scenario(jobs, name: str) -> dict:
    code, log = jobs[name].wait()
    result = json.loads((jobs[name].out / "result.json").read_text())
    assert code == 0, result.get("error") or log[-3000:]
    return result


@pytest.mark.parametrize("name", NAMES)
def test_template_in_freecadcmd_classes_colours_callouts_and_reopen(jobs, expected, name):
    result = _scenario(jobs, name)
    before, after = result["before"], result["after"]
    want = expected[name]
    solver_json = json.loads((jobs[name].out / "solver_analysis.json").read_text())

    # stationarity and tolerance classes: stored in the document == the solver's JSON == the solver run here
    assert _verdicts(before["analysis"]) == _verdicts(solver_json) == _verdicts(want["analysis"])
    assert before["parameter_classes"] == _classes(want["analysis"]["tolerances"]) == _classes(before["tolerances"])
    here = want["analysis"]["tolerances"]
    assert before["tolerances"]["counts"] == here["counts"]  # the report's counts, computed here without FreeCAD
    assert before["tolerance_counts"] == {k: str(v) for k, v in here["counts"].items()}
    assert [(t["id"], t["statement"], t["class"]) for t in before["tolerances"]["items"]] == \
        [(t["id"], t["statement"], t["class"]) for t in here["items"]]
    assert all(t["value"] is not None for t in before["tolerances"]["items"] if t["class"] != "non-influent")
    assert before["mobility"] == want["analysis"]["mobility"]
    assert before["overconstraint"] == want["analysis"]["overconstraint"]
    assert before["status"] == "analysed" and not before["needs_rebuild"]

    # markers: one per sidecar node, placed at the template's frame poses (mm)
    assert set(before["markers"]) == set(want["poses"])
    for node, matrix in before["markers"].items():
        np.testing.assert_allclose(np.reshape(matrix, (4, 4)), want["poses"][node], atol=1e-6, err_msg=node)

    # class spheres: one per element with defects, on its marker, in the colour of the report and the pictures
    classes, ids = wb_element_classes(want["analysis"])
    assert set(before["spheres"]) == set(classes)
    for element, sphere in before["spheres"].items():
        assert sphere["class"] == classes[element]
        np.testing.assert_allclose(sphere["color"], WB_RGB[classes[element]], atol=1e-6)
        assert sphere["marker"] == f"m_{element}"
        assert sphere["radius"] == pytest.approx(0.35 * want["marker_size"], rel=1e-3)
    _check_sphere_places(before["spheres"], want)
    # callouts: every marker with its tolerance ids, once
    lines = sorted(line for text in before["callouts"].values() for line in text)
    assert lines == sorted(wb_callout_text(e, ids.get(e, [])) for e in classes)

    # parameters are bound to the spreadsheet, and equal the template's defaults (mm, rad)
    assert before["parameters"] == pytest.approx({p["name"]: p["default"] for p in _template_parameters(name)},
                                                 rel=1e-12, abs=1e-12)
    assert set(before["expressions"]) == set(before["parameters"])
    assert all(expr.startswith(f"{before['spreadsheet']}.") for expr in before["expressions"].values())

    # save, close, reopen: the proxy is restored and everything else is as it was
    assert result["skeletons_after_reopen"] == ["Skeleton"]
    assert after["proxy"] == "SkeletonFeature" and after["proxy_module"] == "hyperstat_freecad.feature"
    assert after["proxy_state"] == before["proxy_state"] == {"Type": "HyperstatSkeleton", "version": 1}
    for key in ("type_id", "status", "mechanism", "summary", "parameters", "expressions", "analysis", "tolerances",
                "tolerance_counts", "parameter_classes", "callouts", "mobility", "overconstraint", "marker_size",
                "needs_rebuild"):
        assert after[key] == before[key], key
    assert set(after["markers"]) == set(before["markers"])
    for node, matrix in after["markers"].items():
        np.testing.assert_allclose(matrix, before["markers"][node], atol=1e-9)
    assert set(after["spheres"]) == set(before["spheres"])
    for element, sphere in after["spheres"].items():
        assert (sphere["class"], sphere["marker"]) == (before["spheres"][element]["class"], f"m_{element}")
        # FreeCAD saves a colour as 8 bits per channel
        np.testing.assert_allclose(sphere["color"], WB_RGB[classes[element]], atol=0.5 / 255)
        np.testing.assert_allclose(sphere["center"], before["spheres"][element]["center"], atol=1e-9)


def test_tripteor_headless_report_is_written_or_its_absence_told(jobs):
    result = _scenario(jobs, "tripteor_x7")
    if "report" in result:
        assert (Path(result["report"]) / "report.html").is_file()
    else:
        assert "'report'" in result["report_missing"] and "make freecad-install" in result["report_missing"]


def test_registered_unit_tests_pass_in_freecadcmd(jobs):
    code, log = jobs["unit"].wait()
    assert code == 0, log[-4000:]
    assert "\nOK" in log and "Ran 10 tests" in log, log[-2000:]
