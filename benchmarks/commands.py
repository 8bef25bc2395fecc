"""Whole-command benchmarks: each command in a new process, as a user runs it (units: seconds).

``benchmarks/run.py`` times the kernels inside one warm process; this script times what a
user waits for: imports, loading the template, the stationarity analysis, sampling,
threads and writing the output included.  Every command runs ``--repeat`` times in a
fresh ``python -m hyperstat.cad_plugin.cli`` process (the ``hyperstat`` console script
runs the same entry point); the table gives the median and the range of the wall-clock
time, the median CPU time (user + system of the child) and the load average of the
machine before the runs, because on a shared machine the wall-clock time depends on
what else runs.

``make demo`` is timed as the commands of its recipe, read from the Makefile (the
``setup`` prerequisite, which only checks the installed venv, is left out).  The data of
the report and of the diagnosis come from ``hyperstat simulate`` run once before the timed
runs.  The commands run as an installed ``hyperstat`` does: compiled bytecode is allowed
(``PYTHONDONTWRITEBYTECODE`` is removed from their environment) and one untimed run of
``hyperstat --version`` before the table writes it, so that "cold" means a new process with
its imports, not a first compilation of the sources.

Rows: the four goals of issue 24 (accuracy over 100,000 Triflex-II configurations, Monte
Carlo with 100,000 samples, the Tripteor report with data, ``make demo``), ``hyperstat
analyze`` on every bundled template (two independent samples, the default) and ``hyperstat
diagnose`` on the Tripteor (goal of issue 20: 5 s).

Usage (the whole table, 3 runs per row: about 6 minutes of CPU on 2 idle cores)::

    .venv/bin/python benchmarks/commands.py [--repeat 3] [--markdown out/commands.md] [--only accuracy]
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CLI = [sys.executable, "-m", "hyperstat.cad_plugin.cli"]

#: the bundled templates timed by ``hyperstat analyze`` (the Makefile's TEMPLATE_NAMES)
TEMPLATES = ("slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod", "five_bar")

#: name -> (goal in s or None, description); the goals of issue 24 (and issue 20 for diagnose)
GOALS = {
    "accuracy": (5.0, "hyperstat accuracy, Triflex-II, 100,000 configurations (refined worst cases)"),
    "montecarlo": (5.0, "hyperstat montecarlo, Triflex-II, 100,000 samples"),
    "report": (8.0, "hyperstat report, Tripteor X7 with data, cold"),
    "demo": (15.0, "make demo after set-up (simulate + report + export-controller)"),
    "diagnose": (5.0, "hyperstat diagnose, Tripteor X7, 107 + 30 points"),
    **{f"analyze-{t}": (None, f"hyperstat analyze templates/{t}.py (2 samples)") for t in TEMPLATES},
}

#: the environment of the timed commands: bytecode written and read, as in an installed package
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def _demo_commands(out: Path) -> list[list[str]]:
    """The recipe of ``make demo`` with ``$(VENV)/bin/hyperstat`` -> this Python's CLI, ``out/demo`` -> ``out``."""
    text = (ROOT / "Makefile").read_text()
    recipe = re.search(r"^demo:.*\n((?:\t.*\n|.*\\\n)+)", text, re.M)
    if recipe is None:
        raise SystemExit("Makefile: no 'demo' recipe found.")
    lines = recipe.group(1).replace("\\\n", " ").splitlines()
    cmds = []
    for line in lines:
        line = line.strip()
        if not line.startswith("$(VENV)/bin/hyperstat"):
            continue
        words = shlex.split(line.replace("$(VENV)/bin/hyperstat", "").replace("out/demo", str(out)))
        cmds.append(CLI + words)
    return cmds


