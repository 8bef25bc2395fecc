"""Closure residuals, screw Jacobians against finite differences, assembly."""

import numpy as np
import pytest

from hyperstat.solver import AssemblyError, Kinematics, MechanismBuilder
from hyperstat.solver.kinematics.frames import so3_log

H = 1e-6


def _twist(t0, t1):
    return np.r_[so3_log(t1[:3, :3] @ t0[:3, :3].T), t1[:3, 3] - t0[:3, 3]]


def test_assembly_closes_the_slider_crank_everywhere(slider_crank):
    kin = Kinematics(slider_crank)
    qa = np.linspace(-3.0, 3.0, 13)[:, None]
    res = kin.solve(qa)
    assert res.converged.all()
    assert res.residual.max() < 1e-9
    # closed form of the slider travel: x4 = L1 cos t1 + sqrt(L2^2 - (L1 sin t1)^2) + L3 - L4
    p = slider_crank.metadata["parameters"]
    x4 = p["L1"] * np.cos(qa[:, 0]) + np.sqrt(p["L2"] ** 2 - (p["L1"] * np.sin(qa[:, 0])) ** 2) + p["L3"] - p["L4"]
    assert np.allclose(res.q[:, 3], x4, atol=1e-9)


@pytest.mark.parametrize("nonzero_defects", [False, True])
def test_jacobians_match_finite_differences(slider_crank, nonzero_defects):
    kin = Kinematics(slider_crank)
    q = kin.solve(np.array([[0.7]])).q[0]
    rng = np.random.default_rng(3)
    xi = rng.normal(0, 1e-2, kin.n_xi) if nonzero_defects else np.zeros(kin.n_xi)
    if nonzero_defects:  # reassemble so that the closure rows are comparable
        q = kin.assemble(q[None], xi).q[0]
    st = kin.evaluate(q[None], xi)
    for j in range(kin.n_xi):
        e = np.zeros(kin.n_xi)
        e[j] = H
        sp, sm = kin.evaluate(q[None], xi + e, False), kin.evaluate(q[None], xi - e, False)
        fd_out = (_twist(st.output_pose[0], sp.output_pose[0]) - _twist(st.output_pose[0], sm.output_pose[0])) / (2 * H)
        assert np.allclose(fd_out, st.output_xi[0, :, j], atol=1e-6), slider_crank.parameters[j].name
        if not nonzero_defects:
            fd = (sp.residual[0] - sm.residual[0]) / (2 * H)
            assert np.allclose(fd, st.closure_xi[0, :, j], atol=1e-6), slider_crank.parameters[j].name
    for j in range(kin.n_q):
        dq = np.zeros(kin.n_q)
        dq[j] = H
        sp, sm = kin.evaluate((q + dq)[None], xi, False), kin.evaluate((q - dq)[None], xi, False)
        fd_out = (_twist(st.output_pose[0], sp.output_pose[0]) - _twist(st.output_pose[0], sm.output_pose[0])) / (2 * H)
        assert np.allclose(fd_out, st.output_q[0, :, j], atol=1e-6)


def test_non_closing_home_is_a_clear_error():
    b = MechanismBuilder("broken")
    b.revolute("1", (0, 0, 0), (0, 0, 1), role="actuated", defects="", home=0.0)
    b.revolute("2", (100, 0, 0), (0, 0, 1), home=0.0)
    b.prismatic("3", (0, 50, 0), (1, 0, 0), home=0.0)
    b.chain("a", "R0", "F", ["1", "2"])
    b.chain("b", "R0", "F", ["3"])
    m = b.build()
    # the builder closes the loop at home by construction; break it by moving the slide
    import dataclasses

    ch = m.chains[1]
    j3 = ch.elements[0]
    moved = dataclasses.replace(j3, placement=dataclasses.replace(j3.placement, origin=(0.0, 55.0, 0.0)))
    m2 = dataclasses.replace(m, chains=(m.chains[0], dataclasses.replace(ch, elements=(moved,) + ch.elements[1:])))
    with pytest.raises(AssemblyError, match=r"does not close at its home configuration: loop 'b -> F' misses by 5 mm"):
        Kinematics(m2).check_home()


