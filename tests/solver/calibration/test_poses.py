"""Pose selection: the D-optimal choice beats random subsets and is exchange-optimal (direct determinants)."""

from __future__ import annotations

import warnings

import numpy as np

from hyperstat.solver.calibration.identify import MeasurementModel
from hyperstat.solver.calibration.poses import design_jacobian, select_poses
from hyperstat.solver.calibration.virtual import VirtualMachine


def test_d_optimal_beats_random(tripteor, tripteor_analysis):
    vm = VirtualMachine.random(tripteor, tripteor_analysis, seed=0)
    candidates = vm.poses(300, seed=1)
    model = MeasurementModel(tripteor, tripteor_analysis)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sel = select_poses(model, candidates, 60, noise=vm.noise, random_trials=10)
    assert len(set(sel.index.tolist())) == 60
    # D-optimality maximises the geometric mean of the singular values (O1): it must beat random
    assert sel.observability["O1"] > sel.random_observability["O1"]
    assert sel.condition_number < sel.random_condition_number


def test_choice_is_exchange_optimal(scara, scara_analysis):
    """No single swap of a chosen pose for a candidate increases log det(J^T J + eps I) (direct determinants)."""
    vm = VirtualMachine.random(scara, scara_analysis, seed=0)
    candidates = vm.poses(40, seed=2)
    model = MeasurementModel(scara, scara_analysis)
    sel = select_poses(model, candidates, 10, noise=vm.noise, exchanges=50, random_trials=3)
    jac, base = design_jacobian(model, candidates, vm.noise)

    def logdet(rows):
        info = 1e-6 * np.eye(len(base)) + sum(jac[i].T @ jac[i] for i in rows)
        return np.linalg.slogdet(info)[1]

    best = logdet(sel.index)
    others = [c for c in range(len(candidates)) if c not in set(sel.index.tolist())]
    for pos in range(len(sel.index)):
        for c in others:
            swapped = sel.index.copy()
            swapped[pos] = c
            assert logdet(swapped) <= best + 1e-9