def _commands(work: Path) -> dict:
    t = ROOT / "templates"
    data = work / "data"
    return {
        "accuracy": [CLI + ["accuracy", str(t / "triflex_ii.py"), "--workspace-configurations", "100000",
                            "--orientation-accuracy", "0.026180", "--json", str(work / "accuracy.json"), "--quiet"]],
        "montecarlo": [CLI + ["montecarlo", str(t / "triflex_ii.py"), "--samples", "100000",
                              "--json", str(work / "montecarlo.json"), "--quiet"]],
        "report": [CLI + ["report", str(t / "tripteor_x7.py"), "--data", str(data / "measurements.csv"),
                          "--validation", str(data / "measurements.validation.csv"),
                          "--hypotheses", str(t / "tripteor_x7.hypotheses.yaml"), "--out", str(work / "report")]],
        "demo": _demo_commands(work / "demo"),
        "diagnose": [CLI + ["diagnose", str(t / "tripteor_x7.py"), str(data / "measurements.csv"),
                            "--validation", str(data / "measurements.validation.csv"), "--quiet"]],
        **{f"analyze-{n}": [CLI + ["analyze", str(t / f"{n}.py"), "--quiet"]] for n in TEMPLATES},
    }


def _run(cmds: list[list[str]]) -> tuple[float, float]:
    """Wall-clock and child CPU time (s) of running ``cmds`` one after the other."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    for cmd in cmds:
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=ENV)
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--markdown", metavar="FILE")
    ap.add_argument("--only", action="append", choices=list(GOALS))
    args = ap.parse_args(argv)
    names = args.only or list(GOALS)
    rows = []
    started = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="hyperstat-bench-") as tmp:
        work = Path(tmp)
        cmds = _commands(work)
        (work / "demo").mkdir()  # the recipe's 'mkdir -p out/demo'
        _run([CLI + ["--version"]])  # writes the bytecode, as an installation has it (not timed)
        if {"report", "diagnose"} & set(names):  # the data of the report and the diagnosis, once, not timed
            (work / "data").mkdir()
            _run([CLI + ["simulate", str(ROOT / "templates" / "tripteor_x7.py"), "--effect", "backlash",
                         "--out", str(work / "data" / "measurements.csv"), "--truth", str(work / "data" / "truth.json"),
                         "--quiet"]])
        for name in names:
            load = os.getloadavg()[0]
            walls, cpus = [], []
            for _ in range(args.repeat):
                wall, cpu = _run(cmds[name])
                walls.append(wall)
                cpus.append(cpu)
            goal, what = GOALS[name]
            med = statistics.median(walls)
            rows.append((what, med, min(walls), max(walls), statistics.median(cpus), load, goal))
            verdict = "" if goal is None else f", goal < {goal:g} s: {'met' if med < goal else 'NOT met'}"
            print(f"{what}: median {med:.2f} s (range {min(walls):.2f}-{max(walls):.2f}), CPU "
                  f"{statistics.median(cpus):.2f} s, load {load:.1f}{verdict}", flush=True)
    cores = os.cpu_count()
    total = time.perf_counter() - started
    lines = [f"Whole commands, new process each, median of {args.repeat} (wall-clock s); {cores} cores; "
             "load = 1-minute load average before the runs; CPU = user + system of the command and its "
             f"children (median). Generated by `python benchmarks/commands.py` in {total:.0f} s.", "",
             "| command | median (s) | range (s) | CPU user+sys (s) | load | goal (s) | |",
             "|---|---|---|---|---|---|---|"]
    for what, med, lo, hi, cpu, load, goal in rows:
        met = "" if goal is None else ("met" if med < goal else "not met")
        lines.append(f"| {what} | {med:.2f} | {lo:.2f}-{hi:.2f} | {cpu:.2f} | {load:.1f} | "
                     f"{'-' if goal is None else f'< {goal:g}'} | {met} |")
    table = "\n".join(lines) + "\n"
    print(table)
    if args.markdown:
        Path(args.markdown).parent.mkdir(parents=True, exist_ok=True)
        Path(args.markdown).write_text(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
