"""Run an action's steps in the GUI without freezing it: one ``QProcess`` per command-line call.

Units: none (the steps work in mm and rad).

An action of :mod:`.operations` is a generator that yields a :class:`~.operations.Call`
for each run of ``hyperstat`` and touches the document only after the last one.  A
:class:`Job` starts each call as a ``QProcess`` (the calls of a :class:`~.operations.Together` at once, one
process each) and returns to Qt's event loop: FreeCAD
stays responsive (the 3D view turns, the tree scrolls), a progress bar in the status
bar (and in the task panel that started the job) names the stage, counts the seconds
and says how long the stage usually takes (:mod:`.estimates`: the last runs of that
command for that template, or its typical duration), and *Cancel* stops the process.  When a process ends, the generator resumes
in the GUI thread with its output, so every document change happens in the GUI thread,
after the last call, in one undo transaction.

One job at a time (:func:`running`): the workbench's commands that start one are
greyed out while it runs.
"""

from __future__ import annotations

import time

from . import estimates
from .runner import DEFAULT_TIMEOUT_S, HyperstatWorkbenchError, interpret, prepare_command

__all__ = ["Job", "running", "CURRENT"]

#: the job under way (at most one)
CURRENT: list = []


def running() -> bool:
    """True while a job runs."""
    return bool(CURRENT)


class _StatusProgress:
    """A busy progress bar, a label and a Cancel button in FreeCAD's status bar."""

    def __init__(self, job):
        from PySide import QtGui

        import FreeCADGui

        bar = FreeCADGui.getMainWindow().statusBar()
        self.widget = QtGui.QWidget()
        self.widget.setObjectName("HyperstatProgress")
        layout = QtGui.QHBoxLayout(self.widget)
        layout.setContentsMargins(0, 0, 0, 0)
        self.label = QtGui.QLabel()
        self.label.setObjectName("HyperstatProgressText")
        self.bar = QtGui.QProgressBar()
        self.bar.setRange(0, 100)  # the share of the stage's estimated duration
        self.bar.setMaximumWidth(160)
        self.cancel = QtGui.QPushButton("Cancel")
        self.cancel.setObjectName("HyperstatCancel")
        self.cancel.clicked.connect(job.cancel)
        for w in (self.label, self.bar, self.cancel):
            layout.addWidget(w)
        bar.addPermanentWidget(self.widget)
        self.widget.show()

    def update(self, text: str, percent: int) -> None:
        self.label.setText(text)
        self.bar.setValue(percent)

    def close(self) -> None:
        import FreeCADGui

        FreeCADGui.getMainWindow().statusBar().removeWidget(self.widget)
        self.widget.deleteLater()


class _Run:
    """One process of a stage: its call, command line and ``QProcess``; its outcome once ended (result or error)."""

    def __init__(self, call, command: list, process):
        self.call, self.command, self.process = call, command, process
        self.ended = False
        self.outcome = None


