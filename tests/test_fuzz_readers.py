"""Property-based tests of every reader through the command line (issue 31): any corruption of a good file is
either read (and the command then runs to its end) or refused with exit code 2 and one sentence; never a
traceback, never a partial output.

Units: lengths in mm, angles in rad (the files state theirs).

Each suite starts from a good input the command accepts, corrupts it (hypothesis draws the
corruption: numbers replaced by nasty values, lines deleted, doubled or swapped, text cut or
inserted, JSON / YAML values replaced or keys removed), runs the command in-process and checks:
exit code 0, or exit code 2 with exactly one line ``hyperstat: error: ... .`` on stderr, no
traceback, and none of the command's outputs (and no hidden temporary file) left in its folder.
An imported robot that is accepted is analysed as well (a table with ``a = 1e308`` used to import
and then fail in LAPACK).  Example counts are in :data:`COUNTS`; the seed is fixed (derandomized),
so the same examples run every time.
"""

from __future__ import annotations

import copy
import json
import os
import re
import shutil
import tempfile
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.conftest import TEMPLATES, run_cli
from tests.solver.calibration.fanuc_like import DH_YAML, Campaign
from tests.solver.kinematics.test_robot_import_checks import DH, DH_CSV, URDF

SC = TEMPLATES / "slider_crank.py"

#: examples per suite (modest: the whole file runs in about a minute on the shared machine)
COUNTS = {"model file": 40, "template parameters": 40, "DH YAML": 50, "DH CSV": 50, "URDF": 50,
          "measurement file": 30, "hypothesis file": 40, "controller file": 30}


def _settings(suite: str):
    """The suite's settings; ``HYPERSTAT_FUZZ_FACTOR=k`` runs k times the examples with a random seed (exploration)."""
    factor = int(os.environ.get("HYPERSTAT_FUZZ_FACTOR", "1") or 1)
    return settings(max_examples=COUNTS[suite] * factor, deadline=None, derandomize=factor == 1, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                           HealthCheck.data_too_large])


NASTY = st.sampled_from(["nan", "NaN", "inf", "-inf", "1e308", "-1e308", "1e-320", "0", "-0", "1e6", "-1e9",
                         "180", "-90", "720", "", " ", "x", "1,2", "0x10", "1_0", "true", "null", "[]", "{}",
                         "'", '"', "#", "\\", "1e", "--1", "\u00b2", "9" * 400]) | \
    st.floats(allow_nan=True, allow_infinity=True).map(repr) | st.integers(-10**12, 10**12).map(str)
NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def corrupt(text: str, data) -> str:
    """One to three random edits of ``text``: a number replaced, a line deleted / doubled / swapped, a cut, an insert."""
    for _ in range(data.draw(st.integers(1, 3), label="edits")):
        lines = text.splitlines(keepends=True) or [""]
        op = data.draw(st.sampled_from(["number", "number", "nudge", "delete line", "double line", "swap lines", "cut",
                                        "insert"]), label="op")
        if op in ("number", "nudge"):
            spans = [m.span() for m in NUMBER.finditer(text)]
            if spans:
                a, b = data.draw(st.sampled_from(spans), label="number at")
                if op == "nudge":  # a plausible value: the same number a little off
                    value = repr(float(text[a:b]) * data.draw(st.floats(0.5, 1.5), label="factor"))
                else:
                    value = data.draw(NASTY, label="value")
                text = text[:a] + value + text[b:]
            continue
        i = data.draw(st.integers(0, len(lines) - 1), label="line")
        if op == "delete line":
            del lines[i]
        elif op == "double line":
            lines.insert(i, lines[i])
        elif op == "swap lines":
            j = data.draw(st.integers(0, len(lines) - 1), label="other line")
            lines[i], lines[j] = lines[j], lines[i]
        elif op == "cut":
            a = data.draw(st.integers(0, len(text)), label="cut at")
            text = text[:a] + text[a + data.draw(st.integers(1, 40), label="cut length"):]
            continue
        else:
            a = data.draw(st.integers(0, len(text)), label="insert at")
            text = text[:a] + data.draw(st.text(max_size=12), label="inserted") + text[a:]
            continue
        text = "".join(lines)
    return text


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6) | st.floats(allow_nan=False, allow_infinity=False)
    | st.sampled_from([1e308, -1e308, 1e-320, 180.0, -90.0]) | st.text(max_size=6),
    lambda children: st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=5), children, max_size=3),
    max_leaves=8)


