"""The corpus's command runs: which members, which commands, and a worker that runs them.

Units: lengths in mm, angles in rad.

``python -m tests.templates.corpus_runner OUT MEMBER...`` runs every command on each member in this one
process (the command line's ``main``, as :func:`tests.conftest.run_cli` does) and appends one JSON line per
command to ``OUT/outcomes.jsonl``: exit code, stdout, stderr, wall and CPU seconds.  The test session starts
it in the background when the corpus tests are collected (``tests/templates/conftest.py``), so that it runs
on the second core while the rest of the suite runs; ``tests/templates/test_corpus.py`` reads the outcomes.
"""

from __future__ import annotations

import json
import re
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


def run(root: Path, members: list[str]) -> None:
    """Every command on every member, appended to ``root / "outcomes.jsonl"`` as it ends."""
    from tests.conftest import run_cli

    log = root / "outcomes.jsonl"
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
    (root / "done").write_text("done\n", encoding="utf-8")


if __name__ == "__main__":  # pragma: no cover - the background worker
    run(Path(sys.argv[1]), sys.argv[2:])
