"""The corpus's command runs: which members, which commands, and a worker that runs them.

Units: lengths in mm, angles in rad.

``python -m tests.templates.corpus_runner OUT MEMBER...`` runs every command on each member (the command
line's ``main``, as :func:`tests.conftest.run_cli` does) and appends one JSON line per command to
``OUT/outcomes.jsonl``: exit code, stdout, stderr, wall and CPU seconds.  The members are shared by
:data:`PROCESSES` processes (:func:`parts`: the revolute Delta, whose ``report`` and ``accuracy`` are about
half of the corpus' CPU, in one, the other members in the other), each writing its own
``OUT/outcomes.K.jsonl``; the lines are gathered into ``outcomes.jsonl`` in member order when all are done,
then ``OUT/done`` is written.  The test session starts it in the background when the corpus tests are
collected (``tests/templates/conftest.py``), so that it runs beside the rest of the suite;
``tests/templates/test_corpus.py`` reads the outcomes.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent
CORPUS_DIR = ROOT / "templates" / "corpus"
TEMPLATES = sorted(p.stem for p in CORPUS_DIR.glob("*.py") if not p.name.startswith("_"))
ROBOTS = ["puma560.dh.yaml", "panda.mdh.yaml", "iiwa14.urdf"]
MEMBERS = TEMPLATES + ROBOTS
THEORY = re.compile(r"Theory: mobility (\d+), degree of over-constraint (\d+), assembly conditions (\d+)\.")
#: command -> the outputs it writes (relative to the member's folder); checked absent when it refuses
OUTPUTS = {"build": ["model.json", "m.step", "m.step.json"], "import-robot": ["model.json"], "analyze": ["a.json"],
           "report": ["rep/report.html", "rep/report.md", "rep/report.json"], "accuracy": ["acc.json"],
           "montecarlo": ["mc.json"], "simulate": ["d.csv", "d.validation.csv", "t.json"], "identify": ["id.json"],
           "diagnose": ["dg.json"], "export-controller": ["m.json"], "check-controller": ["check.json"]}
#: (member, command) left out of the default run, and why: the revolute Delta's 47 assembly conditions make the
#: assembly-value search of report and accuracy take about ten CPU minutes (issue 39); everything else runs
LEFT_OUT: dict = {}  # (member, command) -> why it is not run; empty: every member through every command
#: processes the background run uses (one alone took 650 s of CPU, the longest single chain of ``make test``)
PROCESSES = 2
#: members whose commands take minutes (CPU seconds, clean-clone run of 2026-11-29: delta_r's report 170 s and
#: accuracy 158 s): each starts a process of its own, the rest share the last one
HEAVY = ("delta_r",)


def theory_of(member: str) -> tuple[int, int, int]:
    """The ``Theory:`` line of a member (docstring, YAML or XML comment): mobility, over-constraint, conditions."""
    found = THEORY.findall((CORPUS_DIR / (member if "." in member else f"{member}.py")).read_text(encoding="utf-8"))
    if len(found) != 1:
        raise ValueError(f"{member}: one 'Theory: ...' line expected, found {len(found)}")
    return tuple(int(v) for v in found[0])


def member_dir(root: Path, member: str) -> Path:
    return root / member.split(".")[0]


def commands(member: str, d: Path) -> list[list]:
    """The command lines a user would run on ``member``, in order, with small samples where a command has them."""
    if member in ROBOTS:
        src = d / "model.json"
        first = ["import-robot", CORPUS_DIR / member, "--out", src, "--quiet"]
    else:
        src = CORPUS_DIR / f"{member}.py"
        first = ["build", src, "--model", d / "model.json", "--step", d / "m.step", "--quiet"]
    data, val = d / "d.csv", d / "d.validation.csv"
    out = [first,
           ["analyze", src, "--json", d / "a.json", "--quiet"],
           ["report", src, "--out", d / "rep", "--quiet"],
           ["accuracy", src, "--json", d / "acc.json", "--no-refine", "--workspace-configurations", "200", "--quiet"],
           ["montecarlo", src, "--json", d / "mc.json", "--samples", "200", "--workspace-configurations", "100",
            "--quiet"],
           # the default campaign (107 poses, 30 held out): fewer poses make a poorer and slower identification
           ["simulate", src, "--out", data, "--truth", d / "t.json", "--quiet"],
           ["identify", src, data, "--validation", val, "--json", d / "id.json", "--quiet"],
           ["diagnose", src, data, "--validation", val, "--effects", "backlash,compliance", "--json", d / "dg.json",
            "--quiet"],
           ["export-controller", src, data, "--validation", val, "--out", d / "m.json", "--quiet"],
           ["check-controller", d / "m.json", "--source", src, "--json", d / "check.json", "--quiet"]]
    return [argv for argv in out if (member.split(".")[0], argv[0]) not in LEFT_OUT]


def cpu_seconds() -> float:
    """CPU seconds of this process and of its finished children (the report draws its views in a child)."""
    import resource

    return sum(resource.getrusage(who).ru_utime + resource.getrusage(who).ru_stime
               for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))


def parts(members: list[str], processes: int = PROCESSES) -> list[list[str]]:
    """The members split among ``processes`` lists: each of :data:`HEAVY` alone (while processes remain), the rest
    together in the last, every member exactly once and in its order."""
    heavy = [m for m in members if m.split(".")[0] in HEAVY][:max(processes - 1, 0)]
    rest = [m for m in members if m not in heavy]
    return [[m] for m in heavy] + ([rest] if rest else [])


def run_parallel(root: Path, members: list[str], processes: int = PROCESSES) -> None:
    """:func:`run` on :func:`parts` of ``members`` in as many processes; then ``outcomes.jsonl`` (member order) and
    ``done``.  A part that fails leaves no ``done`` (its log is in ``root / "part.K.log"``)."""
    groups = parts(members, processes)
    procs = []
    for k, group in enumerate(groups):
        with open(root / f"part.{k}.log", "w", encoding="utf-8") as log:
            procs.append(subprocess.Popen([sys.executable, "-m", "tests.templates.corpus_runner", "--part", str(k),
                                           str(root), *group], cwd=ROOT, stdout=log, stderr=subprocess.STDOUT))
    codes = [p.wait() for p in procs]
    if any(codes):
        raise SystemExit(f"corpus parts ended with {codes}: see {root}/part.K.log")
    lines = {}
    for k in range(len(groups)):
        for line in (root / f"outcomes.{k}.jsonl").read_text(encoding="utf-8").splitlines():
            lines.setdefault(json.loads(line)["member"], []).append(line)
    with open(root / "outcomes.jsonl", "a", encoding="utf-8") as fh:
        for member in members:
            fh.writelines(line + "\n" for line in lines.get(member, []))
    (root / "done").write_text("done\n", encoding="utf-8")


def run(root: Path, members: list[str], part: str | None = None) -> None:
    """Every command on every member, appended to ``root / "outcomes.jsonl"`` (``outcomes.PART.jsonl`` for a part
    of :func:`run_parallel`) as it ends; then ``done`` (a whole run only)."""
    from tests.conftest import run_cli

    log = root / ("outcomes.jsonl" if part is None else f"outcomes.{part}.jsonl")
    for member in members:
        d = member_dir(root, member)
        d.mkdir(parents=True, exist_ok=True)
        for argv in commands(member, d):
            t, c = time.perf_counter(), cpu_seconds()
            code, stdout, stderr = run_cli(argv)
            line = {"member": member, "command": argv[0], "code": code, "stdout": stdout[-20000:],
                    "stderr": stderr[-20000:], "seconds": time.perf_counter() - t, "cpu": cpu_seconds() - c}
            with open(log, "a", encoding="utf-8") as fh:
                fh.write(json.dumps(line) + "\n")
    if part is None:
        (root / "done").write_text("done\n", encoding="utf-8")


if __name__ == "__main__":  # pragma: no cover - the background worker
    if sys.argv[1] == "--part":
        run(Path(sys.argv[3]), sys.argv[4:], part=sys.argv[2])
    else:
        run_parallel(Path(sys.argv[1]), sys.argv[2:])
