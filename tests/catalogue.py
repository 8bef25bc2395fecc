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
    """Move the first defect the file does not list as identified by 1e-4 (mm or rad) and recompute the hash: only
    the test vectors can tell (an identified one must equal its estimate, refused before)."""
    from hyperstat.solver.export.controller import content_hash

    identified = {p["name"] for p in doc["identified"]}
    name = next(n for n in sorted(doc["defects"]) if n not in identified)
    doc["defects"][name] += 1e-4
    doc["sha256"] = content_hash(doc)


def _jittered_copies(good: Path, dst: Path) -> Path:
    """Every pose of a measurement file repeated with a 1e-9 rad jitter of its first joint (a copied campaign)."""
    lines = good.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("pose,"))
    copies = []
    for line in lines[head + 1:]:
        row = line.split(",")
        row[0] += "b"
        row[1] = repr(float(row[1]) + 1e-9)
        copies.append(",".join(row))
    return _write(dst, "\n".join(lines + copies) + "\n")


def _serial_model(tmp: Path, masses: dict) -> Path:
    """The robot-import tests' DH table as a model file, with ``metadata.masses`` set to ``masses``."""
    from hyperstat.solver.kinematics.modelfile import save_model
    from hyperstat.solver.kinematics.robot_import import import_robot

    path = save_model(import_robot(_robot(tmp, "r.yaml", "angle: deg}", "angle: deg}")), tmp / "serial.skel.json")
    doc = json.loads(path.read_text())
    doc["metadata"]["masses"] = masses
    return _write(tmp / "m.json", json.dumps(doc))


def _link_inertial(tmp: Path, inertial: str) -> Path:
    """The robot-import tests' URDF with link l2 given ``inertial`` (XML)."""
    return _robot(tmp, "r.urdf", '<link name="l2"/>', f'<link name="l2">{inertial}</link>')


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


def _import(robot: Path, tmp: Path) -> list:
    return ["import-robot", str(robot), "--out", str(tmp / "out.skel.json")]


def _robot(tmp: Path, name: str, old: str, new: str) -> Path:
    """A good robot file (``.urdf``, ``.yaml``, ``.csv``; those of the robot-import tests) with ``old`` replaced by
    ``new``."""
    from tests.solver.kinematics.test_robot_import_checks import DH, DH_CSV, URDF

    text = {".urdf": URDF, ".yaml": DH, ".csv": DH_CSV}[Path(name).suffix]
    assert old in text, (name, old)
    return _write(tmp / name, text.replace(old, new, 1))


def _rehashed(change: Callable[[dict], None]) -> Callable[[dict], None]:
    """A controller-file change followed by a recomputed hash: what only the content checks can catch."""
    def apply(doc: dict) -> None:
        from hyperstat.solver.export.controller import content_hash

        change(doc)
        doc["sha256"] = content_hash(doc)
    return apply


def _widen_first_range(doc: dict) -> None:
    joint = next(e for ch in doc["model"]["chains"] for e in ch["elements"] if e.get("role") == "actuated")
    joint["range"][1] += 50.0


