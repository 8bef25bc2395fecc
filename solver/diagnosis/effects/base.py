"""Base class of the unmodelled effects that extend the rigid geometric model.

Units: lengths in mm, angles in rad, temperatures in degC, masses in kg, forces in N.

An effect is a small parametric extension that enters the kinematics at one of four
places of :meth:`hyperstat.solver.calibration.identify.MeasurementModel.predict`:

* the actuated joint values (``actuator_correction``: screw pitch and periodic errors,
  backlash, compliance of the actuated joints),
* the defect vector (``defect_directions``: a violated forced defect),
* the target position in the base frame (``output_correction``: thermal expansion),
* the tracker reading (``measurement_correction``: tracker scale, drift between sessions).

Each returns its value and its derivative with respect to its own parameters, so the
effect is identified together with the geometry by the same Levenberg-Marquardt fit and
exported to the controller file with it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Effect"]


class Effect:
    """An unmodelled effect with parameters (subclasses override the hooks they use).

    Attributes
    ----------
    name : str
        One of ``compliance``, ``violated-constraint``, ``thermal``, ``screw-pitch``,
        ``screw-periodic``, ``backlash``, ``tracker-scale``, ``tracker-drift``.
    truth : ndarray
        True parameter values when the effect is part of a virtual machine (zeros otherwise).
    requires : tuple of str
        Metadata columns the effect needs (``dir*`` stands for one per actuator).
    """

    name = "effect"
    requires: tuple = ()

    def __init__(self, names: list[str], units: list[str], magnitude: np.ndarray) -> None:
        self._names = list(names)
        self._units = list(units)
        self.magnitude = np.asarray(magnitude, dtype=float)
        self.truth = np.zeros(len(self._names))

    # -------------------------------------------------------------- parameters
    def parameter_names(self, model) -> list[str]:
        """Names of the effect's parameters (prefixed by the effect name)."""
        return list(self._names)

    def parameter_units(self, model) -> list[str]:
        """Units of the parameters."""
        return list(self._units)

    def initial(self, model) -> np.ndarray:
        """Prior value of the parameters (zero: no effect)."""
        return np.zeros(len(self._names))

    def with_truth(self, values: np.ndarray) -> "Effect":
        """Set the true parameters (for a virtual machine); returns ``self``."""
        values = np.asarray(values, dtype=float)
        if values.shape != self.truth.shape:
            raise ValueError(f"{self.name}: {values.size} values for {self.truth.size} parameters")
        self.truth = values
        return self

    def draw_truth(self, rng: np.random.Generator) -> "Effect":
        """Draw realistic true parameters: magnitude times a random sign and a factor in [0.6, 1]."""
        signs = rng.choice([-1.0, 1.0], size=self.magnitude.shape)
        return self.with_truth(self.magnitude * signs * rng.uniform(0.6, 1.0, size=self.magnitude.shape))

    # -------------------------------------------------------------- hooks
    def actuator_correction(self, model, theta: np.ndarray, data):
        """``(dq (K, n_act), d dq / d theta (K, n_act, n_e))`` added to the actuated values, or None."""
        return None

    def defect_directions(self, model):
        """``(n_xi, n_e)`` matrix: defects added to the geometry are ``directions @ theta``, or None."""
        return None

    def output_correction(self, model, theta, data, q, state, world, jacobian):
        """``(dp (K, 3), d dp / d theta (K, 3, n_e))`` added to the target in the base frame, or None."""
        return None

    def measurement_correction(self, model, theta, data, position, jacobian):
        """``(new position, d new / d theta (K, 3, n_e), d new / d position (K, 3, 3))``, or None."""
        return None

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(self._names)})"
