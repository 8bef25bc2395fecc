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
    #: why the domain is what it is (printed when a candidate is rejected)
    domain_note = "no physical bound"
    #: other physical causes with the same signature (printed with an "explained" answer)
    also_explains = ""

    def __init__(self, names: list[str], units: list[str], magnitude: np.ndarray, lower=None, upper=None,
                 plausible=None, what=None, source: str | list | None = None, groups: list | None = None) -> None:
        self._names = list(names)
        self._units = list(units)
        self.magnitude = np.asarray(magnitude, dtype=float)
        self.truth = np.zeros(len(self._names))
        n = len(self._names)
        #: physical domain of each parameter (the bounded fit stays inside it)
        self.lower = np.full(n, -np.inf) if lower is None else np.broadcast_to(np.asarray(lower, float), (n,)).copy()
        self.upper = np.full(n, np.inf) if upper is None else np.broadcast_to(np.asarray(upper, float), (n,)).copy()
        #: largest plausible absolute value of each parameter (default 50x the realistic magnitude)
        self.plausible = (50.0 * self.magnitude if plausible is None
                          else np.broadcast_to(np.asarray(plausible, float), (n,)).copy())
        #: words for each parameter's prior ("gear harmonic" ...) and the key of its source
        #: (:data:`hyperstat.solver.diagnosis.effects.priors.SOURCES`)
        self.prior_what = [what or "magnitude"] * n if what is None or isinstance(what, str) else list(what)
        self.prior_source = [source or "none stated"] * n if source is None or isinstance(source, str) \
            else list(source)
        #: parameters whose joint norm is the physical magnitude (a harmonic's sin and cos: its amplitude)
        self.groups = [[j] for j in range(n)] if groups is None else [list(g) for g in groups]

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
        """Draw realistic true parameters: magnitude times a random sign and a factor in [0.6, 1].

        The sign is flipped where the drawn value would leave the physical domain
        (a compliance or a backlash is never negative).
        """
        signs = rng.choice([-1.0, 1.0], size=self.magnitude.shape)
        values = self.magnitude * signs * rng.uniform(0.6, 1.0, size=self.magnitude.shape)
        outside = (values < self.lower) | (values > self.upper)
        values[outside] = -values[outside]
        return self.with_truth(values)

    def plausibility(self, estimate: np.ndarray, std: np.ndarray, sigmas: float = 3.0) -> str | None:
        """Why an estimate is physically implausible (None when it is plausible).

        A parameter more than ``sigmas`` standard deviations beyond a bound of its domain
        (``lower``, ``upper``), or a group's magnitude (a harmonic's amplitude) more than
        ``sigmas`` standard deviations beyond its plausible bound (:mod:`.priors`), rejects
        the effect; the sentence says by how much and cites the prior's source.
        """
        from hyperstat.solver.diagnosis.effects.priors import prior_sentence

        names, units = self.parameter_names(None), self.parameter_units(None)
        estimate = np.asarray(estimate, float)
        std = np.where(np.isfinite(std), np.asarray(std, float), 0.0)
        for j, (e, s) in enumerate(zip(estimate, std)):
            for bound, side in ((self.lower[j], -1.0), (self.upper[j], 1.0)):
                if np.isfinite(bound) and side * (e - bound) > sigmas * s:
                    sig = side * (e - bound) / s if s > 0 else np.inf
                    return (f"the data ask for {names[j]} = {e:.3g} {units[j]}, {sig:.0f} std "
                            f"{'below' if side < 0 else 'above'} its physical bound {bound:g} "
                            f"({self.domain_note}); fitted within its domain it sits at the bound")
        for g in self.groups:
            size = float(np.linalg.norm(estimate[g]))
            spread = float(np.sqrt(np.mean(std[g] ** 2)))
            bound = float(np.max(self.plausible[g]))
            if size - sigmas * spread > bound:
                name = names[g[0]] if len(g) == 1 else names[g[0]].rsplit("_", 1)[0] + " (amplitude)"
                return (prior_sentence(name, size, units[g[0]], bound, self.prior_what[g[0]], self.prior_source[g[0]])
                        + f"; {self.domain_note}")
        return None

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