def _mkdir(path: Path) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    return path


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
    Case("template-angle-in-degrees", "template", "an angle out of its bounds that fits them in degrees",
         lambda t, g: _analyze(SC, t, "-p", "home_angle=30"), "did you mean 30deg"),
    Case("source-unknown-name", "source", "a name that is no file and no bundled template",
         lambda t, g: _analyze(Path("slider_crunk"), t), "did you mean 'slider_crank'"),
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
    # robot files (import-robot): malformed URDF graphs, implausible values, declarations twice (issue 31)
    Case("urdf-missing-link", "URDF", "a joint's parent link is not declared",
         lambda t, g: _import(_robot(t, "r.urdf", '<parent link="l1"/>', '<parent link="lX"/>'), t), "'lX'"),
    Case("urdf-loop", "URDF", "a closed loop (a link with two parents)",
         lambda t, g: _import(_robot(t, "r.urdf", "</robot>", '<joint name="j4" type="fixed"><parent link="l3"/>'
                                     '<child link="l1"/></joint></robot>'), t), "closed loop"),
    Case("urdf-zero-axis", "URDF", "a zero joint axis",
         lambda t, g: _import(_robot(t, "r.urdf", '<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>'), t), "'j2'"),
    Case("urdf-mimic", "URDF", "a mimic joint on the chain",
         lambda t, g: _import(_robot(t, "r.urdf", '<axis xyz="0 1 0"/>', '<axis xyz="0 1 0"/><mimic joint="j1"/>'), t),
         "mimic"),
    Case("urdf-degrees", "URDF", "limits in degrees",
         lambda t, g: _import(_robot(t, "r.urdf", 'lower="-2" upper="2"', 'lower="-120" upper="120"'), t), "degrees"),
    Case("dh-degrees", "DH table", "angles in degrees labelled rad (YAML)",
         lambda t, g: _import(_robot(t, "r.yaml", "angle: deg}", "angle: rad}"), t), "looks like degrees"),
    Case("dh-range-degrees", "DH table", "ranges of +-180 labelled rad (CSV)",
         lambda t, g: _import(_write(t / "r.csv", "# convention: dh\n"
                                     "joint,type,a[mm],alpha[rad],d[mm],theta[rad],min[rad],max[rad]\n"
                                     "1,R,312,-1.5,670,0,-180,180\n2,R,1075,0,0,-1.5,-1,1\n"), t),
         "looks like degrees"),
    Case("dh-huge", "DH table", "a = 1e308 (YAML)",
         lambda t, g: _import(_robot(t, "r.yaml", "a: 1075", "a: 1e308"), t), "1e+308"),
    Case("dh-huge-csv", "DH table", "a = 1e308 (CSV)",
         lambda t, g: _import(_robot(t, "r.csv", "2,R,1075", "2,R,1e308"), t), "1e+308"),
    Case("dh-key-twice", "DH table", "a field declared twice in a row",
         lambda t, g: _import(_robot(t, "r.yaml", "a: 1075,", "a: 1075, a: 1076,"), t), "declared twice"),
    Case("dh-joint-map-self", "DH table", "a joint map naming a model joint as a controller joint",
         lambda t, g: _import(_robot(t, "r.yaml", '"2": {J2: -1, offset: 0.5}', '"2": {"2": -1}'), t), "model joint"),
    # model files and templates: plausibility and declarations twice
    Case("model-absurd-origin", "model file", "an origin of 1e308 mm",
         lambda t, g: _analyze(_json_edit(g["model"], t / "m.json", lambda d: d["chains"][0]["elements"][1]["placement"]
                                          .update(origin=[1e308, 0, 0])), t), "1e+308"),
    Case("model-range-degrees", "model file", "a revolute range in degrees",
         lambda t, g: _analyze(_json_edit(g["model"], t / "m.json", lambda d: d["chains"][0]["elements"][1]
                                          .update(range=[-180, 180])), t), "looks like degrees"),
    Case("model-key-twice", "model file", "a key declared twice",
         lambda t, g: _analyze(_write(t / "m.json", g["model"].read_text().replace('"name":', '"name": "x", "name":', 1)),
                               t), "declared twice"),
    Case("template-absurd-length", "template", "a length of 1e308 mm",
         lambda t, g: _analyze(SC, t, "-p", "L1=1e308mm"), "L1"),
    Case("template-twice", "template", "a parameter given twice",
         lambda t, g: _analyze(SC, t, "-p", "L1=30", "-p", "L1=31"), "twice"),
    # measurement and hypothesis files: declarations twice
    Case("data-two-priors", "measurement file", "two priors for the same reflector",
         lambda t, g: _identify(_edit(g["data"], t / "d.csv", "# target:", "# target: 1 2 3\n# target:"), t),
         "declared in line"),
    Case("hypotheses-key-twice", "hypothesis file", "an axis declared twice",
         lambda t, g: ["check-hypotheses", str(SC), str(_edit(g["hyp"], t / "h.yaml", "  a3: {element: '3'}",
                                                              "  a3: {element: '3'}\n  a3: {element: '2'}")),
                       "--json", str(t / "out.json")], "declared twice"),
    # controller files that try to vouch for themselves (hash recomputed)
    Case("controller-tolerance", "controller file", "test-vector tolerance raised, hash recomputed",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json", _rehashed(
             lambda d: d["test_vectors"]["tolerance"].update(length_mm=1e3))))], "cannot set its own tolerance"),
    Case("controller-unknown-defect", "controller file", "an unknown defect dX99, hash recomputed",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json", _rehashed(
             lambda d: d["defects"].update(dX99=0.0))))], "dX99"),
    Case("controller-range", "controller file", "a joint range widened, hash recomputed",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json",
                                                          _rehashed(_widen_first_range)))], "joint ranges"),
    Case("controller-magnitude", "controller file", "a defect beyond what the version admits, hash recomputed",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json", _rehashed(
             lambda d: d["defects"].update({sorted(d["defects"])[0]: 0.5}))))], "version 3 admits"),
    # controller files that contradict themselves (issue 37; hash recomputed)
    Case("controller-name", "controller file", "another mechanism's name, hash recomputed",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json", _rehashed(
             lambda d: d.update(mechanism="tripteor_x7"))))], "the embedded model is 'hexapod'"),
    Case("controller-identified", "controller file", "an identified estimate moved 0.5 mm from its defect, hash "
         "recomputed",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json", _rehashed(
             lambda d: next(p for p in d["identified"] if p["unit"] == "mm").update(
                 estimate=next(p for p in d["identified"] if p["unit"] == "mm")["estimate"] + 0.5))))],
         "the file contradicts itself"),
    Case("controller-negative-rms", "controller file", "a negative RMS, hash recomputed",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json", _rehashed(
             lambda d: d["statistics"]["identification"].update(rms=-0.01))))], "at least 0"),
    Case("controller-rank", "controller file", "a rank above the unknowns, hash recomputed",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json", _rehashed(
             lambda d: d["statistics"].update(rank=99))))], "statistics.rank"),
    Case("controller-condition", "controller file", "condition number 1e308 in a file not written with --force, hash "
         "recomputed",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json", _rehashed(
             lambda d: d["statistics"].update(condition_number=1e308))))], "--force"),
    Case("controller-vectors-dropped", "controller file", "test vectors dropped, hash recomputed",
         lambda t, g: ["check-controller", str(_json_edit(g["controller"], t / "c.json", _rehashed(
             lambda d: d["test_vectors"].update(vectors=d["test_vectors"]["vectors"][:20]))))], "were vectors dropped"),
    # outputs: checked before the work
    Case("output-is-a-directory", "output", "--out names an existing directory",
         lambda t, g: ["export-controller", str(SC), str(g["data"]), "--out", str(_mkdir(t / "dir.json"))],
         "is a directory"),
    Case("output-under-a-file", "output", "an output directory below a file",
         lambda t, g: ["export-linuxcnc-kins", str(g["model"]), "--out", str(_write(t / "f.txt", "x") / "k")],
         "is a file, not a directory"),
    # a calibration that must not be exported
    Case("export-absurd", "calibration", "export of a fit identify calls absurd (z in m, values in mm)",
         lambda t, g: ["export-controller", str(SC), str(_edit(g["data"], t / "d.csv", "z[mm]", "z[m]")), "--out",
                       str(t / "out.json")], "--force"),
    Case("export-repeated", "calibration", "every pose repeated with a 1e-9 rad jitter",
         lambda t, g: ["export-controller", str(SC), str(_jittered_copies(g["data"], t / "d.csv")), "--out",
                       str(t / "out.json")], "repeat others within the noise"),
    Case("export-outlier", "calibration", "one coordinate 50 mm off",
         lambda t, g: ["export-controller", str(SC), str(_cell(g["data"], t / "d.csv", "z[mm]", "50")), "--out",
                       str(t / "out.json")], "--exclude-outliers"),
    Case("export-few-poses", "calibration", "5 poses for 9 identified parameters",
         lambda t, g: ["export-controller", str(SC), str(_measurement_rows(g["data"], t / "d.csv", 5)), "--out",
                       str(t / "out.json")], "equations per identified parameter"),
    # masses (issue 37)
    Case("urdf-inertial-twice", "URDF", "a link with two <inertial>",
         lambda t, g: _import(_link_inertial(t, '<inertial><mass value="3"/></inertial>'
                                                '<inertial><mass value="4"/></inertial>'), t), "<inertial> 2 times"),
    Case("urdf-inertial-nan", "URDF", "an inertial origin xyz=\"nan 0 0\"",
         lambda t, g: _import(_link_inertial(t, '<inertial><mass value="3"/><origin xyz="nan 0 0"/></inertial>'), t),
         "finite"),
    Case("urdf-mass-grams", "URDF", "a link mass in grams (3000 for 3 kg)",
         lambda t, g: _import(_link_inertial(t, '<inertial><mass value="3000"/><origin xyz="0.15 0 0"/></inertial>'),
                              t), "in grams"),
    Case("urdf-com-far", "URDF", "a centre of mass 10 m from its link",
         lambda t, g: _import(_link_inertial(t, '<inertial><mass value="3"/><origin xyz="10 0 0"/></inertial>'), t),
         "outside the link"),
    Case("model-mass-absurd", "model file", "metadata.masses with a 1e30 kg body",
         lambda t, g: _analyze(_serial_model(t, {"1": {"mass": 1e30, "com": [150, 0, 600]},
                                                 "2": {"mass": 20.0, "com": [800, 0, 670]}}), t),
         "not plausible for its size"),
    Case("model-mass-missing", "model file", "metadata.masses leaving a moving joint out",
         lambda t, g: _analyze(_serial_model(t, {"1": {"mass": 20.0, "com": [0, 0, 600]}}), t),
         "gives no mass for joint"),
    Case("template-density", "template", "a material density in g/cm^3 (7.85)",
         lambda t, g: _analyze(_template(t, "dense.py", GOOD_TEMPLATE_TAIL + "def build(**p):\n    sk = Skeleton('d')\n"
                                         "    sk.material('steel', density_kg_m3=7.85)\n    return sk\n"), t),
         "g/cm^3"),
    # command-line values
    Case("montecarlo-nothing-to-draw", "option", "Monte Carlo with a spec the calibration noise uses up",
         lambda t, g: ["montecarlo", "spherical_4r", "--orientation-accuracy", "1e-9", "--samples", "10",
                       "--workspace-configurations", "20", "--json", str(t / "out.json")], "--angle-tolerance"),
    Case("option-noise", "option", "noise model that cannot be read",
         lambda t, g: ["simulate", str(SC), "--noise", "5 um", "--out", str(t / "out.csv")], "--noise"),
    Case("option-effect", "option", "unknown effect",
         lambda t, g: ["simulate", str(SC), "--effect", "gravity", "--out", str(t / "out.csv")], "gravity"),
    Case("option-workspace-loss", "option", "workspace-loss budget of 100 % or more",
         lambda t, g: ["report", str(SC), "--workspace-loss", "1.5", "--out", str(t / "out")], "--workspace-loss"),
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
             "code 2, no traceback and no output file.  Outputs are checked before the work starts (a folder",
             "that cannot be written, a directory where a file goes, a file that cannot be replaced), and a",
             "command's files are written together at its end or not at all (`solver/atomic.py`).",
             "This table is produced by `python -m tests.catalogue docs/errors.md` and checked by",
             "`tests/test_bad_inputs.py` (temporary paths shortened to `TMP/`).", "",
             "| input | case | message |", "|---|---|---|"]
    for case, message in rows:
        lines.append(f"| {case.kind} | {case.what} | `{message}` |")
    return "\n".join(lines + [""] + TRAILER) + "\n"


