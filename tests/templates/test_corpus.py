"""The corpus: every mechanism of ``templates/corpus/`` through every command, against its theory.

Units: lengths in mm, angles in rad.

For each member, the commands a user would run, in order (:mod:`tests.templates.corpus_runner`): ``build``
(model + STEP; ``import-robot`` for the DH tables and the URDF), ``analyze``, ``report`` (HTML, Markdown,
JSON), ``accuracy``, ``montecarlo``, ``simulate``, ``identify``, ``diagnose``, ``export-controller`` and
``check-controller``, with small samples where a command has them.  They run once per session in a
background worker started at collection (``tests/templates/conftest.py``), on the other core while the
rest of the suite runs.  Every command must end with exit code 0, or with 2 and one sentence on stderr that
says what it cannot do for this mechanism (no traceback, none of its outputs left behind, whole or
half-written).  Left out, and said why: ``corpus_runner.LEFT_OUT``.

The theory: each member states ``Theory: mobility M, degree of over-constraint D, assembly conditions
C.``; ``analyze`` must say the same, and so must an independent computation
(:mod:`tests.templates.screw_theory`: products of exponentials, no solver code) from the template's
declarations, with ``C`` = the screw computation's first-order conditions on the joint lines plus ``D``
(see that module).  The printed PDF is checked for two members (Bennett, and the 3-UPU as a parallel
robot).
"""

from __future__ import annotations

import json
import re
import subprocess

import pytest

from hyperstat.cad_plugin.templates import CORPUS_DIR, build_template

from tests.templates.conftest import corpus_job, wait_shared_corpus
from tests.templates.corpus_runner import LEFT_OUT, MEMBERS, OUTPUTS, ROBOTS, TEMPLATES, commands, member_dir, parts, \
    run, theory_of
from tests.templates.screw_theory import screw_model

PRINTED = ["bennett", "tsai_3upu"]
WAIT_S = 3600


@pytest.fixture(scope="session")
def corpus(tmp_path_factory) -> dict:
    """Every command on every member, once per session: outcome, stderr, wall and CPU seconds per (member, command).

    Read from the background worker that the collection started (``tests/templates/conftest.py``; under xdist, the
    one the controller started); run here, in this process, when there is none.
    """
    job = corpus_job()
    try:
        shared = None if job else wait_shared_corpus(WAIT_S)
    except (TimeoutError, RuntimeError) as exc:
        pytest.fail(str(exc))
    if job:
        try:
            job["proc"].wait(timeout=WAIT_S)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the corpus worker did not finish within {WAIT_S} s")
        root = job["root"]
        assert (root / "done").is_file(), (root / "worker.log").read_text(encoding="utf-8")[-4000:]
    elif shared is not None:
        root = shared
    else:
        root = tmp_path_factory.mktemp("corpus")
        run(root, MEMBERS)
    out = {"root": root, "runs": {}}
    for line in (root / "outcomes.jsonl").read_text(encoding="utf-8").splitlines():
        r = json.loads(line)
        r["dir"] = member_dir(root, r["member"])
        out["runs"][(r["member"], r["command"])] = r
    out["seconds"] = sum(r["seconds"] for r in out["runs"].values())
    out["cpu"] = sum(r["cpu"] for r in out["runs"].values())
    return out


def test_the_corpus_has_at_least_fifteen_members_each_with_its_theory():
    assert len(MEMBERS) >= 15
    for member in MEMBERS:
        theory_of(member)


def test_the_background_processes_run_every_member_once():
    """The background run's processes (``corpus_runner.parts``): every member in exactly one, in its order, the
    revolute Delta alone; one process: all members."""
    for processes in (1, 2, 3):
        split = parts(MEMBERS, processes)
        assert len(split) <= processes and sorted(m for group in split for m in group) == sorted(MEMBERS)
        assert all(group == [m for m in MEMBERS if m in group] for group in split)
    assert parts(MEMBERS, 1) == [MEMBERS] and ["delta_r"] in parts(MEMBERS, 2)


