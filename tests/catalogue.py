"""The bad-input catalogue: malformed inputs across every reader, each run through the command line.

Units: lengths in mm, angles in rad.

Each case builds its input in a temporary directory from a good one (a template, a model
file, a STEP file with its sidecar, a measurement file, a hypothesis file, a controller
file) and returns the command line to run and the output that must NOT appear.  The
test (``tests/test_bad_inputs.py``) requires exit code 2, exactly one line on stderr
starting with ``hyperstat: error:``, naming the input, no traceback, and no output file.
``python -m tests.catalogue docs/errors.md`` writes the table of messages.
"""

from __future__ import annotations

import json
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parent.parent
TEMPLATES = ROOT / "templates"
SC = TEMPLATES / "slider_crank.py"


@dataclass
class Case:
    """One malformed input: how to make it, and what the message must name."""

    id: str
    kind: str
    what: str
    make: Callable[[Path, dict], list]  # (tmp, goods) -> argv; the output path is tmp / "out*"
    names: str  # a text the message must contain


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _edit(src: Path, dst: Path, old: str, new: str) -> Path:
    text = src.read_text()
    assert old in text, (src, old)
    return _write(dst, text.replace(old, new, 1))


def _json_edit(src: Path, dst: Path, change: Callable[[dict], None]) -> Path:
    doc = json.loads(src.read_text())
    change(doc)
    return _write(dst, json.dumps(doc))


def _rehashed_defect_change(doc: dict) -> None:
    """Move the first defect by 1e-4 (mm or rad) and recompute the hash: only the test vectors can tell."""
    from hyperstat.solver.export.controller import content_hash

    name = sorted(doc["defects"])[0]
    doc["defects"][name] += 1e-4
    doc["sha256"] = content_hash(doc)


def _analyze(path: Path, tmp: Path, *extra: str) -> list:
    return ["analyze", str(path), *extra, "--json", str(tmp / "out.json")]


def _identify(data: Path, tmp: Path) -> list:
    return ["identify", str(SC), str(data), "--json", str(tmp / "out.json")]


def _template(tmp: Path, name: str, text: str) -> Path:
    return _write(tmp / name, text)


GOOD_TEMPLATE_TAIL = '''
from dataclasses import dataclass
from hyperstat.cad_plugin.params import param
from hyperstat.cad_plugin.skeleton import Skeleton
@dataclass
class Parameters:
    length: float = param(10.0, "mm", "a length")
'''


def _cycle(doc: dict) -> None:
    frame = {"kind": "frame", "name": "ta", "placement": {"origin": [0, 0, 0], "z_axis": [0, 0, 1],
                                                           "x_axis": [1, 0, 0]}}
    doc["chains"].append({"name": "a", "start": "X", "end": "Y", "elements": [frame]})
    doc["chains"].append({"name": "b", "start": "Y", "end": "X", "elements": [dict(frame, name="tb")]})


def _measurement_rows(good: Path, dst: Path, keep: int) -> Path:
    lines = good.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("pose,"))
    return _write(dst, "\n".join(lines[: head + 1 + keep]) + "\n")


def _duplicate_row(good: Path, dst: Path) -> Path:
    lines = good.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("pose,"))
    row = lines[head + 1].split(",")
    row[0] = "P999"
    return _write(dst, "\n".join(lines + [",".join(row)]) + "\n")


def _cell(good: Path, dst: Path, column: str, value: str) -> Path:
    lines = good.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("pose,"))
    cols = lines[head].split(",")
    row = lines[head + 2].split(",")
    row[cols.index(column)] = value
    lines[head + 2] = ",".join(row)
    return _write(dst, "\n".join(lines) + "\n")