class Job:
    """Drive a step generator with one ``QProcess`` per call (see the module docstring).

    Parameters
    ----------
    title : str
        What the user asked for ("Insert skeleton"), shown with the progress.
    steps : generator
        From :mod:`.operations` (``insert_steps``, ``edit_steps``, ``analyze_steps``...).
    on_done : callable(value)
        Called in the GUI thread with the generator's return value.
    on_error : callable(exception)
        Called with the failure (the generator has seen it first); default: a message box.
    progress : callable(str), optional
        Also told each stage (a task panel's own label).
    on_cancel : callable(), optional
        Called when the user cancelled (nothing was written to the document).
    """

    def __init__(self, title: str, steps, on_done, on_error=None, progress=None, on_cancel=None):
        self.on_cancel = on_cancel
        self.title = title
        self.steps = steps
        self.on_done = on_done
        self.on_error = on_error
        self.progress = progress
        self.process = None
        self._runs: list = []
        self.stage = ""
        self.step = 0
        self.call = None
        self.stage_started = 0.0
        self.estimate = (0.0, False)
        self.started = 0.0
        self.cancelled = False
        self.finished = False
        self._status = None
        self._ticker = None
        self.percent = 0  # the share of the stage's estimated duration at the last tick (%)

    # ------------------------------------------------------------------ public
    def start(self) -> bool:
        """Start (False, with a message, if another job runs)."""
        from PySide import QtCore

        if CURRENT:
            self._fail(HyperstatWorkbenchError(
                f"'{CURRENT[0].title}' is still running: wait for it or cancel it first."), to_steps=False)
            return False
        CURRENT[:] = [self]
        self.started = time.monotonic()
        self._status = _StatusProgress(self)
        self._ticker = QtCore.QTimer()
        self._ticker.setInterval(500)
        self._ticker.timeout.connect(self._tick)
        self._ticker.start()
        self._advance(lambda: next(self.steps))
        return True

    def cancel(self) -> None:
        """Stop the running process(es); nothing is written to the document."""
        if self.finished:
            return
        self.cancelled = True
        running = [run.process for run in self._runs if not run.ended]
        if running:
            for proc in running:
                proc.kill()  # _finished runs next and closes the job
        else:
            self._close()

    # ------------------------------------------------------------------ internals
    def _tick(self) -> None:
        elapsed = time.monotonic() - self.stage_started
        seconds, measured = self.estimate
        text = estimates.progress_text(self.title, self.stage, self.step, elapsed, seconds, measured)
        percent = int(min(95.0, 100.0 * elapsed / max(seconds, 1e-3)))
        self.percent = percent
        if self._status is not None:
            self._status.update(text, percent)
        if self.progress is not None:
            try:
                self.progress(text)
            except RuntimeError:  # the panel was closed (its widgets are gone)
                self.progress = None

    def _advance(self, resume) -> None:
        try:
            call = resume()
        except StopIteration as stop:
            self._close()
            self.on_done(stop.value)
            return
        except Exception as exc:  # noqa: BLE001 - every failure becomes a message
            self._fail(exc, to_steps=False)
            return
        self._launch(call)

    def _launch(self, call) -> None:
        """Start the process of a :class:`~.operations.Call`, or one per call of a :class:`~.operations.Together`
        (their results go back to the steps together, in order, when all have ended)."""
        from PySide import QtCore

        self.stage = call.label
        self.step += 1
        self.call = call
        self.stage_started = time.monotonic()
        calls = list(getattr(call, "calls", None) or [call])
        # runs started together take as long as the longest of them
        self.estimate = max((estimates.expected(c.arguments[0], getattr(c, "subject", "")) for c in calls),
                            key=lambda e: e[0])
        self._tick()
        try:
            prepared = [prepare_command(c.arguments, check_optional=False) for c in calls]
        except Exception as exc:  # noqa: BLE001
            self._advance(lambda: self.steps.throw(exc))
            return
        self._runs = [_Run(c, command, QtCore.QProcess()) for c, (command, _) in zip(calls, prepared)]
        self._timeout = QtCore.QTimer()
        self._timeout.setSingleShot(True)
        self._timeout.timeout.connect(self._kill_all)
        self._timeout.start(int(DEFAULT_TIMEOUT_S * 1000))
        for run, (command, env) in zip(self._runs, prepared):
            proc = run.process
            qenv = QtCore.QProcessEnvironment()
            for key, value in env.items():
                qenv.insert(key, value)
            proc.setProcessEnvironment(qenv)
            # PySide2 may pick the one-argument overload of finished: read the status from the process
            proc.finished.connect(lambda *args, r=run: self._finished(r))
            proc.errorOccurred.connect(lambda error, r=run: self._error(r, error))
        self.process = self._runs[0].process
        for run in self._runs:
            self._log(f"hyperstat: starting '{' '.join(run.command)}'\n")
            run.process.start(run.command[0], run.command[1:])

    def _kill_all(self) -> None:
        for run in self._runs:
            if not run.ended:
                run.process.kill()

    def _error(self, run, error) -> None:
        from PySide import QtCore

        if error == QtCore.QProcess.FailedToStart and not run.ended:
            run.ended = True
            run.outcome = HyperstatWorkbenchError(
                f"{run.command[0]} could not be started ({run.process.errorString()}).")
            self._all_ended()

    def _finished(self, run) -> None:
        from PySide import QtCore

        if run.ended:
            return
        run.ended = True
        proc, command = run.process, run.command
        code, status = proc.exitCode(), proc.exitStatus()
        stdout = bytes(proc.readAllStandardOutput()).decode("utf-8", "replace")
        stderr = bytes(proc.readAllStandardError()).decode("utf-8", "replace")
        took = time.monotonic() - self.stage_started
        self._log(f"hyperstat: '{' '.join(command)}' exit {code} after {took:.1f} s\n")
        if code == 0 and status == QtCore.QProcess.NormalExit and not self.cancelled:
            estimates.record(run.call.arguments[0], getattr(run.call, "subject", ""), took)
        try:
            if status != QtCore.QProcess.NormalExit:  # killed by the timeout, or crashed
                raise HyperstatWorkbenchError(
                    f"'hyperstat {command[1] if len(command) > 1 else ''}' was stopped or crashed "
                    f"(after {time.monotonic() - self.started:.0f} s).")
            run.outcome = interpret(command, code, stdout, stderr)
        except Exception as exc:  # noqa: BLE001 - handed to the steps, which record and re-raise it
            run.outcome = exc
        self._all_ended()

    def _all_ended(self) -> None:
        """When every run of the stage has ended: the steps get the result(s), or the first failure in order."""
        if not all(run.ended for run in self._runs):
            return
        self._timeout.stop()
        self.process = None
        if self.cancelled:
            self.steps.close()
            self._close()
            self._info(f"{self.title}: cancelled; the document is unchanged.")
            if self.on_cancel is not None:
                self.on_cancel()
            return
        failures = [run.outcome for run in self._runs if isinstance(run.outcome, Exception)]
        if failures:
            self._advance(lambda: self.steps.throw(failures[0]))
            return
        results = tuple(run.outcome for run in self._runs)
        together = getattr(self.call, "calls", None) is not None
        self._advance(lambda: self.steps.send(results if together else results[0]))

    def _fail(self, exc, to_steps: bool) -> None:
        self._close()
        if self.on_error is not None:
            self.on_error(exc)
        else:
            from .messages import show_error

            show_error(self.title, exc)

    def _close(self) -> None:
        if self.finished:
            return
        self.finished = True
        if self._ticker is not None:
            self._ticker.stop()
        if self._status is not None:
            self._status.close()
        if CURRENT and CURRENT[0] is self:
            CURRENT.clear()

    @staticmethod
    def _log(text: str) -> None:
        import FreeCAD

        FreeCAD.Console.PrintLog(text)

    @staticmethod
    def _info(text: str) -> None:
        from .messages import show_info

        show_info("Hyperstat", text)