def mutate(doc, data):
    """One to three structural edits of a JSON / YAML document: a value replaced or a key removed."""
    doc = copy.deepcopy(doc)

    def paths(d, prefix=()):
        yield prefix
        items = d.items() if isinstance(d, dict) else enumerate(d) if isinstance(d, list) else ()
        for k, v in items:
            yield from paths(v, prefix + (k,))

    found = [p for p in paths(doc) if p]
    for _ in range(data.draw(st.integers(1, 3), label="mutations")):
        path = data.draw(st.sampled_from(found), label="path")
        parent = doc
        try:
            for key in path[:-1]:
                parent = parent[key]
            if isinstance(parent, dict) and data.draw(st.booleans(), label="remove"):
                parent.pop(path[-1], None)
            else:
                parent[path[-1]] = data.draw(JSON_VALUES, label="new value")
        except (KeyError, IndexError, TypeError):
            pass
    return doc


#: suite -> [accepted, refused] runs of the reader's command (printed at the end of the module)
TALLY: dict = {}
#: suites whose uncorrupted input was read (test_the_suites_start_from_good_inputs)
GOOD_READ: set = set()


@pytest.fixture(scope="module", autouse=True)
def _tally():
    """Each suite must see both outcomes (else it tests one path only); the counts are printed (pytest -s)."""
    yield
    import sys

    for suite, (accepted, refused) in sorted(TALLY.items()):
        sys.stderr.write(f"\nfuzz {suite}: {accepted} read, {refused} refused\n")
        # a corrupted file that still reads is rare for the strict readers (a controller file's hash and
        # version-fixed content; a model file's schema): their accepted path is then the uncorrupted file
        # of test_the_suites_start_from_good_inputs
        assert refused and (accepted or suite in GOOD_READ), (suite, accepted, refused)


class Workspace:
    """A fresh folder per example; its files are the command's outputs (none may be left on a refusal)."""

    def __init__(self, base: Path, suite: str = "") -> None:
        self.dir = Path(tempfile.mkdtemp(dir=base))
        self.suite = suite

    def __enter__(self) -> "Workspace":
        return self

    def __exit__(self, *exc) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)

    def run(self, argv: list, inputs: tuple = ()) -> bool:
        """Run; True when accepted (exit 0), False when refused properly; anything else fails the test."""
        before = {p.name for p in self.dir.iterdir()}
        code, out, err = run_cli(argv)
        if self.suite:
            TALLY.setdefault(self.suite, [0, 0])[code != 0] += 1
            self.suite = ""  # only the reader's own command counts (not the analysis after an import)
        if code == 0:
            return True
        lines = err.strip().splitlines()
        assert code == 2, (code, err[-2000:])
        assert len(lines) == 1 and lines[0].startswith("hyperstat: error: ") and lines[0].endswith("."), err
        assert "Traceback" not in out + err
        left = {p.name for p in self.dir.iterdir()} - before - {Path(i).name for i in inputs}
        assert not left, f"refused, yet wrote {sorted(left)}: {err}"
        return False


def _yaml_or_text(text: str, data) -> str:
    """A YAML document mutated as data (a value replaced, a key removed) or corrupted as text, half of the time each."""
    if data.draw(st.booleans(), label="structural"):
        return yaml.safe_dump(mutate(yaml.safe_load(text), data))
    return corrupt(text, data)


def _write(ws: Workspace, name: str, text: str) -> Path:
    path = ws.dir / name
    path.write_bytes(text.encode("utf-8", errors="replace"))  # drawn text may hold lone surrogates
    return path


# ------------------------------------------------------------------------------------------------ model file
@pytest.fixture(scope="module")
def model_doc():
    from hyperstat.cad_plugin.templates import build_template
    from hyperstat.solver.kinematics.modelfile import mechanism_to_dict

    return json.loads(json.dumps(mechanism_to_dict(build_template(SC).mechanism())))


