"""The effects of parallel machines (issue 40, item 4), checked with a generator that shares no code with them.

Units: lengths in mm, angles in rad, masses in kg.  The campaigns come from ``pkm_generator.py`` (its own
model-file parser, loop solver, statics and effects; it imports nothing from hyperstat) on the Tripteor X7
and the hexapod with a declared moving mass; the expected answers are its truth.  The rates over every case
and three seeds are in ``docs/diagnosis.md`` (``hyperstat validate-diagnosis --independent 3 --generator
tests/solver/diagnosis/pkm_generator.py``).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.calibration.measurements import parse_measurements
from hyperstat.solver.diagnosis.diagnose import diagnose
from hyperstat.solver.diagnosis.effects import gravity_moment, make_effect
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.modelfile import load_model

from tests.solver.diagnosis import pkm_generator as gen


@pytest.fixture(scope="module")
def tripteor_model():
    mech = load_model(gen.MODELS["tripteor_x7"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return mech, analyze(mech, n_configurations=24, seed=0), Kinematics(mech)


def _diagnose(model, case: str, seed: int):
    mech, analysis, kin = model
    id_text, val_text, truth = gen.campaign(gen.MODELS[mech.name], case, seed, n_id=60, n_val=20)
    data = parse_measurements(id_text, mech, "id.csv")
    val = parse_measurements(val_text, mech, "val.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return diagnose(mech, analysis, data, val, kinematics=kin, per_target=False), truth


@pytest.mark.parametrize("arm", ["tripteor_x7", "hexapod"])
def test_the_generator_assembles_the_machine_as_hyperstat_does(arm):
    """Two loop solvers of the same model file agree at the nominal geometry (1e-9 mm), the loops closed."""
    mech = load_model(gen.MODELS[arm])
    kin = Kinematics(mech)
    machine = gen.Machine(gen.MODELS[arm], np.random.default_rng(0), errors=0.0)
    lo, hi = mech.ranges[mech.actuated].T
    qa = lo + (hi - lo) * np.random.default_rng(1).uniform(0.2, 0.8, (4, len(lo)))
    q = machine.solve(qa, true=False)
    assert np.abs(machine._closure(q, true=False)).max() < 1e-8
    np.testing.assert_allclose(machine.tool(q, true=False), kin.evaluate(kin.solve(qa).q, None).output_pose, atol=1e-9)


def test_straightness_where_the_machine_does_not_absorb_it(tripteor_model):
    """A hexapod's UPS legs absorb a bowed guide to first order (no parameter is left); the Tripteor keeps one bow per
    leg, across its platform revolute.  The generator's own loop solver agrees: bowing a hexapod leg moves nothing."""
    mech, _, kin = tripteor_model
    assert make_effect("guide-straightness", mech, kin=kin).parameter_names(None) == [
        "straightness_41_y", "straightness_42_x", "straightness_43_y"]
    hexapod = load_model(gen.MODELS["hexapod"])
    assert make_effect("guide-straightness", hexapod).parameter_names(None) == []
    machine = gen.Machine(gen.MODELS["hexapod"], np.random.default_rng(0), errors=0.0)
    lo, hi = hexapod.ranges[hexapod.actuated].T
    q = machine.solve(lo + (hi - lo) * np.random.default_rng(2).uniform(0.3, 0.7, (3, len(lo))), true=False)
    before = machine.tool(q, true=False)[:, :3, 3]
    machine.extra = {"31": gen._bow(machine, "31", q[:, machine.index["31"]], np.array([0.02, 0.02]))}
    after = machine.tool(machine.assemble(q, true=False), true=False)[:, :3, 3]
    assert np.abs(after - before).max() < 1e-5  # mm, against 0.02 mm of bow


def test_the_moment_of_the_moving_mass_is_its_weight_at_its_centre(tripteor_model):
    """``gravity_moment`` of a declared moving mass at the output: ``p x m g`` with ``p`` its centre (closed form)."""
    mech, _, kin = tripteor_model
    q = mech.home[mech.actuated][None, :] + np.array([[0.0, 0.0, 0.0, 0.0, 0.0], [40.0, -30.0, 20.0, 0.5, 0.3]])
    st = kin.evaluate(kin.solve(q).q, None)
    com = np.asarray(mech.metadata["com"], float)
    centre = st.output_pose[:, :3, 3] + np.einsum("kij,j->ki", st.output_pose[:, :3, :3], com)
    mass = mech.metadata["moving_mass"] + np.array([0.0, 25.0])
    expected = np.cross(centre, mass[:, None] * np.array([0.0, 0.0, -9.81]))
    np.testing.assert_allclose(gravity_moment(mech, kin, q, np.array([0.0, 25.0])), expected, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("case, expected", [("leg-thermal", {"leg-thermal", "thermal"}),
                                            ("base-deformation", {"base-deformation"})])
def test_a_parallel_machine_effect_is_named(tripteor_model, case, expected):
    """Leg growth with the temperature (each leg by its own length), the frame tilting under the moving mass: named (or
    in the set the poses cannot separate it from), and the held-out error comes down."""
    d, truth = _diagnose(tripteor_model, case, 0)
    members = {m for s in d.equivalence_sets for m in s["members"]}
    assert d.outcome == "explained" and case in set(d.named_effects) | members
    assert set(d.named_effects) <= expected
    if "joints" in truth and case in d.effect_joints:
        assert set(d.effect_joints[case]) <= set(truth["joints"])
    assert d.validation_after["rms"] < d.validation_before["rms"]