@pytest.mark.parametrize("member", TEMPLATES)
def test_the_theory_line_is_screw_theory(member):
    """The docstring's numbers from the declarations alone: mobility, over-constraint and conditions."""
    mobility, overconstraint, conditions = theory_of(member)
    skeleton = build_template(CORPUS_DIR / f"{member}.py")
    got = screw_model(skeleton).theory(configurations=14 if mobility == 1 else 8)
    assert got["condition_gap"] > 1e4, got  # a clear rank decision
    assert (got["mobility"], got["overconstraint"], got["conditions"] + got["overconstraint"]) == \
        (mobility, overconstraint, conditions)


@pytest.mark.parametrize("member", MEMBERS)
def test_analyze_equals_the_theory(corpus, member):
    run = corpus["runs"][(member, "analyze")]
    assert run["code"] == 0, run["stderr"]
    doc = json.loads((run["dir"] / "a.json").read_text())
    mobility, overconstraint, conditions = theory_of(member)
    assert (doc["mobility"], doc["overconstraint"]) == (mobility, overconstraint)
    assert doc["tolerances"]["counts"]["assembly"] == conditions == doc["rank"]
    assert doc["stability"]["stable"], doc["stability"]


@pytest.mark.parametrize("member", MEMBERS)
def test_every_command_ends_with_0_or_one_sentence_and_2(corpus, member):
    """Exit 0 with its outputs, or exit 2 with one sentence on stderr and none of its outputs; no traceback."""
    ran = [c for (who, c) in corpus["runs"] if who == member]
    assert ran == [argv[0] for argv in commands(member, corpus["root"])]  # every command (but LEFT_OUT) ran
    for (who, command), run in corpus["runs"].items():
        if who != member:
            continue
        assert "Traceback" not in run["stderr"] + run["stdout"], (command, run["stderr"])
        assert run["code"] in (0, 2), (command, run["code"], run["stderr"])
        outputs = [run["dir"] / o for o in OUTPUTS[command]]
        if run["code"] == 0:
            assert all(o.is_file() and o.stat().st_size > 0 for o in outputs), (command, outputs)
            continue
        errors = [line for line in run["stderr"].splitlines() if line.startswith("hyperstat: error: ")]
        assert len(errors) == 1 and errors[0].endswith("."), (command, run["stderr"])
        assert not any(o.exists() for o in outputs), (command, [o for o in outputs if o.exists()])
    leftovers = [p for p in member_dir(corpus["root"], member).rglob("*")
                 if p.name.startswith(".") or p.suffix in (".part", ".tmp")]
    assert not leftovers, leftovers


@pytest.mark.parametrize("member", MEMBERS)
def test_the_steps_a_designer_needs_succeed(corpus, member):
    """Model, analysis, report, accuracy, Monte Carlo and simulated data exist for every member."""
    for command in ("build" if member in TEMPLATES else "import-robot", "analyze", "report", "accuracy",
                    "simulate", "identify"):
        if (member, command) in LEFT_OUT:
            continue
        run = corpus["runs"][(member, command)]
        assert run["code"] == 0, (command, run["stderr"])


@pytest.mark.parametrize("member", [m for m in MEMBERS if (m, "report") not in LEFT_OUT])
def test_the_reports_tables_keep_their_columns(corpus, member):
    """report.md: a ``|`` inside a cell (an ISO 1101 frame) is escaped, so every row of the tolerance table has its
    nine cells and its class column reads a class; the JSON and the Markdown count the same tolerances."""
    run = corpus["runs"][(member, "report")]
    assert run["code"] == 0, run["stderr"]
    md = (run["dir"] / "rep" / "report.md").read_text(encoding="utf-8")
    doc = json.loads((run["dir"] / "rep" / "report.json").read_text())
    table = md.split("## Tolerances", 1)[1].split("\n\n", 2)[1].splitlines()
    assert table[0].startswith("| id | feature")
    rows = [re.split(r"(?<!\\)\|", row)[1:-1] for row in table[2:]]  # a GitHub-flavoured Markdown reader's split
    assert len(rows) == len(doc["tolerances"]["items"])
    for cells, item in zip(rows, doc["tolerances"]["items"]):
        assert len(cells) == 9, cells
        assert cells[7].strip() == item["class"] and cells[0].strip() == item["id"]
    assert "<html" in (run["dir"] / "rep" / "report.html").read_text(encoding="utf-8")[:200].lower()