@_settings("model file")
@given(data=st.data())
def test_model_file(model_doc, tmp_path, data):
    with Workspace(tmp_path, "model file") as ws:
        if data.draw(st.booleans(), label="structural"):
            text = json.dumps(mutate(model_doc, data))
        else:
            text = corrupt(json.dumps(model_doc, indent=1), data)
        path = _write(ws, "m.json", text)
        ws.run(["analyze", path, "--configurations", "6", "--json", ws.dir / "out.json", "--quiet"], (path,))


# ------------------------------------------------------------------------------------------- template parameters
PARAMETERS = ["L1", "L2", "L3", "L4", "home_angle", "section", "colour", "l1", ""]
VALUES = NASTY | st.builds(lambda v, u: f"{v}{u}", st.floats(-1e4, 1e4).map(lambda v: f"{v:g}"),
                           st.sampled_from(["", "mm", "cm", "m", "in", "deg", "rad", " mm", "MM", "um"])) | \
    st.floats(5.0, 60.0).map(lambda v: f"{v:.3g}mm")  # plausible lengths: the model is then built and analysed


@_settings("template parameters")
@given(overrides=st.lists(st.tuples(st.sampled_from(PARAMETERS), VALUES), min_size=1, max_size=3))
def test_template_parameters(tmp_path, overrides):
    with Workspace(tmp_path, "template parameters") as ws:
        argv = ["build", SC, "--model", ws.dir / "out.json", "--quiet"]
        for name, value in overrides:
            argv += ["-p", f"{name}={value}"]
        if ws.run(argv):
            ws.run(["analyze", ws.dir / "out.json", "--configurations", "6", "--json", ws.dir / "a.json", "--quiet"],
                   ("out.json",))


# ---------------------------------------------------------------------------------------- robot files (import)
def _import_then_analyze(ws: Workspace, path: Path) -> None:
    out = ws.dir / "out.skel.json"
    if ws.run(["import-robot", path, "--out", out, "--quiet"], (path,)):
        ws.run(["analyze", out, "--configurations", "6", "--json", ws.dir / "a.json", "--quiet"], (path, out))


@_settings("DH YAML")
@given(data=st.data())
def test_dh_yaml(tmp_path, data):
    with Workspace(tmp_path, "DH YAML") as ws:
        _import_then_analyze(ws, _write(ws, "robot.yaml", _yaml_or_text(DH, data)))


@_settings("DH CSV")
@given(data=st.data())
def test_dh_csv(tmp_path, data):
    with Workspace(tmp_path, "DH CSV") as ws:
        _import_then_analyze(ws, _write(ws, "robot.csv", corrupt(DH_CSV, data)))


@_settings("URDF")
@given(data=st.data())
def test_urdf(tmp_path, data):
    with Workspace(tmp_path, "URDF") as ws:
        _import_then_analyze(ws, _write(ws, "robot.urdf", corrupt(URDF, data)))


# ------------------------------------------------------------- measurement file: three reflectors and 6-D rows
@pytest.fixture(scope="module")
def robot_campaign(tmp_path_factory):
    """The FANUC-like robot as a model file, and 12 poses of three SMRs with positions (m) and quaternions."""
    from hyperstat.solver.calibration.measurements import read_measurements
    from hyperstat.solver.kinematics.modelfile import save_model
    from hyperstat.solver.kinematics.robot_import import import_robot

    tmp = tmp_path_factory.mktemp("fuzz_meas")
    (tmp / "r.dh.yaml").write_text(DH_YAML)
    mech = import_robot(tmp / "r.dh.yaml")
    model = save_model(mech, tmp / "r.skel.json")
    c = Campaign(7)
    smrs = ("SMR1", "SMR2", "SMR3")
    cols = ["pose"] + [f"J{i}[deg]" for i in range(1, 7)]
    cols += [f"{a}_{s}[m]" for s in smrs for a in "xyz"] + [f"quat_{a}_{s}" for s in smrs for a in "wxyz"]
    lines = ["# hyperstat measurements, version 1", "# mechanism: fanuc_like", "# noise: 0.01 mm + 0.005 mm/m",
             "# orientation noise: 0.05 mrad", "# target SMR1: 118 -8 68", ",".join(cols)]
    for i, q in enumerate(c.poses(12)):
        pos, quat = zip(*(c.measure_pose(q, s, 5e-5) for s in smrs))
        lines.append(",".join([f"P{i + 1}"] + [repr(float(v)) for v in c.controller(q)]
                              + [f"{v / 1000:.9f}" for p in pos for v in p] + [f"{v:.12f}" for u in quat for v in u]))
    text = "\n".join(lines) + "\n"
    (tmp / "good.csv").write_text(text)
    data = read_measurements(tmp / "good.csv", mech)
    assert data.n_targets == 3 and data.rotation is not None  # the suite starts from a good file
    return model, text