#: the refusals that the table shows one example of, by class, with where each is tested
TRAILER = """## The classes behind the table

**Plausibility, with units** (`solver/plausibility.py`).  Every number read is converted to mm or rad
and refused outside its range, in the unit the input used: a length or position beyond 100 m
(`... = 1e+308 mm is not a plausible length (at most 100 m).`; a value in a file that says `m` and
would fit in mm: `...: it looks like millimetres (state the unit as mm).`); a constant angle (DH `alpha`,
`theta`, roll-pitch-yaw, a rotation vector, a joint-map offset) beyond a turn, and a revolute joint
range beyond two turns: `... = -90 rad is beyond 2 pi rad (a turn): it looks like degrees (state the
unit as deg).`; a joint value in `rad` outside its range that fits in degrees: `...: it looks like
degrees (write 'q1[deg]').`; tracker noise beyond 100 mm or 100 mm/m, orientation noise beyond
0.1 rad, a temperature outside -100..200 degC, a payload outside 0..10000 kg, a gear ratio outside
1e-6..1e6, a coupling coefficient beyond 1000; NaN and infinities everywhere.  Readers: model files
(`Mechanism`), template parameters, DH tables (YAML, CSV), joint maps, URDF, measurement files
(positions, 6-D rows, header lines, metadata), controller files (below).
Tests: `tests/solver/kinematics/test_robot_import_checks.py`,
`tests/solver/calibration/test_measurement_checks.py`, the table above.

**Malformed URDF graphs** (`check_urdf` in `solver/kinematics/robot_import.py`, every joint, not only
the chain's): a parent or child link not declared; a link the child of two joints or joints that
close a loop (`... the joints form a closed loop`); a joint joining a link to itself; a zero or
non-finite axis; a mimic joint on the chain (refused) or naming an unknown joint; two links or two
joints of one name; an unknown joint type; lower >= upper; XML that is not well formed.  Nothing is
dropped: a chain with a missing link was imported short before.
Tests: `tests/solver/kinematics/test_robot_import_checks.py` (18 URDF cases).

**Declared twice or in conflict**: a YAML or JSON key declared twice (DH tables, joint maps,
hypothesis files, model files, controller files: `key 'a' is declared twice (line 8).`, read by
`solver/strict_load.py`); a CSV column or header line twice; a measurement header declared twice
(two priors for one reflector, in any case), a prior for a reflector without columns, reflectors
whose names differ only by case; a model joint twice in a joint map; a template parameter given
twice; an axis through the same point twice, or through two points that coincide at home.

**A controller file cannot vouch for itself** (`check_admissible` in `solver/export/controller.py`,
run by every reader of the file after the hash): a test-vector tolerance other than the version's;
a defect the model does not have, or one missing; a defect beyond 0.1 rad or 100 mm, a tool point or
target beyond 2000 mm; an effect option, parameter or value the effect does not admit; keys the
format does not hold (schema); test vectors that are not the version's configurations from the file's
joint ranges (a range changed after export), one missing that assembles, fewer than 12 draws;
controller joint values the joint map does not turn into the vectors' actuated values.  Nor can it
contradict itself (`solver/export/controller_checks.py`): another mechanism's name, an identified
estimate other than the value applied, implausible statistics (a negative RMS, a rank above the
unknowns, a condition number that is not finite), a calibration record whose numbers the export gate
refuses in a file not marked as written with `--force`.  `check-controller` also refuses an actuated
range a parallel mechanism cannot reach, and, with `--source`, a model (ranges included) that differs
from the trusted one.
Tests: `tests/solver/export/test_controller.py`.

**A calibration that must not be exported**: `export-controller`, `export-urdf` and `export-dh` refuse
every refusing finding of identify unless `--force`, which records the reasons in the file: residuals
(fitted or held-out, per target) more than 3 times the stated noise or absurd, worse than the nominal
model on held-out poses, fewer than 2 equations per parameter, poor conditioning, targets that
coincide, poses repeated within the noise, outliers still in (`... not written: it predicts the held-out
poses worse than the nominal model (validation RMS A mm against B mm with the nominal geometry); check
the inputs, or write it anyway with --force (the reasons are then recorded in the file).`).
Tests: `tests/solver/export/test_calibration_gate.py`, `tests/solver/calibration/test_export_findings.py`.

**Masses** (`solver/kinematics/masses.py`): a URDF `<inertial>` declared twice or with a value that
is not finite, a mass beyond a ball of solid copper around its link, a centre of mass outside its link
widened by a fifth of the chain's reach (`import-robot`, per link and then per body as the model file it writes
carries them); the same for `metadata.masses`, and a moving
joint of a serial chain left out of it; a material density outside 100-22590 kg/m^3 (`sk.material`).
Tests: `tests/solver/kinematics/test_mass_plausibility.py`.

**Outputs**: refused before the work (the table's examples, and an output folder that cannot be
written: `TMP/locked: the directory cannot be written (Operation not permitted), so ... cannot be
written.`); at the end, a file that cannot be replaced: `TMP/k/machine.ini: cannot be replaced
(read-only or immutable); no output was written.`, every other output left as it was.
Tests: `tests/test_outputs_whole_or_absent.py` (each output of `report`, `export-linuxcnc-kins`,
`export-controller`, `identify` made unwritable in turn), `tests/solver/test_atomic.py`.

**Plug-ins**: an effect plug-in that cannot be loaded is named (`the effect plug-in 'NAME' (VALUE)
cannot be loaded: ...`); one that fails while the diagnosis runs is issue 28's.""".splitlines()


def clean(message: str, tmp: Path) -> str:
    """The message with the temporary directory replaced by ``TMP``, and a measured distance (which
    differs in its last digits between runs of the identification behind it) by ``D``."""
    import re

    text = message.strip().replace(str(tmp) + "/", "TMP/").replace(str(tmp), "TMP")
    text = re.sub(r"is \d\.\d+e-\d+ mm from the file's", "is D mm from the file's", text)
    text = re.sub(r"the residuals are [\d.]+ times", "the residuals are S times", text)
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