CASES = [
    # templates (Python: run as code)
    Case("template-syntax", "template", "syntax error",
         lambda t, g: _analyze(_template(t, "syntax.py", "def build(:\n"), t), "syntax.py: syntax error"),
    Case("template-raises", "template", "exception inside build()",
         lambda t, g: _analyze(_template(t, "boom.py", GOOD_TEMPLATE_TAIL +
                                         "def build(**p):\n    raise ValueError('no')\n"), t), "boom.py"),
    Case("template-no-build", "template", "no build() function",
         lambda t, g: _analyze(_template(t, "nobuild.py", GOOD_TEMPLATE_TAIL), t), "nobuild.py"),
    Case("template-unknown-parameter", "template", "unknown parameter override",
         lambda t, g: _analyze(SC, t, "-p", "colour=3"), "colour"),
    Case("template-negative-length", "template", "negative length",
         lambda t, g: _analyze(SC, t, "-p", "L1=-5mm"), "L1"),
    Case("template-not-a-number", "template", "override that is not a number",
         lambda t, g: _analyze(SC, t, "-p", "L1=__import__('os')"), "L1"),
    Case("template-wrong-unit", "template", "override with a unit of the wrong kind",
         lambda t, g: _analyze(SC, t, "-p", "L1=30deg"), "L1"),
    # model files
    Case("model-not-json", "model file", "not JSON",
         lambda t, g: _analyze(_write(t / "m.json", "{ nope"), t), "m.json"),
    Case("model-missing-field", "model file", "missing field",
         lambda t, g: _analyze(_json_edit(g["model"], t / "m.json", lambda d: d.pop("base")), t), "'base'"),
    Case("model-wrong-version", "model file", "wrong version",
         lambda t, g: _analyze(_json_edit(g["model"], t / "m.json", lambda d: d.update(version=9)), t), "version"),
    Case("model-non-unit-axis", "model file", "non-unit joint axis",
         lambda t, g: _analyze(_json_edit(g["model"], t / "m.json", lambda d: d["chains"][0]["elements"][1]["placement"]
                                          .update(z_axis=[0, 0, 2])), t), "unit vector"),
    Case("model-unknown-frame", "model file", "chain starting at an unknown frame",
         lambda t, g: _analyze(_json_edit(g["model"], t / "m.json", lambda d: d["chains"][1].update(start="nowhere")),
                               t), "nowhere"),
    Case("model-cycle", "model file", "a cycle in the chain definition",
         lambda t, g: _analyze(_json_edit(g["model"], t / "m.json", _cycle), t), "cycle"),
    Case("model-home-outside-range", "model file", "home value outside the joint range",
         lambda t, g: _analyze(_json_edit(g["model"], t / "m.json", lambda d: d["chains"][0]["elements"][1]
                                          .update(home=99.0)), t), "home 99"),
    Case("source-unknown-kind", "source", "unknown file kind",
         lambda t, g: _analyze(_write(t / "m.txt", "x"), t), "m.txt"),
    Case("source-missing", "source", "file that does not exist",
         lambda t, g: _analyze(t / "absent.json", t), "absent.json"),
    # STEP files
    Case("step-missing-sidecar", "STEP file", "sidecar missing",
         lambda t, g: _analyze(Path(shutil.copy(g["step"], t / "lonely.step")), t), "lonely.step.json"),
    Case("step-missing-marker", "STEP file", "a marker the sidecar names is missing",
         lambda t, g: (_json_edit(g["step_sidecar"], t / "x.step.json",
                                  lambda d: d["nodes"].update(m_9=dict(d["nodes"]["m_2"], element="9"))),
                       _analyze(Path(shutil.copy(g["step"], t / "x.step")), t))[1], "m_9"),
    Case("step-metres", "STEP file", "length unit metre",
         lambda t, g: (_write(t / "u.step.json", g["step_sidecar"].read_text()),
                       _analyze(_write(t / "u.step", g["step"].read_text(errors="replace").replace(
                           "SI_UNIT(.MILLI.,.METRE.)", "SI_UNIT($,.METRE.)")), t))[1], "METRE"),
    # measurement files
    Case("data-missing-column", "measurement file", "missing column",
         lambda t, g: _identify(_edit(g["data"], t / "d.csv", "x[mm],", ""), t), "x[mm]"),
    Case("data-nan", "measurement file", "NaN value",
         lambda t, g: _identify(_cell(g["data"], t / "d.csv", "y[mm]", "nan"), t), "NaN"),
    Case("data-text", "measurement file", "text in a number column",
         lambda t, g: _identify(_cell(g["data"], t / "d.csv", "z[mm]", "twelve"), t), "twelve"),
    Case("data-duplicate", "measurement file", "duplicate pose",
         lambda t, g: _identify(_duplicate_row(g["data"], t / "d.csv"), t), "repeat the same pose"),
    Case("data-wrong-unit", "measurement file", "wrong unit",
         lambda t, g: _identify(_edit(g["data"], t / "d.csv", "q1[rad]", "q1[grad]"), t), "q1[grad]"),
    Case("data-too-few", "measurement file", "too few rows for identification",
         lambda t, g: _identify(_measurement_rows(g["data"], t / "d.csv", 2), t), "too few"),
    Case("data-out-of-range", "measurement file", "pose outside the joint range",
         lambda t, g: _identify(_cell(g["data"], t / "d.csv", "q1[rad]", "99"), t), "outside the joint range"),
    Case("data-bad-header", "measurement file", "first line is not the format line",
         lambda t, g: _identify(_edit(g["data"], t / "d.csv", "# hyperstat measurements, version 1", "# csv"), t),
         "first line"),
    Case("data-ragged", "measurement file", "row with a missing value",
         lambda t, g: _identify(_cell(g["data"], t / "d.csv", "z[mm]", "1,2"), t), "values for"),
    # hypothesis files
    Case("hypotheses-yaml", "hypothesis file", "not YAML",
         lambda t, g: ["check-hypotheses", str(SC), str(_write(t / "h.yaml", "a: [b\n")), "--json",
                       str(t / "out.json")], "h.yaml"),
    Case("hypotheses-unknown-relation", "hypothesis file", "unknown relation",
         lambda t, g: ["check-hypotheses", str(SC), str(_edit(g["hyp"], t / "h.yaml", "parallel", "skew")),
                       "--json", str(t / "out.json")], "skew"),
    Case("hypotheses-unknown-axis", "hypothesis file", "relation naming an unknown axis",
         lambda t, g: ["check-hypotheses", str(SC), str(_edit(g["hyp"], t / "h.yaml", "[a2, a3]", "[a2, zz]")),
                       "--json", str(t / "out.json")], "zz"),
    # controller files
    Case("controller-tampered", "controller file", "content changed after export",
         lambda t, g: ["export-linuxcnc", "--controller",
                       str(_json_edit(g["controller"], t / "c.json", lambda d: d["target"].__setitem__(0, 1.0))),
                       "--hal", str(t / "out.hal")], "SHA-256"),
    Case("controller-version", "controller file", "wrong version",
         lambda t, g: ["export-linuxcnc", "--controller",
                       str(_json_edit(g["controller"], t / "c.json", lambda d: d.update(version=7))),
                       "--hal", str(t / "out.hal")], "version"),
    Case("controller-not-json", "controller file", "not JSON",
         lambda t, g: ["export-linuxcnc", "--controller", str(_write(t / "c.json", "[1,")), "--hal",
                       str(t / "out.hal")], "c.json"),
    Case("controller-test-vectors", "controller file", "defect changed and hash recomputed (test vectors fail)",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json", _rehashed_defect_change)),
                       "--json", str(t / "out.json")], "test vector"),
    Case("kins-mechanism", "model file", "mechanism with no LinuxCNC world coordinates (export-linuxcnc-kins)",
         lambda t, g: ["export-linuxcnc-kins", str(g["model"]), "--out", str(t / "out")], "actuated joint"),
    # command-line values
    Case("option-noise", "option", "noise model that cannot be read",
         lambda t, g: ["simulate", str(SC), "--noise", "5 um", "--out", str(t / "out.csv")], "--noise"),
    Case("option-effect", "option", "unknown effect",
         lambda t, g: ["simulate", str(SC), "--effect", "gravity", "--out", str(t / "out.csv")], "gravity"),
]