@_settings("measurement file")
@given(data=st.data())
def test_measurement_file(robot_campaign, tmp_path, data):
    model, text = robot_campaign
    with Workspace(tmp_path, "measurement file") as ws:
        path = _write(ws, "d.csv", corrupt(text, data))
        ws.run(["identify", model, path, "--configurations", "6", "--select-size", "none", "--json",
                ws.dir / "out.json", "--residuals", ws.dir / "res.csv", "--quiet"], (path,))


# --------------------------------------------------------------------------------------------- hypothesis file
HYPOTHESES = ("format: hyperstat-hypotheses\nversion: 1\naxes:\n  a2: {element: '2'}\n  a3: {element: '3'}\n"
              "  a23: {through: [p2, p3]}\npoints:\n  p2: {element: '2'}\n  p3: {element: '3'}\nhypotheses:\n"
              "  - {id: h1, parallel: [a2, a3]}\n  - {id: h2, point_on_axis: [p3, a3]}\n  - {id: h3, perpendicular: [a23, a2]}\n")


@_settings("hypothesis file")
@given(data=st.data())
def test_hypothesis_file(tmp_path, data):
    with Workspace(tmp_path, "hypothesis file") as ws:
        path = _write(ws, "h.yaml", _yaml_or_text(HYPOTHESES, data))
        ws.run(["check-hypotheses", SC, path, "--configurations", "6", "--json", ws.dir / "out.json", "--quiet"],
               (path,))


# --------------------------------------------------------------------------------------------- controller file
@pytest.fixture(scope="module")
def controller_doc(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fuzz_ctl")
    data = tmp / "d.csv"
    assert run_cli(["simulate", SC, "--poses", "30", "--validation", "0", "--out", data, "--quiet"])[0] == 0
    assert run_cli(["export-controller", SC, data, "--out", tmp / "c.json", "--quiet"])[0] == 0
    return json.loads((tmp / "c.json").read_text())


@_settings("controller file")
@given(data=st.data())
def test_controller_file(controller_doc, tmp_path, data):
    """Corruptions with the hash recomputed half of the time (else the hash alone would refuse them all)."""
    from hyperstat.solver.export.controller import content_hash

    with Workspace(tmp_path, "controller file") as ws:
        if data.draw(st.booleans(), label="structural"):
            text = json.dumps(mutate(controller_doc, data))
        else:
            text = corrupt(json.dumps(controller_doc, indent=1), data)
        if data.draw(st.booleans(), label="rehash"):  # what a forger does: the content checks must catch it
            try:
                doc = json.loads(text)
                doc["sha256"] = content_hash(doc)
                text = json.dumps(doc)
            except (TypeError, ValueError, KeyError):
                pass  # not a JSON object: left as it is
        path = _write(ws, "c.json", text)
        ws.run(["check-controller", path, "--json", ws.dir / "out.json", "--quiet"], (path,))


def test_the_suites_start_from_good_inputs(tmp_path, model_doc, controller_doc):
    """Each uncorrupted input is accepted (else the suites would test refusals only)."""
    with Workspace(tmp_path) as ws:
        assert ws.run(["analyze", _write(ws, "m.json", json.dumps(model_doc)), "--configurations", "6", "--quiet"])
        GOOD_READ.add("model file")
        for name, text, suite in (("r.yaml", DH, "DH YAML"), ("r.csv", DH_CSV, "DH CSV"), ("r.urdf", URDF, "URDF")):
            assert ws.run(["import-robot", _write(ws, name, text), "--out", ws.dir / "o.json", "--quiet"])
            GOOD_READ.add(suite)
        assert ws.run(["check-hypotheses", SC, _write(ws, "h.yaml", HYPOTHESES), "--configurations", "6", "--quiet"])
        GOOD_READ.add("hypothesis file")
        assert ws.run(["check-controller", _write(ws, "c.json", json.dumps(controller_doc)), "--quiet"])
        GOOD_READ.add("controller file")
