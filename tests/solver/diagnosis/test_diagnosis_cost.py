"""What the diagnosis of a parallel machine costs, and what it must not recompute (issue 40: the hexapod).

Units: lengths in mm, angles in rad.  The campaigns come from the project's generators
(``independent_generator.py``, ``pkm_generator.py``: their own parsers, kinematics and effects; they import
nothing from hyperstat).  No timing is asserted: the tests check that work whose result the diagnosis never
reads is not done, and that the answer is the same without it; the times are in ``docs/diagnosis.md``
("Speed") and ``benchmarks/diagnose_hexapod.py``.
"""

from __future__ import annotations

import warnings

import numpy as np

from hyperstat.solver.analysis.stationarity import analyze
from hyperstat.solver.calibration.identify import identify
from hyperstat.solver.calibration.measurements import parse_measurements
from hyperstat.solver.diagnosis.diagnose import diagnose
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.modelfile import load_model

from tests.solver.diagnosis import independent_generator as gen


def test_the_diagnosis_does_not_refit_the_rigid_model_to_name_outliers():
    """One identification point off by 0.4 mm (80x the noise): ``identify`` flags it and, to say which points are
    outliers, fits the whole model again without it (``without_outliers``).  The diagnosis reads neither the flags nor
    that second fit (its answer comes from the fit itself), so it must not pay for it: on the hexapod that second fit
    was half of the rigid fit's CPU time (70 of 124 s at 107 poses).  The rigid fit the diagnosis uses is the same
    fit, to the last digit."""
    mech = load_model(gen.SCARA)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        analysis = analyze(mech, n_configurations=24, seed=0)
        kin = Kinematics(mech)
        id_text, val_text, _ = gen.campaign(gen.SCARA, "none", 0)
        data = parse_measurements(id_text, mech, "id.csv")
        val = parse_measurements(val_text, mech, "val.csv")
        data.position[5, 0] += 0.4  # mm: a gross error on one point
        full = identify(mech, analysis, data, val, kinematics=kin)
        d = diagnose(mech, analysis, data, val, kinematics=kin, per_target=False)
    assert full.without_outliers is not None  # the calibration's own check names the outlier (a second fit)
    assert d.rigid.without_outliers is None  # the diagnosis skipped that second fit ...
    np.testing.assert_array_equal(d.rigid.theta, full.theta)  # ... and fitted the same model
    assert d.rigid.sigma == full.sigma and d.rigid.rank == full.rank
