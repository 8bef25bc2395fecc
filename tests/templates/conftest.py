"""The corpus runs in the background: started when its tests are collected, read when they run.

Units: lengths in mm, angles in rad.

Every command on every corpus member is minutes of CPU (``tests/templates/corpus_runner.py``).  When a
collected test uses the ``corpus`` fixture, one worker process starts as soon as collection ends and runs
them all while the rest of the suite runs on the other core; the fixture waits for it.  The worker is
stopped with the session.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

_JOB: dict = {}


def pytest_collection_finish(session) -> None:
    if _JOB or not any("corpus" in getattr(item, "fixturenames", ()) for item in session.items):
        return
    from tests.templates.corpus_runner import MEMBERS, ROOT

    root = Path(tempfile.mkdtemp(prefix="hyperstat-corpus-"))
    log = open(root / "worker.log", "w", encoding="utf-8")
    proc = subprocess.Popen([sys.executable, "-m", "tests.templates.corpus_runner", str(root), *MEMBERS], cwd=ROOT,
                            stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    _JOB.update(root=root, proc=proc, log=log)


def corpus_job() -> dict:
    """The background worker (``root``, ``proc``), or an empty dict when none was started."""
    return _JOB


def pytest_sessionfinish(session, exitstatus) -> None:
    import shutil

    proc = _JOB.get("proc")
    if proc is not None and proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)  # the worker's own session: it and whatever it started
        proc.wait()
    if _JOB:
        _JOB["log"].close()
        shutil.rmtree(_JOB["root"], ignore_errors=True)
