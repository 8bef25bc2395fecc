"""Several reflectors and 6-D rows in one diagnosis: one answer for the robot, and the check per target.

Units: lengths in mm, angles in rad.  The campaigns come from the FANUC-like generator of the
calibration tests (its own DH forward kinematics, tracker, three SMRs; it imports nothing from
hyperstat), with a periodic error of joint 1 added to its true joint angles: the expected
answer is that error, on every target.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.calibration.measurements import parse_measurements
from hyperstat.solver.diagnosis.diagnose import diagnose
from hyperstat.solver.kinematics.robot_import import import_robot

from tests.solver.calibration.fanuc_like import DH_YAML, TARGETS, Campaign

AMPLITUDE = 1.2e-4  # rad, two cycles per revolution of joint 1 (a strain-wave gear's ellipticity)


class GearCampaign(Campaign):
    """The FANUC-like robot with a periodic transmission error of joint 1: ``q1 + A sin(2 q1 + 0.4)``."""

    def flange(self, q: np.ndarray) -> np.ndarray:
        q = np.array(q, dtype=float)
        q[0] += AMPLITUDE * math.sin(2.0 * q[0] + 0.4)
        return super().flange(q)


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    path = tmp_path_factory.mktemp("fanuc") / "fanuc_like.dh.yaml"
    path.write_text(DH_YAML)
    mech = import_robot(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return mech, analyze(mech, n_configurations=24, seed=0)


def diagnose_texts(robot, text_id: str, text_val: str):
    """Diagnose two measurement files given as text with ``robot = (mechanism, analysis)``."""
    mech, analysis = robot
    data = parse_measurements(text_id, mech, "id.csv")
    val = parse_measurements(text_val, mech, "val.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return diagnose(mech, analysis, data, val)


def test_three_reflectors_diagnosed_in_one_run(robot):
    """36 poses with 3 SMRs each (24 to identify, 12 held out): one answer for the robot, and each SMR alone
    tells the same story."""
    c = GearCampaign(5)
    d = diagnose_texts(robot, c.csv(c.poses(24), "P"), c.csv(c.poses(12), "V"))
    assert d.outcome == "explained" and d.named_effects == ["angle-harmonic-2"]
    assert len(d.rigid.residuals) == 72  # every (pose, SMR) observation in the one fit
    assert [t["target"] for t in d.per_target] == list(TARGETS)
    assert d.targets_agree is True and "same story" in d.targets_evidence
    # the amplitude on joint 1 comes back from the three reflectors together (within 25 %)
    amp = np.hypot(*[p["estimate"] for p in d.effect_parameters if p["name"].startswith("harmonic2_1_")])
    assert amp == pytest.approx(AMPLITUDE, rel=0.25)
    assert d.validation_after["rms"] < d.validation_before["rms"]
    doc = d.to_dict()
    assert doc["targets_agree"] is True and [t["target"] for t in doc["per_target"]] == list(TARGETS)
    assert all({"target", "outcome", "named_effects"} <= set(t) for t in doc["per_target"])


def test_a_reflector_that_tells_another_story_is_reported():
    """The check per target compares stories, not sizes: another effect named by one target disagrees; a target
    that finds less with a third of the data does not."""
    from hyperstat.solver.diagnosis.targets import targets_agree

    whole = {"outcome": "explained", "named_effects": ["angle-harmonic-2"],
             "equivalence_sets": [{"members": ["angle-harmonic-2", "angle-scale"]}]}
    same = [{"target": "A", "outcome": "explained", "named_effects": ["angle-scale"]},
            {"target": "B", "outcome": "unexplained", "named_effects": []}]
    ok, words = targets_agree(whole, same)
    assert ok and "target B: unexplained" in words
    other = same + [{"target": "C", "outcome": "partly explained", "named_effects": ["compliance"]}]
    ok, words = targets_agree(whole, other)
    assert not ok and "target C names compliance" in words


def test_six_d_rows_are_diagnosed_as_three_points_of_the_target_frame(robot):
    """6-D measurements (one SMR with its orientation): a position and an orientation row per pose in one fit; the
    check per target reads three points of the target frame, each weighted by the position and orientation noise."""
    from hyperstat.solver.calibration.measurements import parse_measurements
    from hyperstat.solver.diagnosis.targets import as_points

    c = GearCampaign(6)
    sigma_rad = 5e-5

    def six_d(q, prefix):
        lines = ["# hyperstat measurements, version 1", "# mechanism: fanuc_like",
                 f"# noise: {c.noise[0]} mm + {c.noise[1]} mm/m", f"# orientation noise: {sigma_rad} rad",
                 "pose," + ",".join(f"J{i}[deg]" for i in range(1, 7))
                 + ",x[mm],y[mm],z[mm],quat_w,quat_x,quat_y,quat_z"]
        for i, qi in enumerate(q):
            p, quat = c.measure_pose(qi, "SMR1", sigma_rad)
            lines.append(",".join([f"{prefix}{i + 1}"] + [repr(float(v)) for v in c.controller(qi)]
                                  + [repr(float(v)) for v in p] + [repr(float(v)) for v in quat]))
        return "\n".join(lines) + "\n"

    mech, _ = robot
    text = six_d(c.poses(30), "P")
    data = parse_measurements(text, mech, "id.csv")
    points = as_points(data)
    assert len(points) == 3 * len(data) and points.target_names == ["T.o", "T.x", "T.y"]
    lever = points.lever_mm
    # the x point sits at the lever along the target frame's x axis, with the noise of both measurements
    np.testing.assert_allclose(np.linalg.norm(points.position[1::3] - points.position[0::3], axis=1), lever)
    sigma_p = data.noise.sigma(np.linalg.norm(data.position, axis=1))
    np.testing.assert_allclose(points.row_sigma[1::3], np.sqrt(sigma_p**2 + 2 / 3 * (lever * sigma_rad) ** 2))
    d = diagnose_texts(robot, text, six_d(c.poses(12), "V"))
    assert d.outcome == "explained" and d.named_effects == ["angle-harmonic-2"]
    assert [t["target"] for t in d.per_target] == ["T.o", "T.x", "T.y"] and d.targets_agree
