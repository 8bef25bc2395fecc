"""The rows the diagnosis works on: one per position measurement, and one per orientation measurement (6-D).

Units: position rows in mm (weights 1/mm), orientation rows in rad (weights 1/rad).

Every test of the diagnosis is a weighted least-squares statement about rows of three
components with a scalar weight.  A 3-D measurement is one row (the target's position,
weight ``1 / sigma(distance)`` from the file's noise model); a 6-D measurement is two
independent rows: its position and its orientation error ``log(R_pred R_meas^T)`` (weight
``1 / orientation noise``), with the model's rotation Jacobian.  Position and orientation
noises are independent, so the rows stay independent (a chi-square of ``3 x rows - rank``
degrees of freedom, F-tests as for positions).  The joint values and metadata of a pose
are repeated on its orientation row (:func:`row_view`).
"""

from __future__ import annotations

import numpy as np

from hyperstat.solver.calibration.identify import _weights, orientation_residual
from hyperstat.solver.calibration.measurements import MeasurementSet

__all__ = ["oriented", "row_view", "residual_rows", "stack_rows"]


def oriented(model, data: MeasurementSet | None) -> bool:
    """Whether ``data`` brings orientation rows for ``model`` (6-D measurements and a 6-D model)."""
    return bool(data is not None and data.rotation is not None and getattr(model, "orientation", False)
                and data.rotation_noise)


def row_view(data: MeasurementSet, with_orientation: bool) -> MeasurementSet:
    """``data`` with its poses repeated once more for the orientation rows (positions first)."""
    if not with_orientation:
        return data
    k = len(data)
    return data.subset(np.r_[np.arange(k), np.arange(k)])


def stack_rows(position: np.ndarray, rotation: np.ndarray | None) -> np.ndarray:
    """Position rows then orientation rows (the first axis), or the position rows alone."""
    return position if rotation is None else np.concatenate([position, rotation], axis=0)


def residual_rows(model, theta: np.ndarray, data: MeasurementSet, jacobian: bool = False,
                  q_start: np.ndarray | None = None):
    """Residual rows (prediction - measurement), their weights, their Jacobian (or None), and the prediction.

    Returns
    -------
    resid : ndarray, (R, 3)
        Position rows (mm) then, for 6-D data, orientation rows (rad).
    w : ndarray, (R,)
        1 / sigma of each row.
    jac : ndarray, (R, 3, n) or None
        ``d resid / d theta``.
    prediction : Prediction
        The model's prediction at the poses of ``data``.
    """
    pred = model.predict(theta, data, jacobian=jacobian, q_start=q_start)
    resid = pred.position - data.position
    w = _weights(data)
    jac = pred.jacobian
    if oriented(model, data) and pred.rotation is not None:
        resid = stack_rows(resid, orientation_residual(pred.rotation, data))
        w = stack_rows(w, np.full(len(data), 1.0 / data.rotation_noise))
        if jacobian:
            jac = stack_rows(jac, pred.rotation_jacobian)
    return resid, w, jac, pred
