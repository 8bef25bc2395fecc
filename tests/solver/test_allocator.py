"""The allocator setting of the command line (hyperstat.solver.allocator): set by the command, the same outputs."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

CHILD = """
import sys
from hyperstat.solver import allocator
from hyperstat.cad_plugin.cli import main
sys.argv = ["hyperstat"] + sys.argv[1:]
code = main()
print("kept" if allocator._done else "left", code)
"""


def _run(tmp_path: Path, name: str, keep: str) -> tuple[str, bytes]:
    out = tmp_path / f"{name}.json"
    env = dict(os.environ, HYPERSTAT_KEEP_MEMORY=keep, HYPERSTAT_CACHE="off")
    proc = subprocess.run([sys.executable, "-c", CHILD, "analyze", str(ROOT / "templates" / "slider_crank.py"),
                           "--json", str(out), "--quiet"],
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.split()[-2], out.read_bytes()


def test_the_command_keeps_freed_memory_and_writes_the_same_bytes_as_without(tmp_path):
    kept, with_setting = _run(tmp_path, "kept", "1")
    left, without = _run(tmp_path, "left", "0")
    assert (kept, left) == ("kept", "left")  # the command line sets it, HYPERSTAT_KEEP_MEMORY=0 does not
    assert with_setting == without


def test_the_python_api_leaves_the_allocator_of_its_caller_alone():
    code = ("from hyperstat.solver import allocator; from hyperstat.cad_plugin.cli import main; "
            "main(['analyze', 'slider_crank', '--quiet']); print(allocator._done)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                          env=dict(os.environ, HYPERSTAT_CACHE="off"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split()[-1] == "False"
