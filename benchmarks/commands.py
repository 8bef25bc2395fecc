"""Whole-command benchmarks beside their kernels: each command in a new process, as a user runs it.

Units: seconds (s) of wall-clock and of CPU time (user + system), MiB of peak resident memory.

``benchmarks/run.py`` times the kernels inside one warm process; this script times what a
user waits for: imports, loading the template, the stationarity analysis, sampling,
threads and writing the output included.  Every command runs ``--repeat`` times in a
fresh ``python -m hyperstat.cad_plugin.cli`` process (the ``hyperstat`` console script
runs the same entry point); the table gives the median and the range of the wall-clock
time, the median CPU time and the peak resident memory of the command (``os.wait4`` of its
process), and the load average of the machine before the runs, because on a shared machine
the wall-clock time depends on what else runs.

**Kernels.**  Beside every command, in the same run and right after it (so under the same
load), a new process times the batched kernels the command is built on, warm (imports,
set-up and one warm-up run excluded; median of ``--repeat``), and the table gives the ratio
command / kernel for the wall-clock and the CPU time:

* ``accuracy`` over ``K`` workspace configurations: the closure Jacobian of every draw and
  the inverse of its passive block (the floor of a certificate that costs one Jacobian),
  then the accuracy maps with the task rows of the tolerance values (one set of Jacobians
  per certified configuration); the configurations are a certified sample of 2,000 repeated
  to the command's sizes (the cost does not depend on which configurations);
* ``montecarlo``: the two Monte Carlo re-assemblies the command runs (as built, and
  calibrated), 100,000 samples each;
* ``analyze``: the stationarity analysis with two samples (the command's default);
* ``report`` and ``diagnose``: the same command run a second time in one process (what is
  left without imports and first-call costs); ``make demo`` (three commands) has none.

**Scaling.**  ``accuracy`` runs over 10,000, 100,000 and 1,000,000 configurations (rows
``accuracy-10k``, ``accuracy``, ``accuracy-1m``; the last once whatever ``--repeat``).

**Issue 39.**  Every row carries the goal of issue 39 where it names one (``GOALS``; a goal on CPU
time for the hexapod's ``accuracy``, memory goals for the 100,000 and 1,000,000 rows: the latter's
"independent of the count" is read as a peak within 10 % of the 100,000 row's, measured in the same
run).  Every timed run starts with an **empty cache of results** (:mod:`hyperstat.solver.cache`, a folder of the run):
"cold" is a first run of the model.  The ``report-cached`` row times the same report after one
untimed run filled the cache (what the user waits for the second time); the ``report-changed`` row, the report
with one dimension changed (``-p depth=810``) after an untimed run of the template as it is (the design loop:
change a parameter, wait for the answer, with the cache the previous value left).  The ``freecad`` row
installs the workbench into a temporary ``HOME`` with the real installer and runs
``benchmarks/freecad_insert_analyse.py`` in ``freecadcmd``: *Insert template* (Tripteor X7) and
*Analyse*, as the workbench's functions run them (FreeCAD's own start is not counted; the CPU and
memory columns are the whole ``freecadcmd`` process with its ``hyperstat`` children).

``make demo`` is timed as the commands of its recipe, read from the Makefile (the
``setup`` prerequisite, which only checks the installed venv, is left out).  The data of
the report and of the diagnosis come from ``hyperstat simulate`` run once before the timed
runs.  The commands run as an installed ``hyperstat`` does: compiled bytecode is allowed
(``PYTHONDONTWRITEBYTECODE`` is removed from their environment) and one untimed run of
``hyperstat --version`` before the table writes it, so that "cold" means a new process with
its imports, not a first compilation of the sources.

Usage (the whole table: about 15 minutes of CPU on 2 idle cores)::

    .venv/bin/python benchmarks/commands.py [--repeat 3] [--markdown out/commands.md] [--only accuracy]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import shutil
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

#: the sizes of the ``accuracy`` rows (configurations drawn over the Triflex-II's workspace)
ACCURACY_SIZES = {"accuracy-10k": 10_000, "accuracy": 100_000, "accuracy-1m": 1_000_000}

#: name -> (goal in s or None, peak-memory goal in MiB or None, description); the goals of issue 39 (and of
#: issues 20, 24 and 32 for the rows it does not name).  A goal on CPU time is written as a string "cpu:<s>"; a
#: memory goal ``(MiB, row)`` also asks for a peak within :data:`SAME_MEMORY` of that row's peak (ten times the
#: configurations in the same memory: "independent of the count") when both rows run.
GOALS = {
    "report": (4.0, None, "hyperstat report, Tripteor X7 with data, cold (empty cache)"),
    "report-cached": (None, None, "hyperstat report, Tripteor X7 with data, the cache filled by one run before"),
    "report-changed": (None, None, "hyperstat report, Tripteor X7 with data, depth 800 -> 810 mm after one run at 800 "
                                   "(the design loop: the cache filled by the previous value)"),
    "demo": (8.0, None, "make demo after set-up (simulate + report + export-controller), empty cache"),
    "accuracy": (5.0, 300.0, "hyperstat accuracy, Triflex-II, 100,000 configurations (refined worst cases)"),
    "accuracy-1m": (40.0, (300.0, "accuracy"), "hyperstat accuracy, Triflex-II, 1,000,000 configurations (memory: "
                                               "independent of the count: the 100,000 row's goal, and within 10 % of "
                                               "that row's peak when both run)"),
    "accuracy-hexapod": ("cpu:10", None, "hyperstat accuracy, hexapod, default sample (2,000 draws)"),
    "freecad": (10.0, None, "FreeCAD: insert the Tripteor X7 template + Analyse (workbench, freecadcmd; "
                            "FreeCAD's start not counted), empty cache"),
    "accuracy-10k": (None, None, "hyperstat accuracy, Triflex-II, 10,000 configurations"),
    "montecarlo": (5.0, None, "hyperstat montecarlo, Triflex-II, 100,000 samples"),
    "diagnose": (5.0, None, "hyperstat diagnose, Tripteor X7, 107 + 30 points"),
    "report-delta_r": (None, None, "hyperstat report, the corpus' revolute Delta (47 assembly conditions), cold"),
    "report-planar_3rrr": (None, None, "hyperstat report, planar 3-RRR template (21 assembly conditions, the values "
                                       "together by linear programmes), cold"),
    **{f"analyze-{t}": (None, None, f"hyperstat analyze templates/{t}.py (2 samples)") for t in TEMPLATES},
}

#: the environment of the timed commands: bytecode written and read, as in an installed package; the cache of
#: results (hyperstat.solver.cache) in a folder of the run, emptied before every timed run but the PRIMED rows'
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


def _arguments(work: Path) -> dict:
    """Name -> the ``hyperstat`` arguments of each timed command (``demo``: a list of them)."""
    t = ROOT / "templates"
    data = work / "data"
    out = {f"analyze-{n}": ["analyze", str(t / f"{n}.py"), "--quiet"] for n in TEMPLATES}
    for name, k in ACCURACY_SIZES.items():
        out[name] = ["accuracy", str(t / "triflex_ii.py"), "--workspace-configurations", str(k),
                     "--orientation-accuracy", "0.026180", "--json", str(work / f"{name}.json"), "--quiet"]
    out["accuracy-hexapod"] = ["accuracy", str(t / "hexapod.py"), "--json", str(work / "accuracy-hexapod.json"),
                               "--quiet"]
    out.update({
        "montecarlo": ["montecarlo", str(t / "triflex_ii.py"), "--samples", "100000",
                       "--json", str(work / "montecarlo.json"), "--quiet"],
        "report": ["report", str(t / "tripteor_x7.py"), "--data", str(data / "measurements.csv"),
                   "--validation", str(data / "measurements.validation.csv"),
                   "--hypotheses", str(t / "tripteor_x7.hypotheses.yaml"), "--out", str(work / "report")],
        "report-delta_r": ["report", str(t / "corpus" / "delta_r.py"), "--out", str(work / "report-delta_r"), "--quiet"],
        "report-planar_3rrr": ["report", str(t / "planar_3rrr.py"), "--out", str(work / "report-planar_3rrr"),
                               "--quiet"],
        "diagnose": ["diagnose", str(t / "tripteor_x7.py"), str(data / "measurements.csv"),
                     "--validation", str(data / "measurements.validation.csv"), "--quiet"],
    })
    return out


def _commands(work: Path) -> dict:
    cmds = {name: [CLI + args] for name, args in _arguments(work).items()}
    cmds["report-cached"] = cmds["report"]
    changed = list(cmds["report"][0])
    at = changed.index("report") + 2  # after the template
    changed[at:at] = ["-p", "depth=810"]
    cmds["report-changed"] = [changed]
    cmds["demo"] = _demo_commands(work / "demo")
    return cmds


def _empty(folder: Path) -> None:
    """Empty the cache folder of the timed commands (a cold run computes everything)."""
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)


def _run(cmds: list[list[str]], env: dict | None = None) -> tuple[float, float, float]:
    """Wall-clock time, CPU time (s) and the largest peak resident memory (MiB) of ``cmds`` run one after the other.

    Each process is waited for with ``os.wait4``, which gives its own CPU time (its children's
    included) and its own maximum resident set.
    """
    t0 = time.perf_counter()
    cpu, peak = 0.0, 0.0
    for cmd in cmds:
        proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env or ENV)
        stderr = proc.stderr.read().decode(errors="replace")
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{stderr[-2000:]}")
        cpu += usage.ru_utime + usage.ru_stime
        peak = max(peak, usage.ru_maxrss / 1024)
    return time.perf_counter() - t0, cpu, peak


# ---------------------------------------------------------------------------- kernels (in a child process)
def _timed(fn, repeat: int) -> tuple[float, float]:
    """Median wall-clock and CPU time (s) of ``fn()`` after one warm-up run."""
    fn()
    walls, cpus = [], []
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    return statistics.median(walls), statistics.median(cpus)


def _triflex_sample(n: int):
    """The Triflex-II, its kinematics and ``n`` certified configurations (a sample of 2,000 repeated)."""
    import warnings

    import numpy as np

    from hyperstat.cad_plugin.templates import TEMPLATE_DIR, build_template
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.tolerances.accuracy import sample_workspace

    mech = build_template(TEMPLATE_DIR / "triflex_ii.py").mechanism()
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        base = sample_workspace(mech, 3000, seed=0, kinematics=kin)[:2000]
    return mech, kin, base[np.arange(n) % len(base)]


def _accuracy_kernel(draws: int, certified: int):
    """One closure Jacobian and passive inverse per draw, then the maps and task rows of the certified configurations."""
    import numpy as np

    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.tolerances.accuracy import accuracy_maps, in_chunks
    from hyperstat.solver.tolerances.classification import classify

    mech, kin, q = _triflex_sample(max(draws, certified))
    result = analyze(mech, kinematics=kin)
    cl = classify(mech, result, kin)
    dirs = np.stack([t.direction for t in cl.items if t.cls in ("accuracy-critical", "compensable")], axis=1)
    pas = mech.passive

    def jacobians(start: int) -> None:
        b = kin.evaluate(q[start:start + 2048], None, "joints").closure_q
        np.linalg.inv(kin.dimensionless(b[:, :, pas], kin.joint_scale[pas]))

    def kernel() -> None:
        in_chunks(jacobians, draws, 2048)
        accuracy_maps(mech, q[:certified], None, kinematics=kin, task=cl.declaration.task, task_directions=dirs)

    return kernel


def _montecarlo_kernel():
    """The two re-assemblies of ``hyperstat montecarlo`` (every tolerance, then the accuracy-critical ones)."""
    import warnings

    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.tolerances.classification import classify
    from hyperstat.solver.tolerances.montecarlo import monte_carlo
    from hyperstat.solver.tolerances.values import assign_values

    import numpy as np

    from hyperstat.solver.tolerances.accuracy import sample_workspace

    mech, kin, _ = _triflex_sample(0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        q = sample_workspace(mech, 2000, seed=0, kinematics=kin)  # the command's sample (its default size)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cl = classify(mech, analyze(mech, kinematics=kin), kin)
        assign_values(cl, mech, kin, q, assembly=False)
    runs = []
    for keep in (("accuracy-critical", "compensable"), ("accuracy-critical",)):
        drawn = [t for t in cl.items if t.cls in keep and t.value]
        if drawn:
            runs.append(({t.id: float(t.value) for t in drawn},
                         ([t.id for t in drawn], np.stack([t.direction for t in drawn], axis=1), [t.unit for t in drawn])))

    def kernel() -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for tol, directions in runs:
                monte_carlo(mech, q, tol, 100_000, "uniform", 0, kinematics=kin, directions=directions,
                            task=cl.declaration.task)

    return kernel


def _analyze_kernel(template: str):
    from hyperstat.cad_plugin.templates import TEMPLATE_DIR, build_template
    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.kinematics.closure import Kinematics

    mech = build_template(TEMPLATE_DIR / f"{template}.py").mechanism()
    return lambda: analyze(mech, kinematics=Kinematics(mech))


def _warm_command(args: list[str]):
    """The command run again in this process (imports and first-call costs excluded)."""
    from hyperstat.cad_plugin.cli import main

    return lambda: main(list(args))


def kernel_child(name: str, repeat: int, work: Path, draws: int, certified: int) -> None:
    """Print ``{"wall": s, "cpu": s}`` of the kernel of ``name`` (run in a new process by :func:`_kernel`)."""
    import contextlib
    import io
    import warnings

    warnings.simplefilter("ignore")
    if name in ACCURACY_SIZES:
        fn = _accuracy_kernel(draws, certified)
    elif name == "montecarlo":
        fn = _montecarlo_kernel()
    elif name.startswith("analyze-"):
        fn = _analyze_kernel(name.split("-", 1)[1])
    else:
        fn = _warm_command(_arguments(work)[name])
    with contextlib.redirect_stdout(io.StringIO()):
        wall, cpu = _timed(fn, repeat)
    print(json.dumps({"wall": wall, "cpu": cpu}))


def _kernel(name: str, repeat: int, work: Path) -> tuple[float, float] | None:
    """Wall-clock and CPU time (s) of the kernel of ``name``, timed in a new process; None for ``demo``."""
    if name == "demo":
        return None
    draws = certified = 0
    if name in ACCURACY_SIZES:
        draws = ACCURACY_SIZES[name]
        certified = json.loads((work / f"{name}.json").read_text())["configurations"]
    cmd = [sys.executable, str(Path(__file__).resolve()), "--kernel-of", name, "--repeat", str(repeat), "--work",
           str(work), "--draws", str(draws), "--certified", str(certified)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=ENV)
    if proc.returncode != 0:
        raise SystemExit(f"kernel of {name} failed:\n{proc.stderr[-2000:]}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    return out["wall"], out["cpu"]


# ---------------------------------------------------------------------------- table
def _ratio(a: float, b: float | None) -> str:
    return "-" if not b else f"{a / b:.1f}x"


#: a peak within this factor of another row's peak is "the same memory" (a memory goal ``(MiB, row)``)
SAME_MEMORY = 1.10


def _goal_text(goal, mem_goal) -> list[str]:
    out = []
    if isinstance(goal, str):
        out.append(f"< {goal.split(':')[1]} s CPU")
    elif goal is not None:
        out.append(f"< {goal:g} s")
    if isinstance(mem_goal, tuple):
        out.append(f"< {mem_goal[0]:g} MiB")
        out.append(f"peak <= {SAME_MEMORY:g} x the '{mem_goal[1]}' row's")
    elif mem_goal is not None:
        out.append(f"< {mem_goal:g} MiB")
    return out


def _verdicts(goal, mem_goal, med: float, cpu: float, peak: float, peaks: dict | None = None) -> list[str]:
    """'met' / 'not met' per goal of :func:`_goal_text`; ``peaks``: row name -> peak (MiB) of this run's rows."""
    out = []
    if isinstance(goal, str):
        out.append("met" if cpu < float(goal.split(":")[1]) else "not met")
    elif goal is not None:
        out.append("met" if med < goal else "not met")
    if isinstance(mem_goal, tuple):
        out.append("met" if peak < mem_goal[0] else "not met")
        other = (peaks or {}).get(mem_goal[1])
        out.append("not measured (the row was not run)" if other is None else
                   f"{'met' if peak <= SAME_MEMORY * other else 'not met'} ({peak:.0f} / {other:.0f} MiB)")
    elif mem_goal is not None:
        out.append("met" if peak < mem_goal else "not met")
    return out