def goods(tmp: Path) -> dict:
    """Good inputs every case starts from (slider-crank model, STEP, data, hypotheses, a controller file)."""
    import warnings

    from hyperstat.cad_plugin.cli import main
    from hyperstat.cad_plugin.templates import build_template
    from hyperstat.solver.kinematics.modelfile import save_model

    tmp.mkdir(parents=True, exist_ok=True)
    sk = build_template(SC)
    model = save_model(sk.mechanism(), tmp / "good.json")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["build", str(SC), "--step", str(tmp / "good.step")]) == 0
        assert main(["simulate", str(SC), "--poses", "30", "--validation", "0", "--out", str(tmp / "good.csv"),
                     "--quiet"]) == 0
    hyp = _write(tmp / "good.yaml", "format: hyperstat-hypotheses\nversion: 1\naxes:\n  a2: {element: '2'}\n"
                 "  a3: {element: '3'}\nhypotheses:\n  - {id: h1, parallel: [a2, a3]}\n")
    hexa = TEMPLATES / "hexapod.py"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["simulate", str(hexa), "--poses", "40", "--validation", "0", "--out", str(tmp / "hex.csv"),
                     "--quiet"]) == 0
        assert main(["export-controller", str(hexa), str(tmp / "hex.csv"), "--out", str(tmp / "good_ctl.json"),
                     "--quiet"]) == 0
    return {"model": model, "step": tmp / "good.step", "step_sidecar": tmp / "good.step.json",
            "data": tmp / "good.csv", "hyp": hyp, "controller": tmp / "good_ctl.json"}


