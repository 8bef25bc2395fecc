"""The batched forward path (hyperstat.solver.kinematics.fastfk) against independent computations (units: mm, rad).

* a plain loop of 4x4 products ``D_1 M_1(q_1) ... D_n M_n(q_n)`` per configuration (eq. 2),
  with ``M`` from ``cos``/``sin`` (the batched path uses ``tan(q/2)`` and complex numbers);
* central finite differences of the nonlinear pose for the Jacobians;
* the element-by-element path of ``Kinematics.evaluate`` on the templates, at a non-zero
  defect vector.
"""

import numpy as np
import pytest

from hyperstat.solver import Kinematics, MechanismBuilder
from hyperstat.solver.kinematics.frames import motion_matrix, so3_log
from hyperstat.solver.kinematics.model import Joint


def _random_chain(seed: int, types: str):
    """A serial chain of random joints (random axes and points), a fixed tool with defects."""
    rng = np.random.default_rng(seed)
    b = MechanismBuilder(f"random{seed}")
    names = []
    for i, typ in enumerate(types):
        axis = rng.normal(size=3)
        point = rng.uniform(-300, 300, 3)
        name = str(i + 1)
        if typ == "R":
            b.revolute(name, point, axis, role="actuated", range=(-4.0, 4.0))
        else:
            b.prismatic(name, point, axis, role="actuated", range=(-200.0, 200.0))
        names.append(name)
    b.fixed("tool", rng.uniform(-300, 300, 3), rng.normal(size=3), defects="IJKabcG")
    b.chain("arm", "R0", "T", names + ["tool"])
    b.output = "T"
    return b.build()


def _loop_fk(kin: Kinematics, xi, q):
    mats = kin.element_matrices(xi)
    out = np.empty((len(q), 4, 4))
    for k, qk in enumerate(q):
        t = np.eye(4)
        for ei, el in enumerate(kin.mechanism.chains[0].elements):
            t = t @ mats[(0, ei)]
            if isinstance(el, Joint):
                t = t @ motion_matrix(el.type, qk[kin.mechanism.joint_index[el.name]])
        out[k] = t
    return out


@pytest.mark.parametrize("seed,types", [(0, "RRRRRR"), (1, "RPRRPR"), (2, "PPR"), (3, "R")])
def test_batched_pose_equals_a_loop_of_matrix_products(seed, types):
    mech = _random_chain(seed, types)
    kin = Kinematics(mech)
    rng = np.random.default_rng(seed + 10)
    xi = rng.normal(0.0, 1e-2, kin.n_xi)
    q = rng.uniform(-4.0, 4.0, (300, kin.n_q))
    q[:, [j for j, jt in enumerate(mech.joints) if jt.type == "P"]] *= 50.0
    # angles where tan(q/2) is 0, huge or periodic
    q[:6, 0] = [0.0, np.pi, -np.pi, 3 * np.pi, 1e-12, 2 * np.pi - 1e-9]
    pose, _ = kin.forward(q, xi)
    ref = _loop_fk(kin, xi, q)
    assert np.max(np.abs(pose - ref)) < 1e-9 * kin.length_scale


@pytest.mark.parametrize("seed,types", [(4, "RRRRRR"), (5, "RPRPR")])
def test_batched_jacobian_equals_finite_differences(seed, types):
    mech = _random_chain(seed, types)
    kin = Kinematics(mech)
    rng = np.random.default_rng(seed)
    xi = rng.normal(0.0, 1e-2, kin.n_xi)
    q = rng.uniform(-3.0, 3.0, (5, kin.n_q))
    pose, jac = kin.forward(q, xi, jacobian=True)
    h = 1e-6
    for j in range(kin.n_q):
        dq = np.zeros(kin.n_q)
        dq[j] = h
        plus, _ = kin.forward(q + dq, xi)
        minus, _ = kin.forward(q - dq, xi)
        w = (so3_log(plus[:, :3, :3] @ np.swapaxes(pose[:, :3, :3], 1, 2))
             - so3_log(minus[:, :3, :3] @ np.swapaxes(pose[:, :3, :3], 1, 2))) / (2 * h)
        v = (plus[:, :3, 3] - minus[:, :3, 3]) / (2 * h)
        assert np.allclose(jac[:, :3, j], w, atol=1e-6)
        assert np.allclose(jac[:, 3:, j], v, atol=1e-6 * kin.length_scale)


def test_chunks_and_threads_do_not_change_the_result():
    mech = _random_chain(6, "RRPRRR")
    kin = Kinematics(mech)
    q = np.random.default_rng(6).uniform(-3, 3, (1001, kin.n_q))
    plan = kin.plan()
    one = plan.run(q, joint_twists=True, threads=1, jacobian_at="T")
    many = plan.run(q, joint_twists=True, chunk=7, threads=2, jacobian_at="T")
    for name in one.frames:
        assert np.allclose(one.frames[name], many.frames[name], rtol=0, atol=1e-10)
    assert np.allclose(one.joint_twists, many.joint_twists, rtol=0, atol=1e-10)
    assert np.allclose(one.jacobian, many.jacobian, rtol=0, atol=1e-10)


