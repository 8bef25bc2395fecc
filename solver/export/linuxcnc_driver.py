#!/usr/bin/python3
"""Headless LinuxCNC "display" that drives a machine by MDI and records what LinuxCNC reports.

Units: the machine's (mm, degrees).

Run by LinuxCNC itself as the ``[DISPLAY] DISPLAY`` program of a configuration written by
:mod:`hyperstat.solver.export.linuxcnc_sim` (``linuxcnc -r machine.ini``), with Debian's
system Python (``/usr/bin/python3``), which has the ``linuxcnc`` module: it needs nothing
from hyperstat.  It reads ``[HYPERSTAT] MOVES`` (a JSON file: ``{"coordinates": "XYZBC",
"moves": [[x, y, z, b, c], ...]}``), then: estop reset, machine on, home all joints, MDI
mode, and for every move ``G1`` to it (the rotary axes named in ``unwrap``, e.g. ``"ABC"``,
on the turn nearest their current position) and waits until the commanded position is the
target, the motion done and the joints still; it records ``joint_actual_position`` and
``actual_position`` (LinuxCNC's forward kinematics of the joints) and writes them as JSON to
``[HYPERSTAT] RESULTS``, atomically.
An error is recorded in the results (``error``, and where the machine stopped: ``stopped``)
rather than raised, so that LinuxCNC shuts down cleanly when this program exits.
"""

import json
import os
import sys
import time


def _ini_value(path, section, key):
    current = None
    with open(path, encoding="utf-8") as handle:
        for line in handle:
            line = line.strip()
            if line.startswith("[") and line.endswith("]"):
                current = line[1:-1]
            elif current == section and "=" in line:
                k, v = line.split("=", 1)
                if k.strip() == key:
                    return v.strip()
    raise KeyError(f"{path}: no [{section}] {key}")


def _wait(stat, predicate, what, timeout=30.0):
    t0 = time.time()
    while time.time() - t0 < timeout:
        stat.poll()
        if predicate():
            return
        time.sleep(0.005)
    raise RuntimeError(f"timed out waiting for {what}")


def _turn_on(stat, cmd, timeout=90.0, retry_after=5.0):
    """Estop reset, then machine on; each command sent again while the task has not reached its state.

    The task takes a command only in a state that allows it: a "machine on" that arrives before the estop reset
    has been processed is dropped, and the machine then never turns on (a clean-clone suite at load 6-7 timed out
    after 30 s waiting for "machine on" on the hexapod, while the same test passed in 15 s alone).  So the reset is
    confirmed before "on" is sent, and each is sent again every ``retry_after`` seconds until ``timeout``.
    """
    import linuxcnc

    t0 = time.time()
    for state, reached, what in ((linuxcnc.STATE_ESTOP_RESET, lambda: stat.task_state != linuxcnc.STATE_ESTOP,
                                  "estop reset"),
                                 (linuxcnc.STATE_ON, lambda: stat.task_state == linuxcnc.STATE_ON, "machine on")):
        while True:
            cmd.state(state)
            cmd.wait_complete()
            try:
                _wait(stat, reached, what, timeout=min(retry_after, max(timeout - (time.time() - t0), 0.01)))
                break
            except RuntimeError:
                if time.time() - t0 >= timeout:
                    raise RuntimeError(f"timed out waiting for {what} ({timeout:.0f} s, the command sent again "
                                       f"every {retry_after:.0f} s; task state {stat.task_state})") from None


SETTLED_FOR = 0.2  #: seconds the joints must stay still (s): five polls 10 ms apart can all fall in one stall of the
# servo thread on a loaded machine, and a move read there was 2.9e-5 rad short of its target (a suite run at load 5)


def _settle(stat, timeout=10.0, reached=None):
    """Wait until the joints stop: in position, no velocity, positions within 1e-9 over five polls (10 ms apart)
    and for :data:`SETTLED_FOR` seconds of wall time; with ``reached`` (a function of the polled status), also
    until it is true."""
    t0, last, same, since = time.time(), None, 0, None
    while time.time() - t0 < timeout:
        time.sleep(0.01)
        stat.poll()
        now = tuple(stat.joint_actual_position)
        still = last is not None and max(abs(a - b) for a, b in zip(now, last)) < 1e-9
        same = same + 1 if (still and stat.inpos and stat.current_vel == 0.0 and (reached is None or reached())) else 0
        since = (since or time.time()) if same else None
        if same >= 5 and time.time() - since >= SETTLED_FOR:
            return
        last = now
    raise RuntimeError(f"timed out waiting for the joints to stop (in position {stat.inpos}, velocity "
                       f"{stat.current_vel}, joints {now}, previous {last})")


