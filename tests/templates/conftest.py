"""The corpus runs in the background: started when its tests are collected, read when they run.

Units: lengths in mm, angles in rad.

Every command on every corpus member is minutes of CPU (``tests/templates/corpus_runner.py``).  When a
collected test uses the ``corpus`` fixture, one worker process starts as soon as collection ends and runs
them all while the rest of the suite runs on the other core; the fixture waits for it.  The worker is
stopped with the session.

Under pytest-xdist (``make test``: ``-n 2``) each xdist worker collects every test: a worker that collected a
corpus test says so (a file in the session's folder, ``tests/conftest.py``) and the controller starts the one
background run for all of them, in ``SESSION_DIR/corpus`` (:func:`start_shared_corpus`); the fixture of any xdist
worker waits for its ``done`` file (:func:`wait_shared_corpus`), and the controller stops it with the session.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_JOB: dict = {}
_SHARED: dict = {}


def _start(root: Path) -> dict:
    """The background run of every command on every member, writing into ``root``."""
    from tests.templates.corpus_runner import MEMBERS, ROOT

    log = open(root / "worker.log", "w", encoding="utf-8")
    proc = subprocess.Popen([sys.executable, "-m", "tests.templates.corpus_runner", str(root), *MEMBERS], cwd=ROOT,
                            stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    (root / "pid").write_text(str(proc.pid), encoding="utf-8")
    return {"root": root, "proc": proc, "log": log}


def _stop(job: dict) -> None:
    proc = job.get("proc")
    if proc is not None and proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)  # the worker's own session: it and whatever it started
        proc.wait()
    if job:
        job["log"].close()


def _shared_root() -> Path:
    from tests.conftest import SESSION_DIR

    return SESSION_DIR / "corpus"


def pytest_collection_finish(session) -> None:
    if _JOB or not any("corpus" in getattr(item, "fixturenames", ()) for item in session.items):
        return
    if os.environ.get("PYTEST_XDIST_WORKER"):  # the controller starts one run for every xdist worker
        _shared_root().parent.mkdir(parents=True, exist_ok=True)
        (_shared_root().parent / "corpus.wanted").touch()
        return
    _JOB.update(_start(Path(tempfile.mkdtemp(prefix="hyperstat-corpus-"))))


def start_shared_corpus() -> None:
    """In the controller of an xdist run: start the background run once, when a worker collected a corpus test."""
    root = _shared_root()
    if _SHARED or not (root.parent / "corpus.wanted").is_file():
        return
    root.mkdir(parents=True, exist_ok=True)
    _SHARED.update(_start(root))


def stop_shared_corpus() -> None:
    """In the controller, at the end of the session: stop the background run if it still runs."""
    _stop(_SHARED)
    _SHARED.clear()


def wait_shared_corpus(timeout_s: float) -> Path | None:
    """In an xdist worker: the folder of the controller's background run once it is done; ``None`` when there is
    none.  Raises ``RuntimeError`` when the run ended without finishing, or ``TimeoutError``."""
    root = _shared_root()
    if not (root.parent / "corpus.wanted").is_file():
        return None
    deadline = time.monotonic() + timeout_s
    while not (root / "done").is_file():
        if time.monotonic() > deadline:
            raise TimeoutError(f"the corpus worker did not finish within {timeout_s:.0f} s")
        pid = (root / "pid").read_text(encoding="utf-8") if (root / "pid").is_file() else None
        if pid is None and time.monotonic() > deadline - timeout_s + 300:
            raise RuntimeError("the controller did not start the corpus worker within 300 s")
        if pid:
            try:
                alive = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
            except OSError:
                alive = False
            if not alive and not (root / "done").is_file():
                log = (root / "worker.log").read_text(encoding="utf-8", errors="replace")[-4000:]
                raise RuntimeError(f"the corpus worker ended without finishing:\n{log}")
        time.sleep(1.0)
    return root


def corpus_job() -> dict:
    """The background worker (``root``, ``proc``), or an empty dict when none was started."""
    return _JOB


def pytest_sessionfinish(session, exitstatus) -> None:
    import shutil

    if _JOB:
        _stop(_JOB)
        shutil.rmtree(_JOB["root"], ignore_errors=True)
