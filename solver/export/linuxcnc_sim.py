"""A LinuxCNC simulation configuration (INI and HAL) for a generated kinematics component, and its run.

Units: mm and degrees on LinuxCNC's side (``LINEAR_UNITS = mm``, ``ANGULAR_UNITS = degree``).

The configuration is a machine with no hardware: every joint's commanded position is fed
back as its measured position, homing takes the current position as the home
(``HOME_SEARCH_VEL = 0``), the joints home at the model's home configuration and their
limits are the model's joint ranges (widened by 1e-6 mm or degree, so that a home on a
limit is not refused for round-off).  ``[DISPLAY] DISPLAY`` is the headless driver
(:mod:`hyperstat.solver.export.linuxcnc_driver`) which moves the machine by MDI; an
integrator swaps it for ``axis`` to drive the machine by hand.

:func:`build_component` compiles and installs the component with ``halcompile``
(LinuxCNC loads kinematics modules only from its module directory), :func:`run_moves`
starts LinuxCNC on the configuration, lets the driver move it and returns what LinuxCNC
reported.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from hyperstat.solver.atomic import all_or_nothing, write_text
from hyperstat.solver.errors import HyperstatError
from hyperstat.solver.export.linuxcnc_kins import LIMIT_MARGIN

__all__ = ["sim_files", "write_sim", "build_component", "remove_component", "run_moves", "linuxcnc_env"]

SYSTEM_PYTHON = "/usr/bin/python3"


def _fmt(v: float) -> str:
    return f"{v:.12g}"


def sim_files(mechanism, component: str, layout: dict, workspace: np.ndarray | None = None,
              display: str = "axis", home: np.ndarray | None = None) -> tuple[str, str]:
    """INI and HAL text of a simulated machine with the kinematics ``component``.

    Parameters
    ----------
    mechanism : Mechanism
        The model (joint types, home, ranges).
    component : str
        Name of the kinematics component (installed module).
    layout : dict
        :func:`hyperstat.solver.export.linuxcnc_kins.world_layout` of the mechanism.
    workspace : ndarray, (K, n_world), optional
        World coordinates the machine reaches (mm, degrees); the axis limits enclose them
        with a 50 % margin (default: +-10000 mm, +-3600 degrees).
    display : str
        ``[DISPLAY] DISPLAY`` program.
    home : ndarray, (n_q,), optional
        Home configuration (every joint; the component's, see
        :func:`hyperstat.solver.export.linuxcnc_kins.kins_component`); default the model's.

    Returns
    -------
    ini, hal : str
    """
    act = [int(i) for i in mechanism.actuated]
    n = len(act)
    coords = layout["coordinates"]
    ini = [
        "# LinuxCNC simulation configuration written by hyperstat (units: mm, degrees)",
        "[EMC]", "VERSION = 1.1", f"MACHINE = {mechanism.name} (hyperstat {component})", "",
        "[DISPLAY]", f"DISPLAY = {display}", "POSITION_FEEDBACK = ACTUAL", "MAX_LINEAR_VELOCITY = 2000", "",
        "[TASK]", "TASK = milltask", "CYCLE_TIME = 0.001", "",
        "[RS274NGC]", "PARAMETER_FILE = sim.var", "RS274NGC_STARTUP_CODE = G21 G90 G94 G17 G40 G49 G54", "",
        "[EMCMOT]", "EMCMOT = motmod", "COMM_TIMEOUT = 1.0", "SERVO_PERIOD = 1000000", "",
        "[EMCIO]", "EMCIO = io", "CYCLE_TIME = 0.100", "",
        "[HAL]", "HALFILE = machine.hal", "",
        "[TRAJ]", f"COORDINATES = {' '.join(coords)}", "LINEAR_UNITS = mm", "ANGULAR_UNITS = degree",
        "DEFAULT_LINEAR_VELOCITY = 1000", "MAX_LINEAR_VELOCITY = 2000", "DEFAULT_LINEAR_ACCELERATION = 20000",
        "MAX_LINEAR_ACCELERATION = 20000", "DEFAULT_ANGULAR_VELOCITY = 2000", "MAX_ANGULAR_VELOCITY = 2000", "",
        "[KINS]", f"KINEMATICS = {component}", f"JOINTS = {n}", "",
    ]
    for k, j in enumerate(act):
        joint = mechanism.joints[j]
        rot = joint.type == "R"
        conv = math.degrees if rot else float
        lo, hi = (conv(v) for v in joint.range)
        lo, hi = lo - LIMIT_MARGIN, hi + LIMIT_MARGIN  # a home on a limit is not refused for round-off
        home_value = conv(joint.home if home is None else float(np.asarray(home).reshape(-1)[j]))
        ini += [f"[JOINT_{k}]", f"# model joint '{joint.name}' ({'revolute, degrees' if rot else 'prismatic, mm'})",
                f"TYPE = {'ANGULAR' if rot else 'LINEAR'}",
                f"HOME = {_fmt(home_value)}", f"HOME_OFFSET = {_fmt(home_value)}",
                "HOME_SEARCH_VEL = 0", "HOME_LATCH_VEL = 0", "HOME_SEQUENCE = 0",
                f"MIN_LIMIT = {_fmt(lo)}", f"MAX_LIMIT = {_fmt(hi)}",
                "MAX_VELOCITY = 100000", "MAX_ACCELERATION = 1000000", ""]
    for i, letter in enumerate(coords):
        if workspace is not None and len(workspace):
            lo, hi = float(np.min(workspace[:, i])), float(np.max(workspace[:, i]))
            pad = 0.5 * (hi - lo) + (1.0 if i < 3 else 5.0)
            lo, hi = lo - pad, hi + pad
        else:
            lo, hi = (-10000.0, 10000.0) if i < 3 else (-3600.0, 3600.0)
        ini += [f"[AXIS_{letter}]", f"MIN_LIMIT = {_fmt(lo)}", f"MAX_LIMIT = {_fmt(hi)}",
                "MAX_VELOCITY = 2000", "MAX_ACCELERATION = 20000", ""]
    hal = ["# HAL of a simulated machine written by hyperstat: commanded joint positions fed back as measured",
           "loadrt [KINS]KINEMATICS",
           "loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS",
           "addf motion-command-handler servo-thread",
           "addf motion-controller servo-thread"]
    hal += [f"net j{k}-pos joint.{k}.motor-pos-cmd => joint.{k}.motor-pos-fb" for k in range(n)]
    hal += ["net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in",
            "net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed",
            "net tool-prep-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared"]
    return "\n".join(ini) + "\n", "\n".join(hal) + "\n"


def write_sim(directory: str | os.PathLike, mechanism, component: str, layout: dict,
              workspace: np.ndarray | None = None, display: str = "axis", home: np.ndarray | None = None,
              extra_hal: str = "") -> Path:
    """Write ``machine.ini`` and ``machine.hal`` (with ``extra_hal`` appended) into ``directory``, both or
    neither (see :func:`sim_files`); return the INI path."""
    directory = Path(directory)
    ini, hal = sim_files(mechanism, component, layout, workspace, display, home)
    with all_or_nothing():
        write_text(directory / "machine.hal", hal + extra_hal)
        return write_text(directory / "machine.ini", ini)


def _require(tool: str) -> str:
    path = shutil.which(tool)
    if not path:
        raise HyperstatError(f"'{tool}' was not found: install Debian's linuxcnc-uspace and linuxcnc-uspace-dev.")
    return path


MODULE_DIR = Path("/usr/lib/linuxcnc/modules")


def _privileged(argv: list[str]) -> list[str]:
    """``argv`` as root: unchanged for root, else through ``sudo -n`` (no password prompt) when there is one."""
    if os.geteuid() == 0 or not shutil.which("sudo"):
        return argv
    return ["sudo", "-n", *argv]


def build_component(comp_file: str | os.PathLike) -> str:
    """Compile and install a ``.comp`` kinematics component with ``halcompile --install``; return its name.

    LinuxCNC loads modules only from its module directory (``/usr/lib/linuxcnc/modules``),
    so this needs write access there: root, or ``sudo`` without a password.
    """
    comp_file = Path(comp_file)
    run = subprocess.run(_privileged([_require("halcompile"), "--install", comp_file.name]), cwd=comp_file.parent,
                         capture_output=True, text=True, timeout=300)
    if run.returncode != 0:
        last = (run.stderr or run.stdout).strip().splitlines()[-1:] or ["no message"]
        raise HyperstatError(f"halcompile failed on {comp_file}: {last[0]}")
    return comp_file.stem


def remove_component(name: str) -> None:
    """Remove an installed component module (``/usr/lib/linuxcnc/modules/NAME.so``)."""
    path = MODULE_DIR / f"{name}.so"
    if path.exists():
        subprocess.run(_privileged(["rm", "-f", str(path)]), capture_output=True, timeout=60)


def linuxcnc_env(workdir: Path) -> dict:
    """Environment for a headless LinuxCNC run (no DISPLAY; as root, an unprivileged RTAPI uid and socket path)."""
    env = dict(os.environ)
    # headless: with a DISPLAY the linuxcnc script asks questions (a stale lock) in a Tk window nobody sees
    for name in ("PYTHONPATH", "DISPLAY", "WAYLAND_DISPLAY"):
        env.pop(name, None)
    env["RTAPI_FIFO_PATH"] = str(workdir / "rtapi.sock")
    if os.geteuid() == 0:
        env["RTAPI_UID"] = "65534"
    return env


def run_moves(ini: str | os.PathLike, coordinates: str, moves: np.ndarray, timeout: float = 300.0,
              unwrap: str = "") -> dict:
    """Start LinuxCNC on ``ini`` with the headless driver, move to ``moves`` by MDI, return what it reported.

    Parameters
    ----------
    ini : path
        Configuration of :func:`write_sim` (its ``DISPLAY`` is replaced by the driver).
    coordinates : str
        World coordinate letters, e.g. ``"XYZBC"``.
    moves : ndarray, (K, len(coordinates))
        Targets (mm, degrees).
    unwrap : str
        Rotary axes (e.g. ``"ABC"``) the driver moves on the turn nearest their current
        position (an angle near +-180 degrees must not turn the wrist over); the command
        sent is in the result.

    Returns
    -------
    dict
        ``home`` and ``moves`` (``command``, ``joints``, ``world`` as LinuxCNC reports
        them), ``error`` (None on success).

    Raises
    ------
    HyperstatError
        When LinuxCNC does not start or the driver reports nothing.
    """
    linuxcnc = _require("linuxcnc")
    if not Path(SYSTEM_PYTHON).exists():
        raise HyperstatError(f"{SYSTEM_PYTHON} (Debian's python3, with the linuxcnc module) is missing.")
    ini = Path(ini)
    work = Path(tempfile.mkdtemp(prefix="hyperstat-lcnc-", dir="/tmp"))
    os.chmod(work, 0o777)  # the realtime part runs as the unprivileged RTAPI_UID
    try:
        driver = work / "driver.py"
        driver.write_text(Path(__file__).with_name("linuxcnc_driver.py").read_text(encoding="utf-8"),
                          encoding="utf-8")
        os.chmod(driver, 0o755)
        (work / "moves.json").write_text(json.dumps({"coordinates": coordinates, "unwrap": unwrap,
                                                      "moves": np.asarray(moves, float).tolist()}))
        text = ini.read_text(encoding="utf-8")
        lines = [f"DISPLAY = {driver}" if line.startswith("DISPLAY =") else line for line in text.splitlines()]
        lines += ["", "[HYPERSTAT]", f"MOVES = {work / 'moves.json'}", f"RESULTS = {work / 'results.json'}"]
        for name in ("machine.hal",):
            shutil.copy(ini.parent / name, work / name)
        (work / "machine.ini").write_text("\n".join(lines) + "\n")
        run = subprocess.run([linuxcnc, "-r", str(work / "machine.ini")], cwd=work, capture_output=True, text=True,
                             timeout=timeout, env=linuxcnc_env(work))
        results = work / "results.json"
        if not results.exists():
            tail = "\n".join((run.stdout + run.stderr).strip().splitlines()[-15:])
            raise HyperstatError(f"LinuxCNC ran without the driver reporting (exit {run.returncode}):\n{tail}")
        out = json.loads(results.read_text())
        out["log"] = run.stdout[-4000:]
        return out
    finally:
        shutil.rmtree(work, ignore_errors=True)