@pytest.mark.parametrize("member", [m for m in MEMBERS if (m, "report") not in LEFT_OUT])
def test_a_zone_no_workshop_holds_is_said_on_page_1_and_on_its_frame(corpus, member):
    """Every frame whose zone is below 0.3 µm (ISO 286-1's finest grade, IT01; read from the JSON here, not from the
    code's list) is named by the PRACTICAL SIZE warning with its tolerances and carries the note on its part page;
    no other frame is; the title block of report.md carries the warning on page 1, the HTML's in its warning style,
    and the appendix's warnings list does not repeat it.  Tsai's 3-UPU has such frames (its U-joints' tilts move the
    platform's orientation thousands of times over); a member without any carries no warning."""
    run = corpus["runs"][(member, "report")]
    assert run["code"] == 0, run["stderr"]
    doc = json.loads((run["dir"] / "rep" / "report.json").read_text())
    md = (run["dir"] / "rep" / "report.md").read_text(encoding="utf-8")
    html = (run["dir"] / "rep" / "report.html").read_text(encoding="utf-8")
    frames = [f for d in doc.get("drawings") or [] for f in d["frames"]]
    small = [f for f in frames if f["zone_mm"] < 3e-4]
    warnings = [w for w in doc["tolerances"].get("warnings") or [] if w.startswith("PRACTICAL SIZE: ")]
    if member == "tsai_3upu":
        assert small, "the 3-UPU's U-joint tilts were expected below 0.3 µm"
    assert len(warnings) == (1 if small else 0), warnings
    for f in frames:
        assert ("below 0.3 µm" in f["note"]) == (f in small), (f["id"], f["zone_mm"], f["note"])
    if not small:
        assert "drawing: WARNING" not in md
        return
    warning = warnings[0]
    assert warning.startswith(f"PRACTICAL SIZE: {len(small)} frame")
    named = re.findall(r"(\S+) \((\S+) mm; ([^)]*)\)", warning)
    assert len(named) == min(len(small), 12)
    classes = {t["id"]: t["class"] for t in doc["tolerances"]["items"]}
    for (fid, zone, carried), f in zip(named, small):
        assert fid == f["id"] and float(zone) == f["zone_mm"]
        said = {}  # "T7-T9, T12 assembly, T13 compensable" -> id: class
        for group in re.findall(r"((?:T\d+(?:-T\d+)?, )*T\d+(?:-T\d+)?) ([a-z-]+)", carried):
            for first, last in re.findall(r"T(\d+)(?:-T(\d+))?", group[0]):
                for n in range(int(first), int(last or first) + 1):
                    said[f"T{n}"] = group[1]
        assert said == {tid: classes[tid] for tid in f["tolerances"]}, (carried, f["tolerances"])
    title = md.split("## Summary", 1)[0]
    assert f"* drawing: WARNING: {warning[len('PRACTICAL SIZE: '):]}" in title
    assert md.count(warning[len("PRACTICAL SIZE: "):]) == 1  # not again in the warnings' list
    assert '<td colspan="3" class="warn">WARNING: ' in html


@pytest.mark.parametrize("member", PRINTED)
def test_the_report_prints(corpus, member, tmp_path):
    """The HTML printed on A4 by headless Chromium: pages, and the tolerance table's words in the PDF."""
    from tests.cad_plugin.test_report import page_text, pages_of, print_pdf

    run = corpus["runs"][(member, "report")]
    pdf = print_pdf(run["dir"] / "rep" / "report.html", tmp_path / "report.pdf")
    pages = pages_of(pdf)
    text = "".join(page_text(pdf, k, layout=False) for k in range(1, pages + 1))
    assert pages >= 2 and member in text and "assembly" in text


def test_a_controller_file_comes_out_of_the_bennett_linkage(corpus):
    """The issue's user story: a Bennett linkage gets its controller file, and the file checks."""
    assert corpus["runs"][("bennett", "export-controller")]["code"] == 0, \
        corpus["runs"][("bennett", "export-controller")]["stderr"]
    assert corpus["runs"][("bennett", "check-controller")]["code"] == 0


