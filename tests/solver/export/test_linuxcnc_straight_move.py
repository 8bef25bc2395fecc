"""A straight G1 move between two reachable poses near the workspace edge, in the real LinuxCNC (issue 31).

Units: mm and rad here; LinuxCNC works in mm and degrees.

The Tripteor X7 (nominal geometry), from a pose near the edge of leg 42's stroke to another
reachable pose: on the straight line in world coordinates ``X Y Z B C`` between them, leg 42
runs below its range at about 5 % of the way.  ``check_straight_move`` (and ``hyperstat
check-move``) says so before the move; a second solver (assembly by continuation at every
point, :func:`world_inverse`) finds the same excursion.  In LinuxCNC, the generated component
refuses a pose outside the joint ranges: the move stops with every joint inside its range, near
the point predicted.  The same component with that check removed runs the leg past its limit
until LinuxCNC's soft limit stops it (what the issue saw).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hyperstat.solver.export.linuxcnc_kins import LIMIT_MARGIN, world_layout
from hyperstat.solver.export.linuxcnc_sim import build_component, remove_component, run_moves
from hyperstat.solver.export.straight_moves import STEP_MM, check_straight_move, world_inverse
from hyperstat.solver.kinematics.closure import Kinematics
from tests.conftest import run_cli

# the move (world coordinates X Y Z B C, mm and degrees): its end points are reachable inside the ranges
START = np.array([596.783, 18.262, -1143.049, -22.58, 161.514])
END = np.array([289.721, -477.765, -987.814, -28.522, -106.756])


@pytest.fixture(scope="module")
def predicted(tripteor):
    return check_straight_move(tripteor, None, START, END)


def test_the_line_leaves_leg_42_and_a_second_solver_agrees(tripteor, predicted):
    r = predicted
    assert not r["inside"] and r["joint"] == "42" and 0.0 < r["fraction"] < 0.2
    lo, hi = tripteor.joints[tripteor.joint_index["42"]].range
    assert r["limit"] == lo and r["value"] < lo and r["excess"]["42"] > 1.0
    assert all(v == 0.0 for n, v in r["excess"].items() if n not in ("42",))
    # second method: assembly by continuation (certified branch) at points along the line, each from the last
    kin, layout = Kinematics(tripteor), world_layout(tripteor)
    q, _ = world_inverse(kin, np.zeros(len(tripteor.parameters)), layout, START, tripteor.home)
    legs = []
    for s in np.linspace(0.0, 0.3, 31):
        q, err = world_inverse(kin, np.zeros(len(tripteor.parameters)), layout, START + s * (END - START), q)
        assert err < 1e-6
        legs.append(q[tripteor.joint_index["42"]])
    deepest = lo - min(legs)
    # the two agree to what the coarser sampling (1 % of the line, about 6 mm) can miss of a smooth minimum
    assert abs(deepest - r["excess"]["42"]) < 0.05 * r["excess"]["42"] + 0.1, (deepest, r["excess"]["42"])


def test_check_move_command(tmp_path, tripteor):
    from hyperstat.solver.kinematics.modelfile import save_model

    model = save_model(tripteor, tmp_path / "tx7.json")
    words = lambda w: " ".join(f"{a}{v:g}" for a, v in zip("XYZBC", w))  # noqa: E731
    short = START + 0.5 * (END - START)  # half the move, past where leg 42 is back in range (39 % of the whole)
    code, out, err = run_cli(["check-move", model, "--from", words(START), "--to", words(short)])
    assert code == 1 and "leaves the range of joint '42' at 9" in out and err == "", (code, out, err)
    code, out, _ = run_cli(["check-move", model, "--from", words(START), "--to", words(START + [-20, -20, 5, 1, -5])])
    assert code == 0 and "stays inside every joint range" in out


def _stop(report: dict) -> dict:
    assert report["error"] and report.get("stopped"), report
    assert len(report["moves"]) == 1  # the move to START arrived, the one to END did not
    return report["stopped"]


def test_linuxcnc_stops_the_move_inside_the_ranges(tripteor, predicted, tmp_path):
    model = tmp_path / "tx7.json"
    from hyperstat.solver.kinematics.modelfile import save_model

    save_model(tripteor, model)
    out = tmp_path / "kins"
    assert run_cli(["export-linuxcnc-kins", model, "--out", out, "--name", "hs_line_kins", "--quiet"])[0] == 0
    act = tripteor.actuated
    lo, hi = tripteor.ranges[act].T
    rot = np.array([tripteor.joints[i].type == "R" for i in act])
    margin = np.where(rot, math.radians(LIMIT_MARGIN), LIMIT_MARGIN)
    reports = {}
    guarded = (out / "hs_line_kins.comp").read_text()
    check = "        if (q[ACT[i]] < ACT_LO[i] || q[ACT[i]] > ACT_HI[i]) return -1;"
    assert check in guarded
    # the same component without the range check: the behaviour before issue 31
    (out / "hs_noguard_kins.comp").write_text(guarded.replace(check, "        ;").replace("hs_line_kins",
                                                                                          "hs_noguard_kins"))
    ini = (out / "machine.ini").read_text()
    for name in ("hs_line_kins", "hs_noguard_kins"):
        (out / "machine.ini").write_text(ini.replace("hs_line_kins", name))
        built = build_component(out / f"{name}.comp")
        try:
            reports[name] = run_moves(out / "machine.ini", "XYZBC", np.array([START, END]))
        finally:
            remove_component(built)
    stop = _stop(reports["hs_line_kins"])
    assert "kinematicsInverse failed" in reports["hs_line_kins"]["error"]
    joints = np.where(rot, np.radians(stop["joints"]), stop["joints"])
    assert np.all(joints >= lo - margin) and np.all(joints <= hi + margin), (joints, lo, hi)
    leg = list(act).index(tripteor.joint_index["42"])
    assert joints[leg] - lo[leg] < 1.0  # it stopped at the limit, not short of it
    # where the line crosses the limit (the first point checked beyond it, 2 mm apart): LinuxCNC stopped there
    assert np.linalg.norm(np.array(stop["world"][:3]) - predicted["world"][:3]) < 2 * STEP_MM + 1.0
    legacy = _stop(reports["hs_noguard_kins"])
    assert "soft limit" in reports["hs_noguard_kins"]["error"]
    assert lo[leg] - legacy["joints"][leg] > 1.0  # without the check, the leg ran past its limit