#: rows without a kernel row (the kernels of issue 32 exist for the rows before issue 39)
NO_KERNEL = {"demo", "report-cached", "report-changed", "accuracy-hexapod", "freecad", "report-delta_r",
             "report-planar_3rrr"}
#: rows timed after an untimed run of another row's command in the same cache (the cache it leaves is the row's start)
PRIMED = {"report-cached": "report", "report-changed": "report"}


def _freecad_setup(work: Path) -> dict | None:
    """A HOME with the workbench installed by the real installer, and the environment of ``freecadcmd``; None
    without FreeCAD."""
    exe = shutil.which("freecadcmd")
    if exe is None:
        return None
    home = work / "fc_home"
    home.mkdir()
    env = {**ENV, "HOME": str(home)}
    env.pop("HYPERSTAT_CLI", None)
    cli = Path(sys.executable).parent / "hyperstat"
    proc = subprocess.run([sys.executable, str(ROOT / "cad_plugin" / "freecad" / "install.py"), "--freecadcmd", exe,
                           "--cli", str(cli)], capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise SystemExit(f"the workbench could not be installed for the FreeCAD row:\n{proc.stderr[-2000:]}")
    return {"exe": exe, "env": env}


def _run_freecad(setup: dict, work: Path) -> tuple[float, float, float]:
    """Insert + Analyse in ``freecadcmd`` (:mod:`benchmarks.freecad_insert_analyse`): their seconds, the CPU time and
    the peak memory of the whole FreeCAD process (its start included, and its hyperstat children)."""
    out = work / "freecad.json"
    env = {**setup["env"], "HYPERSTAT_BENCH_OUT": str(out)}
    proc = subprocess.Popen([setup["exe"], str(ROOT / "benchmarks" / "freecad_insert_analyse.py")], cwd=work,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    stderr = proc.stderr.read().decode(errors="replace")
    _, status, usage = os.wait4(proc.pid, 0)
    doc = json.loads(out.read_text()) if out.exists() else {"error": stderr[-2000:]}
    if os.waitstatus_to_exitcode(status) != 0 or "error" in doc:
        raise SystemExit(f"the FreeCAD row failed:\n{doc.get('error', stderr[-2000:])}")
    return doc["insert_s"] + doc["analyse_s"], usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--markdown", metavar="FILE")
    ap.add_argument("--only", action="append", choices=list(GOALS))
    ap.add_argument("--kernel-of", help=argparse.SUPPRESS)  # the child process that times one kernel
    ap.add_argument("--work", help=argparse.SUPPRESS)
    ap.add_argument("--no-kernels", action="store_true",
                    help="time the commands only (the kernel rows double a report's time: on a shared machine)")
    ap.add_argument("--draws", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--certified", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.kernel_of:
        kernel_child(args.kernel_of, args.repeat, Path(args.work), args.draws, args.certified)
        return 0
    names = [n for n in GOALS if n in args.only] if args.only else list(GOALS)  # a compared row after its reference
    rows = []
    peak_of: dict = {}  # row name -> its peak (MiB), for the memory goals that compare two rows
    started = time.perf_counter()
    loads = [os.getloadavg()[0]]
    with tempfile.TemporaryDirectory(prefix="hyperstat-bench-") as tmp:
        work = Path(tmp)
        cache = work / "cache"
        ENV["HYPERSTAT_CACHE"] = str(cache)
        cmds = _commands(work)
        (work / "demo").mkdir()  # the recipe's 'mkdir -p out/demo'
        _run([CLI + ["--version"]])  # writes the bytecode, as an installation has it (not timed)
        if {"report", "report-cached", "report-changed", "diagnose", "demo"} & set(names):  # the data, once, not timed
            (work / "data").mkdir()
            _run([CLI + ["simulate", str(ROOT / "templates" / "tripteor_x7.py"), "--effect", "backlash",
                         "--out", str(work / "data" / "measurements.csv"), "--truth", str(work / "data" / "truth.json"),
                         "--quiet"]])
        fc = _freecad_setup(work) if "freecad" in names else None
        for name in names:
            if name == "freecad" and fc is None:
                print("FreeCAD row: freecadcmd not found (Debian freecad-python3), left out", flush=True)
                continue
            load = os.getloadavg()[0]
            loads.append(load)
            repeat = 1 if name == "accuracy-1m" else args.repeat
            runs = []
            for _ in range(repeat):
                _empty(cache)
                if name in PRIMED:
                    _run(cmds[PRIMED[name]])  # fills the cache (not timed)
                runs.append(_run_freecad(fc, work) if name == "freecad" else _run(cmds[name]))
            walls, cpus, peaks = ([r[i] for r in runs] for i in range(3))
            kernel = None if name in NO_KERNEL or args.no_kernels else _kernel(name, repeat, work)
            goal, mem_goal, what = GOALS[name]
            med, cpu = statistics.median(walls), statistics.median(cpus)
            rows.append((what, med, min(walls), max(walls), cpu, max(peaks), load, kernel, goal, mem_goal))
            peak_of[name] = max(peaks)
            verdict = ", ".join(f"goal {g}: {v}" for g, v in zip(_goal_text(goal, mem_goal),
                                                                   _verdicts(goal, mem_goal, med, cpu, max(peaks),
                                                                             peak_of)))
            kern = "" if kernel is None else (f"; kernel {kernel[0]:.2f} s wall, {kernel[1]:.2f} s CPU (ratios "
                                              f"{_ratio(med, kernel[0])}, {_ratio(cpu, kernel[1])})")
            print(f"{what}: median {med:.2f} s (range {min(walls):.2f}-{max(walls):.2f}), CPU {cpu:.2f} s, peak "
                  f"{max(peaks):.0f} MiB, load {load:.1f}{kern}{', ' + verdict if verdict else ''}", flush=True)
    loads.append(os.getloadavg()[0])
    cores = os.cpu_count()
    total = time.perf_counter() - started
    lines = [f"Whole commands, new process each, median of {args.repeat} (the 1,000,000 row: one run); {cores} cores; "
             f"load = 1-minute load average before the row (the run: {min(loads):.1f}-{max(loads):.1f}); CPU = user + "
             "system of the command and its children (median); peak = largest resident memory of the command's "
             "process; every run starts with an empty cache of results except the '-cached' and '-changed' rows "
             "(one untimed run before); kernel = the "
             "batched kernels the command is built on, warm, in a new process right after the command (median; see "
             f"the script), and the ratios command / kernel. Generated by `python benchmarks/commands.py` in "
             f"{total:.0f} s.", "",
             "| command | median (s) | range (s) | CPU (s) | peak (MiB) | load | kernel wall / CPU (s) | "
             "ratio wall | ratio CPU | goal | |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for what, med, lo, hi, cpu, peak, load, kernel, goal, mem_goal in rows:
        kern = "-" if kernel is None else f"{kernel[0]:.2f} / {kernel[1]:.2f}"
        lines.append(f"| {what} | {med:.2f} | {lo:.2f}-{hi:.2f} | {cpu:.2f} | {peak:.0f} | {load:.1f} | {kern} | "
                     f"{_ratio(med, kernel and kernel[0])} | {_ratio(cpu, kernel and kernel[1])} | "
                     f"{', '.join(_goal_text(goal, mem_goal)) or '-'} | "
                     f"{', '.join(_verdicts(goal, mem_goal, med, cpu, peak, peak_of))} |")
    table = "\n".join(lines) + "\n"
    print(table)
    if args.markdown:
        Path(args.markdown).parent.mkdir(parents=True, exist_ok=True)
        tmp_md = Path(args.markdown).with_suffix(".md.tmp")
        tmp_md.write_text(table)
        tmp_md.replace(args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
