"""The JSON outputs of the timed commands, written to a folder, and two such folders compared to 1e-9.

Units: whatever each JSON states (mm, rad); the comparison is relative (``|a - b| <= 1e-9 max(1, |a|, |b|)``).

A speed change must not change an answer: this script runs the commands of
``benchmarks/commands.py`` (and a few more: the hexapod's ``accuracy``, the controller export, the
report (``--json-only``) and ``accuracy`` of the slider-crank and the planar 3-RRR, the Tripteor's
``accuracy``; with ``--with-corpus`` the report and ``accuracy`` of the corpus' revolute Delta, minutes of CPU)
once each, with the cache off (``--no-cache``, so that every value is computed), and keeps
their JSON outputs; ``--compare A B`` then lists every number that differs by more than 1e-9
(relative) and every key present in one only.  The reference is made by running the same
script with the code before the change first on ``PYTHONPATH``::

    git archive BASE | tar -x -C /tmp/base/hyperstat
    PYTHONPATH=/tmp/base .venv/bin/python benchmarks/json_outputs.py --out /tmp/json-base
    .venv/bin/python benchmarks/json_outputs.py --out /tmp/json-new
    .venv/bin/python benchmarks/json_outputs.py --compare /tmp/json-base /tmp/json-new

Keys that hold the run's own circumstances (version, date, timings, absolute paths of the
temporary folder) are left out of the comparison (:data:`IGNORED`).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CLI = [sys.executable, "-m", "hyperstat.cad_plugin.cli"]
#: keys whose values depend on the run, not on the answer
IGNORED = {"hyperstat_version", "date", "elapsed_s", "generated", "created", "cache", "time_s"}


def _commands(work: Path, data: Path, sizes: bool, corpus: bool = False) -> dict:
    """Name -> (arguments, the JSON file(s) they write)."""
    t = ROOT / "templates"
    out = {
        "accuracy-10k": (["accuracy", t / "triflex_ii.py", "--workspace-configurations", "10000",
                          "--orientation-accuracy", "0.026180", "--json", work / "accuracy-10k.json"],
                         ["accuracy-10k.json"]),
        "accuracy-hexapod": (["accuracy", t / "hexapod.py", "--json", work / "accuracy-hexapod.json"],
                             ["accuracy-hexapod.json"]),
        "montecarlo": (["montecarlo", t / "triflex_ii.py", "--samples", "100000", "--json", work / "montecarlo.json"],
                       ["montecarlo.json"]),
        "report": (["report", t / "tripteor_x7.py", "--data", data / "measurements.csv", "--validation",
                    data / "measurements.validation.csv", "--hypotheses", t / "tripteor_x7.hypotheses.yaml",
                    "--out", work / "report", "--date", "2026-01-01"], ["report/report.json"]),
        "report-hexapod": (["report", t / "hexapod.py", "--out", work / "report-hexapod", "--date", "2026-01-01"],
                           ["report-hexapod/report.json"]),
        "diagnose": (["diagnose", t / "tripteor_x7.py", data / "measurements.csv", "--validation",
                      data / "measurements.validation.csv", "--json", work / "diagnose.json"], ["diagnose.json"]),
        "export-controller": (["export-controller", t / "tripteor_x7.py", data / "measurements.csv", "--validation",
                               data / "measurements.validation.csv", "--diagnose", "--out", work / "machine.json"],
                              ["machine.json"]),
    }
    for name in ("slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod", "five_bar"):
        out[f"analyze-{name}"] = (["analyze", t / f"{name}.py", "--json", work / f"analyze-{name}.json"],
                                  [f"analyze-{name}.json"])
    # the searched worst cases, allocations, bounds and drawings of more mechanisms (issue 39: the values stage)
    for name in ("slider_crank", "planar_3rrr", "triflex_ii", "scara", "five_bar"):
        out[f"report-{name}"] = (["report", t / f"{name}.py", "--out", work / f"report-{name}", "--date", "2026-01-01",
                                  "--json-only"], [f"report-{name}/report.json"])
    for name in ("slider_crank", "tripteor_x7", "planar_3rrr", "triflex_ii", "scara", "five_bar"):
        out[f"accuracy-{name}"] = (["accuracy", t / f"{name}.py", "--json", work / f"accuracy-{name}.json"],
                                   [f"accuracy-{name}.json"])
    if corpus:  # the revolute Delta of the corpus (47 assembly conditions): minutes of CPU
        c = t / "corpus" / "delta_r.py"
        out["report-delta_r"] = (["report", c, "--out", work / "report-delta_r", "--date", "2026-01-01", "--json-only"],
                                 ["report-delta_r/report.json"])
        out["accuracy-delta_r"] = (["accuracy", c, "--json", work / "accuracy-delta_r.json"], ["accuracy-delta_r.json"])
    if sizes:
        out["accuracy"] = (["accuracy", t / "triflex_ii.py", "--workspace-configurations", "100000",
                            "--orientation-accuracy", "0.026180", "--json", work / "accuracy.json"], ["accuracy.json"])
    return out


def _supports_no_cache() -> bool:
    proc = subprocess.run(CLI + ["accuracy", "--help"], capture_output=True, text=True)
    return "--no-cache" in proc.stdout


def write_outputs(out: Path, only: list | None, sizes: bool, corpus: bool = False) -> None:
    out.mkdir(parents=True, exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    no_cache = ["--no-cache"] if _supports_no_cache() else []
    with tempfile.TemporaryDirectory(prefix="hyperstat-json-") as tmp:
        work, data = Path(tmp), Path(tmp) / "data"
        data.mkdir()
        subprocess.run(CLI + ["simulate", str(ROOT / "templates" / "tripteor_x7.py"), "--effect", "backlash",
                              "--out", str(data / "measurements.csv"), "--truth", str(data / "truth.json"), "--quiet"],
                       check=True, env=env, cwd=ROOT)
        for name, (args, files) in _commands(work, data, sizes, corpus).items():
            if only and name not in only:
                continue
            cached = args[0] in ("accuracy", "montecarlo", "report", "export-controller")
            cmd = CLI + [str(a) for a in args] + ["--quiet"] + (no_cache if cached else [])
            proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT)
            if proc.returncode != 0:
                raise SystemExit(f"{name} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
            for f in files:
                # the temporary folder and the checkout's own path (two checkouts compared) are not answers
                text = (work / f).read_text().replace(str(work), "<work>").replace(str(ROOT), "<root>")
                (out / f.replace("/", "-")).write_text(text)
            print(f"{name}: {', '.join(files)}", flush=True)


def differences(a, b, path: str = "", tol: float = 1e-9) -> list[str]:
    """Where ``a`` and ``b`` differ: numbers by more than ``tol`` relative, anything else at all.

    >>> differences({"x": 1.0, "y": [1, "a"]}, {"x": 1.0 + 1e-12, "y": [1, "b"]})
    ['/y/1: a != b']
    """
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k in IGNORED:
                continue
            if k not in a or k not in b:
                out.append(f"{path}/{k}: only in {'the second' if k not in a else 'the first'}")
                continue
            out += differences(a[k], b[k], f"{path}/{k}", tol)
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} items != {len(b)}"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}/{i}", tol)]
    numbers = (int, float)
    if isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool) and not isinstance(b, bool):
        if math.isclose(a, b, rel_tol=tol, abs_tol=tol):
            return []
        return [f"{path}: {a!r} != {b!r} (relative {abs(a - b) / max(abs(a), abs(b), 1e-300):.2g})"]
    return [] if a == b else [f"{path}: {str(a)[:120]} != {str(b)[:120]}"]


def compare(first: Path, second: Path) -> int:
    bad = 0
    for f in sorted(first.glob("*.json")):
        other = second / f.name
        if not other.exists():
            print(f"{f.name}: missing in {second}")
            bad += 1
            continue
        diffs = differences(json.loads(f.read_text()), json.loads(other.read_text()))
        print(f"{f.name}: {'equal to 1e-9' if not diffs else f'{len(diffs)} difference(s)'}")
        for d in diffs[:40]:
            print(f"    {d}")
        bad += bool(diffs)
    return 1 if bad else 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="folder for the JSON outputs")
    ap.add_argument("--only", action="append", help="one command of the list (repeatable)")
    ap.add_argument("--values", action="store_true",
                    help="only the commands whose JSON the tolerance values stage writes (accuracy, report)")
    ap.add_argument("--with-100k", action="store_true", help="also the 100,000-configuration accuracy")
    ap.add_argument("--with-corpus", action="store_true", help="also the report and accuracy of the corpus' delta_r")
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("A", "B"), help="compare two output folders")
    args = ap.parse_args(argv)
    if args.compare:
        return compare(*args.compare)
    if not args.out:
        ap.error("--out or --compare is required")
    only = args.only
    if args.values:
        only = (only or []) + [n for n in _commands(Path("w"), Path("d"), args.with_100k, args.with_corpus)
                               if n.startswith(("accuracy", "report"))]
    write_outputs(args.out, only, args.with_100k, args.with_corpus)
    return 0


if __name__ == "__main__":
    sys.exit(main())
