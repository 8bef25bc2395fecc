"""The nominal twist maps kept per block of configurations are those a fresh evaluation gives, bit for bit.

Units: rad and mm (twists per unit defect and per unit actuated value).  The reference is the evaluation the stages
made before the blocks were kept (issue 39): ``output_twist_maps(kin.evaluate(q, None, jacobians=True))``.
"""

from __future__ import annotations

import numpy as np
import pytest

from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.tolerances.accuracy import output_twist_maps, sample_workspace
from hyperstat.solver.tolerances.twist_blocks import KEPT_ROWS, nominal_twist_maps


def test_a_kept_block_is_the_fresh_evaluation_read_only_and_keyed_by_its_configurations_and_path(tripteor):
    kin = Kinematics(tripteor)
    q = sample_workspace(tripteor, KEPT_ROWS + 6, seed=2, kinematics=kin)
    st = kin.evaluate(q, None, jacobians=True)
    want = (*output_twist_maps(kin, st), st.output_pose)
    first = nominal_twist_maps(kin, q)
    assert all(np.array_equal(a, b) for a, b in zip(first, want)) and np.abs(want[0]).max() > 0
    again = nominal_twist_maps(kin, q.copy())  # the same bytes: the kept arrays
    assert all(a is b for a, b in zip(first, again))
    with pytest.raises(ValueError):
        first[0][0, 0, 0] = 1.0  # read-only: a reader cannot change what the next stage reads
    other = nominal_twist_maps(kin, q[::-1])  # other configurations: their own maps
    assert np.array_equal(other[1], want[1][::-1]) and other[1] is not first[1]
    kin.use_plan = False  # the element-by-element pass: another key, its own evaluation
    try:
        lean = nominal_twist_maps(kin, q)
        st_e = kin.evaluate(q, None, jacobians=True)
        assert lean[0] is not first[0] and np.array_equal(lean[0], output_twist_maps(kin, st_e)[0])
    finally:
        kin.use_plan = True