def test_an_assembly_given_its_machines_element_matrices_is_the_same_bit_for_bit(slider_crank, slider_crank_analysis):
    """``assemble(_elements=...)`` (the simulated calibrations compute each machine's element matrices once): the
    same configurations and poses as an assembly that computes them, for all rows and for a subset of them."""
    from hyperstat.solver.kinematics.closure import _element_rows

    kin = Kinematics(slider_crank)
    q0 = kin.solve(np.linspace(-2.5, 2.5, 9)[:, None]).q
    basis = slider_crank_analysis.admissible_basis  # admissible defects (dimensionless): the machines close
    xi = (np.random.default_rng(5).normal(0.0, 1e-4, (len(q0), basis.shape[1])) @ basis.T) * kin.parameter_scale
    elements = kin._all_element_matrices(xi)
    alone, given = kin.assemble(q0, xi), kin.assemble(q0, xi, _elements=elements)
    assert alone.converged.all() and np.abs(xi).max() > 1e-3  # machines that close, with defects of 1e-4 and more
    assert np.array_equal(alone.q, given.q) and np.array_equal(alone.output_pose, given.output_pose)
    rows = np.array([1, 4, 6])
    part = kin.assemble(q0[rows], xi[rows], _elements=_element_rows(elements, rows, len(q0)))
    assert np.array_equal(part.q, kin.assemble(q0[rows], xi[rows]).q)


def test_each_machines_element_matrices_repeated_to_its_rows_are_the_same_bit_for_bit(tripteor):
    """The simulated calibrations compute each machine's element matrices (and the axis tilts' velocities of the
    Jacobians) once and repeat them to the machine's configurations (issue 39): the same matrices, extras and
    Jacobians as computed for every row, and an evaluation without the tilt velocities computes the same ones."""
    from hyperstat.solver.kinematics.closure import _element_rows, _with_tilt_velocities

    kin = Kinematics(tripteor)
    rng = np.random.default_rng(3)
    machines = rng.normal(0.0, 1e-3, (4, kin.n_xi)) * kin.parameter_scale
    k = 5
    xi = np.repeat(machines, k, axis=0)
    q = np.tile(tripteor.home, (len(xi), 1)) + rng.normal(0.0, 0.05, (len(xi), kin.n_q))
    every = kin._all_element_matrices(xi)
    once = _element_rows(kin._all_element_matrices(machines), np.repeat(np.arange(len(machines)), k), len(machines))
    assert every[0].keys() == once[0].keys() and all(np.array_equal(every[0][key], once[0][key]) for key in every[0])
    assert all(np.array_equal(every[1][key][name], once[1][key][name]) for key in every[1] for name in every[1][key])
    tilted = _element_rows(_with_tilt_velocities(kin, kin._all_element_matrices(machines)),
                           np.repeat(np.arange(len(machines)), k), len(machines))
    assert any("w_par" in extra for extra in tilted[1].values())
    plain, given = kin.evaluate(q, xi, jacobians=True), kin.evaluate(q, xi, jacobians=True, _elements=tilted)
    for name in ("residual", "closure_xi", "closure_q", "output_pose", "output_xi", "output_q"):
        assert np.array_equal(getattr(plain, name), getattr(given, name)), name
    assert np.abs(plain.closure_xi).max() > 0.1