def _arrive(stat, cmd, arrived, line, what, index, target, timeout=60.0, idle_for=3.0, tries=3):
    """Wait until ``arrived()``; an MDI line the interpreter dropped (idle, nothing queued, in position, away from the
    target for ``idle_for`` seconds: seen once in a suite run at a load of 4-5) is sent again, at most ``tries``
    times (an absolute G90 move: sending it twice goes to the same place).  The timeout's message says where the
    machine was."""
    import linuxcnc

    t0, idle_since, sent = time.time(), None, 1
    while time.time() - t0 < timeout:
        stat.poll()
        if arrived():
            return
        idle = stat.interp_state == linuxcnc.INTERP_IDLE and stat.queue == 0 and stat.inpos
        idle_since = (idle_since or time.time()) if idle else None
        if idle_since is not None and time.time() - idle_since > idle_for and sent < tries:
            cmd.mode(linuxcnc.MODE_MDI)
            cmd.wait_complete()
            cmd.mdi(line)
            cmd.wait_complete(60)
            sent, idle_since = sent + 1, None
        time.sleep(0.005)
    raise RuntimeError(f"timed out waiting for {what} (sent {sent} times; commanded position "
                       f"{[round(stat.position[i], 6) for i in index]}, target {[round(v, 6) for v in target]}, "
                       f"interpreter state {stat.interp_state}, queue {stat.queue}, in position {stat.inpos}, "
                       f"task mode {stat.task_mode})")


def drive(moves_path, results_path):
    """Drive LinuxCNC through the moves of ``moves_path``; write what it reports to ``results_path``."""
    import linuxcnc

    spec = json.load(open(moves_path, encoding="utf-8"))
    letters = spec["coordinates"]
    out = {"coordinates": letters, "moves": [], "error": None}
    stat, cmd, err = linuxcnc.stat(), linuxcnc.command(), linuxcnc.error_channel()
    try:
        _turn_on(stat, cmd)
        cmd.mode(linuxcnc.MODE_MANUAL)
        cmd.wait_complete()
        cmd.home(-1)
        cmd.wait_complete()
        n_joints = stat.joints
        _wait(stat, lambda: all(stat.homed[:n_joints]), "homing")
        out["home"] = {"joints": list(stat.joint_actual_position[:n_joints]),
                       "world": list(stat.actual_position[:6])}
        cmd.mode(linuxcnc.MODE_MDI)
        cmd.wait_complete()
        cmd.mdi("G21 G90 G94")
        cmd.wait_complete()
        feed = float(spec.get("feed", 60000.0))
        unwrap = spec.get("unwrap", "")
        for target in spec["moves"]:
            if unwrap:  # rotary axes: the turn nearest the current position (360 degrees apart, same orientation)
                stat.poll()
                target = [v + 360.0 * round((stat.position["XYZABC".index(a)] - v) / 360.0) if a in unwrap else v
                          for a, v in zip(letters, target)]
            words = " ".join(f"{a}{v:.12f}" for a, v in zip(letters, target))
            cmd.mdi(f"G1 F{feed:.1f} {words}")
            cmd.wait_complete(60)
            index = ["XYZABC".index(a) for a in letters]

            def arrived():
                message = err.poll()
                if message:
                    raise RuntimeError(f"LinuxCNC: {message[1]} (after {words})")
                return (stat.interp_state == linuxcnc.INTERP_IDLE and stat.inpos and stat.queue == 0
                        and all(abs(stat.position[i] - v) <= 1e-6 * max(1.0, abs(v)) for i, v in zip(index, target)))

            # the commanded position must reach the target (a loaded machine may not have started the move yet)
            _arrive(stat, cmd, arrived, f"G1 F{feed:.1f} {words}", "the move to " + words, index, target)

            def there():  # the joints' own position, through LinuxCNC's forward kinematics, at the target: a status
                # polled during a stall of the servo thread on a loaded machine shows still joints short of it
                # (a PUMA move read 1.7e-5 rad short in a suite run at load 4, 1e-10 alone)
                return all(abs((stat.actual_position[i] - v + 180.0) % 360.0 - 180.0 if "XYZABC"[i] in "ABC"
                               else stat.actual_position[i] - v) <= 1e-6 * max(1.0, abs(v))
                           for i, v in zip(index, target))

            try:
                _settle(stat, timeout=30.0, reached=there)
            except RuntimeError:
                _settle(stat)  # never there (the kinematics' own round trip): what the joints say is recorded
            stat.poll()
            out["moves"].append({"command": list(target), "joints": list(stat.joint_actual_position[:n_joints]),
                                 "world": list(stat.actual_position[:6])})
    except Exception as exc:  # recorded, so that LinuxCNC shuts down normally
        out["error"] = f"{exc.__class__.__name__}: {exc}"
        try:  # where the machine stopped (a move refused part-way)
            time.sleep(0.5)
            try:
                # on a loaded machine the status can still show the move under way after the error (seen once in a
                # suite run: a leg recorded 3.4 mm short of where it stopped): wait until it shows the joints still
                _settle(stat)
            except RuntimeError:
                pass  # what the status says is recorded
            stat.poll()
            out["stopped"] = {"joints": list(stat.joint_actual_position[:stat.joints]),
                              "world": list(stat.actual_position[:6]), "position": list(stat.position[:6])}
        except Exception:  # noqa: BLE001 - the error above is what matters
            pass
    tmp = results_path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as handle:
        json.dump(out, handle)
    os.replace(tmp, results_path)


if __name__ == "__main__":
    ini = sys.argv[sys.argv.index("-ini") + 1] if "-ini" in sys.argv else os.environ["INI_FILE_NAME"]
    drive(_ini_value(ini, "HYPERSTAT", "MOVES"), _ini_value(ini, "HYPERSTAT", "RESULTS"))