def test_the_revolute_delta_file_keeps_the_identified_tool_frame(corpus):
    """The revolute Delta's identified defects do not close its loops beyond first order, so the file carries them
    moved onto loops that close, by the change that moves the fitted poses' predictions the least
    (``prediction_metric``).  The file's own model (:class:`ControllerModel`, which reads only the file), with the
    tracker frame and target that ``identify`` fitted on the same data, predicts the held-out poses within 1.5 times
    the RMS the file records, the tracker not placed again; the least-norm move displaced the tool frame by up to
    0.032 mm against the identified base frame (2.1 times the held-out RMS, a note in the file).  No note now, and
    ``check-controller`` prints none."""
    import numpy as np

    from hyperstat.solver.calibration.measurements import read_measurements
    from hyperstat.solver.export.controller import ControllerModel
    from hyperstat.solver.kinematics.frames import so3_exp

    run = corpus["runs"][("delta_r", "export-controller")]
    assert run["code"] == 0, run["stderr"]
    doc = json.loads((run["dir"] / "m.json").read_text())
    assert not [f for f in doc["calibration"]["findings"] if f["code"].startswith("closing-geometry")], doc["calibration"]
    assert json.loads((run["dir"] / "check.json").read_text())["notes"] == []
    fitted = {p["name"]: p["estimate"] for p in json.loads((run["dir"] / "id.json").read_text())["parameters"]}
    rot = so3_exp(np.array([fitted[f"tracker_r{a}"] for a in "xyz"]))
    origin = np.array([fitted[f"tracker_{a}"] for a in "xyz"])
    held = read_measurements(run["dir"] / "d.validation.csv", build_template(CORPUS_DIR / "delta_r.py").mechanism())
    point, _ = ControllerModel(doc).forward(held.q, held.metadata)
    rms = float(np.sqrt(np.mean(np.sum(((point - origin) @ rot - held.position) ** 2, axis=1))))
    recorded = doc["calibration"]["targets"]["target"]["validation"]["rms"]
    assert rms <= 1.5 * recorded, (rms, recorded)


def test_the_corpus_duration_is_reported(corpus, record_property):
    """Not a timing assertion: the corpus's outcomes and durations, for the record (wall and CPU seconds), printed
    after the run (``tests/conftest.py``: also from an xdist worker)."""
    by_member: dict = {}
    for (m, c), r in corpus["runs"].items():
        by_member.setdefault(m, []).append(f"{c} {r['code']}")
    slow = sorted(corpus["runs"].items(), key=lambda kv: -kv[1]["cpu"])[:5]
    lines = [f"corpus: {len(MEMBERS)} members, {len(corpus['runs'])} commands, {corpus['seconds']:.1f} s wall and "
             f"{corpus['cpu']:.1f} s CPU in the worker; most CPU: "
             + ", ".join(f"{m} {c} {r['cpu']:.1f} s" for (m, c), r in slow)]
    lines += [f"  {m}: " + ", ".join(outcomes) for m, outcomes in by_member.items()]
    lines += [f"  {m} {c}: {r['stderr'].strip().splitlines()[-1]}" for (m, c), r in corpus["runs"].items()
              if r["code"] != 0]
    record_property("record", "\n".join(lines))
    assert corpus["cpu"] > 0


def test_a_report_with_numbers_json_cannot_hold_still_renders(corpus):
    """A worst case that diverged or an optimiser tolerance that is unknown is ``null`` in report.json (JSON has
    no inf or NaN): both renderings print a word for it instead of failing (the TypeError the new user met)."""
    from hyperstat.cad_plugin.report import render_html, render_markdown

    doc = json.loads((corpus["runs"][("bennett", "report")]["dir"] / "rep" / "report.json").read_text())
    assert doc["worst_cases"], "the Bennett report has worst cases to spoil"
    w = doc["worst_cases"][0]
    w["optimiser_tolerance"], w["max"], w["sampled_max"] = None, None, None
    name = next(iter(doc["accuracy"]["coefficients"]))
    doc["accuracy"]["coefficients"][name]["max"] = None
    md, page = render_markdown(doc), render_html(doc, {})
    row = next(line for line in md.splitlines() if line.startswith(("| without calibration", "| after calibration")))
    assert "not finite" in row and "unknown" in row
    assert "not finite" in page and "unknown" in page