def test_the_actuation_jacobians_are_those_of_the_full_evaluation_bit_for_bit(tripteor):
    """``evaluate(jacobians="actuation")`` (the compensation's Newton steps, the task's dead centres: issue 39) gives the
    joints' closure rows and the output's joint rows of ``jacobians=True`` to the bit, without the defects' columns:
    per-configuration defects (the element-by-element pass) and the nominal machine (the batched plan)."""
    from hyperstat.solver.tolerances.accuracy import output_twist_maps

    kin = Kinematics(tripteor)
    rng = np.random.default_rng(11)
    q = tripteor.home[None, :] + rng.normal(0.0, 0.05, (6, kin.n_q))  # the rows are defined off the closure too
    xi = rng.normal(0.0, 1e-3, (6, kin.n_xi)) * kin.parameter_scale
    for defects in (xi, None):
        full, lean = kin.evaluate(q, defects, jacobians=True), kin.evaluate(q, defects, jacobians="actuation")
        assert lean.closure_xi is None and lean.output_xi is None and full.closure_xi is not None
        for a, b in ((full.closure_q, lean.closure_q), (full.output_q, lean.output_q), (full.residual, lean.residual),
                     (full.output_pose, lean.output_pose), (output_twist_maps(kin, full)[1], output_twist_maps(kin, lean)[1])):
            assert np.array_equal(a, b)
        assert output_twist_maps(kin, lean)[0] is None and np.abs(full.output_q).max() > 0.1


def test_chord_steps_with_the_nominal_inverse_reach_the_gauss_newton_fixed_points():
    """``assemble(_inverse=...)`` (the simulated calibrations' assemblies, issue 39): chord steps with the nominal
    machine's passive inverse instead of a Jacobian and a solve per iteration.  On the hexapod (a square passive map)
    with per-configuration defects of 1e-3 of the scale, from the nominal configurations, the configurations reached
    are Gauss-Newton's to the round-off (measured: 1.9e-15 of the joint scale; Gauss-Newton itself from starts moved
    by 1e-15: 1.1e-15), every row closes, and nearly no Jacobian was evaluated.  An over-constrained map (the
    Tripteor's 12 rows, 10 passive joints) ignores the inverse: the same bits."""
    from hyperstat.cad_plugin.templates import build_template
    from hyperstat.solver.tolerances.calibrated import _damped_inverse

    from tests.conftest import TEMPLATES

    for name, square in (("hexapod.py", True), ("tripteor_x7.py", False)):
        mech = build_template(TEMPLATES / name).mechanism()
        kin = Kinematics(mech)
        act, pas = mech.actuated, mech.passive
        rng = np.random.default_rng(3)
        q0 = np.tile(mech.home, (20, 1)).astype(float)
        q0[:, act] += rng.uniform(-1, 1, (20, len(act))) * 0.05 * kin.joint_scale[act]
        nominal = kin.assemble(q0)
        assert nominal.converged.all()
        st = kin.evaluate(nominal.q, None, "joints")
        inverse = _damped_inverse(kin.scaled_rows(st.closure_q[:, :, pas]))
        xi = rng.normal(0.0, 1e-3, (20, kin.n_xi)) * kin.parameter_scale
        counted = []
        evaluate = kin.evaluate
        kin.evaluate = lambda q, xi=None, jacobians=True, _elements=None: (  # noqa: E731
            counted.append((jacobians, len(q))) or evaluate(q, xi, jacobians, _elements))
        plain = kin.assemble(nominal.q, xi)
        n_plain = sum(n for j, n in counted if j == "joints")
        counted.clear()
        chord = kin.assemble(nominal.q, xi, _inverse=inverse)
        n_chord = sum(n for j, n in counted if j == "joints")
        if not square:
            assert np.array_equal(plain.q, chord.q) and np.array_equal(plain.output_pose, chord.output_pose)
            continue
        assert chord.converged.all() and chord.residual.max() <= 1e-9 * kin.length_scale
        gap = np.abs(plain.q - chord.q)[:, pas] / kin.joint_scale[pas]
        assert gap.max() <= 1e-13, gap.max()
        assert not np.array_equal(plain.q, chord.q)  # the chord ran: another round-off
        assert n_chord <= 0.1 * n_plain, (n_chord, n_plain)