@pytest.mark.parametrize("fixture", ["slider_crank", "tripteor", "scara"])
def test_batched_and_element_by_element_paths_agree_on_templates(fixture, request):
    mech = request.getfixturevalue(fixture)
    kin = Kinematics(mech)
    rng = np.random.default_rng(7)
    from hyperstat.solver.kinematics.closure import PLAN_BATCH

    q = mech.home + rng.normal(0.0, 0.3, (PLAN_BATCH, kin.n_q))  # a batch this large takes the plan
    xi = rng.normal(0.0, 1e-3, kin.n_xi)
    fast = kin.evaluate(q, xi, jacobians="joints")
    full = kin.evaluate(q, xi, jacobians=True)  # the plan's parent frames and the defect screws of one geometry
    kin.use_plan = False
    slow = kin.evaluate(q, xi, jacobians="joints")
    slow_full = kin.evaluate(q, xi, jacobians=True)  # element by element
    tol = 1e-10 * kin.length_scale
    for field in ("residual", "closure_xi", "closure_q", "output_xi", "output_q", "defect_twists"):
        assert np.allclose(getattr(full, field), getattr(slow_full, field), rtol=0, atol=tol), field
    assert np.allclose(fast.residual, slow.residual, rtol=0, atol=tol)
    assert np.allclose(fast.closure_q, slow.closure_q, rtol=0, atol=tol)
    assert np.allclose(fast.output_pose, slow.output_pose, rtol=0, atol=tol)
    for name in slow.frames:
        assert np.allclose(fast.frames[name], slow.frames[name], rtol=0, atol=tol), name
    for key in slow.element_frames:  # computed on demand for the batched state
        assert np.allclose(fast.element_frames[key], slow.element_frames[key], rtol=0, atol=tol)
    pose, jac = Kinematics(mech).forward(q, xi, jacobian=True)
    assert np.allclose(pose, full.output_pose, rtol=0, atol=tol)
    assert np.allclose(jac, full.output_q, rtol=0, atol=tol)


def test_flop_count_of_a_6r_chain():
    kin = Kinematics(_random_chain(8, "RRRRRR"))
    # first D is copied from the base; 5 more products by D, 6 rotations, the tool product
    assert kin.plan().flops_per_configuration() == {"flops": 5 * 63 + 6 * 18 + 63, "trig_pairs": 6}


def test_few_configurations_are_walked_many_planned_with_the_same_answer(tripteor):
    """A defect vector at a few configurations is evaluated element by element (building its plan would cost more),
    at many on its plan; the choice depends on the call only (the same call gives the same bits whatever ran
    before), and both paths give the same state to round-off."""
    from hyperstat.solver.kinematics.closure import PLAN_BATCH

    kin = Kinematics(tripteor)
    rng = np.random.default_rng(3)
    q = tripteor.home + rng.normal(0.0, 0.2, (PLAN_BATCH, kin.n_q))
    xi = rng.normal(0.0, 1e-3, kin.n_xi)
    few = kin.evaluate(q[:3], xi, jacobians=True)
    assert len(kin._plans) == 1  # the nominal geometry's only (built for the length scale)
    many = kin.evaluate(q, xi, jacobians=True)
    assert len(kin._plans) == 2
    again = kin.evaluate(q[:3], xi, jacobians=True)  # its plan exists now: still walked, the same bits
    tol = 1e-10 * kin.length_scale
    for field in ("residual", "closure_xi", "closure_q", "output_pose", "output_xi", "output_q", "defect_twists"):
        assert np.allclose(getattr(few, field), getattr(many, field)[:3], rtol=0, atol=tol), field
        assert np.array_equal(getattr(few, field), getattr(again, field)), field


@pytest.mark.parametrize("fixture", ["slider_crank", "tripteor"])
def test_rows_on_each_loops_members_are_the_dense_rows_bit_for_bit(fixture, request, monkeypatch):
    """The closure and output rows computed on each loop's member columns only (issue 39: the hexapod's sparse
    memberships) are the dense rows, bit for bit, on both paths (one geometry, and per-configuration defects)."""
    import hyperstat.solver.kinematics.closure as closure

    mech = request.getfixturevalue(fixture)
    kin = Kinematics(mech)
    rng = np.random.default_rng(11)
    q = mech.home + rng.normal(0.0, 0.2, (40, kin.n_q))
    xi = rng.normal(0.0, 1e-3, (40, kin.n_xi))
    fields = ("closure_xi", "closure_q", "output_xi", "output_q")
    states = []
    for share in (1.0, -1.0):  # every membership as runs, then none
        monkeypatch.setattr(closure, "SPARSE_MEMBERS", share)
        monkeypatch.setattr(closure, "_RUNS", {})
        states.append([getattr(kin.evaluate(q, x, jacobians=True), f) for x in (None, xi) for f in fields])
        if share > 0:
            assert any(runs is not None for runs in closure._RUNS.values())  # the member runs were taken
    for sparse, dense in zip(*states):
        assert np.array_equal(sparse, dense)