def run_case(case: Case, tmp: Path, good: dict) -> tuple[int, str, str, list]:
    """Run one case in-process; returns (exit code, stdout, stderr, output files left)."""
    import contextlib
    import io

    from hyperstat.cad_plugin.cli import main

    tmp.mkdir(parents=True, exist_ok=True)
    argv = case.make(tmp, good)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse
            code = exc.code
    left = sorted(p.name for p in tmp.iterdir() if p.name.startswith("out"))
    return code, out.getvalue(), err.getvalue(), left


def markdown(rows: list) -> str:
    """The catalogue as the table of docs/errors.md."""
    lines = ["# Errors: what hyperstat says about bad input", "",
             "Every malformed input gets one sentence on stderr naming the input and what is wrong, exit",
             "code 2, no traceback and no output file (written atomically: a temporary file, then a rename).",
             "This table is produced by `python -m tests.catalogue docs/errors.md` and checked by",
             "`tests/test_bad_inputs.py` (temporary paths shortened to `TMP/`).", "",
             "| input | case | message |", "|---|---|---|"]
    for case, message in rows:
        lines.append(f"| {case.kind} | {case.what} | `{message}` |")
    return "\n".join(lines) + "\n"


def clean(message: str, tmp: Path) -> str:
    """The message with the temporary directory replaced by ``TMP``, and a measured distance (which
    differs in its last digits between runs of the identification behind it) by ``D``."""
    import re

    text = message.strip().replace(str(tmp) + "/", "TMP/").replace(str(tmp), "TMP")
    text = re.sub(r"is \d\.\d+e-\d+ mm from the file's", "is D mm from the file's", text)
    return text.replace(str(ROOT) + "/", "").replace("|", "\\|")


if __name__ == "__main__":  # pragma: no cover
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        base = Path(d)
        good = goods(base / "good")
        rows = []
        for case in CASES:
            code, _, err, _ = run_case(case, base / case.id, good)
            rows.append((case, clean(err, base / case.id)))
        Path(sys.argv[1]).write_text(markdown(rows))
