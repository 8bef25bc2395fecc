"""Authoring API for skeletons: joints as marker frames, links, chains (paper 1, Fig. 1).

Units: lengths in mm, angles in rad.

A template builds a :class:`Skeleton` at the mechanism's *home* configuration in
world coordinates: each joint by a point of its axis and the axis direction (the
frame ``L_i``), configuration frames (base, platform, tool) by an origin and two
axes, links as bars between named points.  The skeleton turns into

* the solver's :class:`~hyperstat.solver.kinematics.model.Mechanism` (:meth:`Skeleton.mechanism`), through
  :class:`hyperstat.solver.kinematics.build.MechanismBuilder`, and
* a CadQuery assembly with one marker (a small x/y/z triad) per joint frame and per
  configuration frame, and the link solids (:func:`hyperstat.cad_plugin.assembly.build_assembly`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from hyperstat.solver.kinematics.build import MechanismBuilder
from hyperstat.solver.kinematics.model import Mechanism

__all__ = ["Skeleton", "Link", "MATERIALS"]

#: densities (kg/m^3) of common structural materials, by name (:meth:`Skeleton.material`)
MATERIALS = {"steel": 7850.0, "stainless steel": 8000.0, "cast iron": 7200.0, "aluminium": 2700.0,
             "titanium": 4500.0, "carbon fibre composite": 1600.0}


@dataclass
class Link:
    """A link drawn as straight bars through points (joint names or coordinates), mm."""

    name: str
    points: tuple
    radius: float
    body: str | None = None  # the joint whose moving body this link is part of (for its mass)


class Skeleton(MechanismBuilder):
    """A mechanism skeleton: declarations in world coordinates at the home configuration.

    Parameters
    ----------
    name : str
        Mechanism name (also the assembly name).
    base : str
        Name of the base frame (the world frame).
    description : str
        Free text.
    parameters : dataclass instance, optional
        The template parameters used, kept as provenance in the model file.
    marker_size : float
        Length of the marker triad arrows, mm.
    """

    def __init__(self, name: str, base: str = "R0", description: str = "", parameters: Any = None,
                 marker_size: float = 20.0) -> None:
        super().__init__(name, base=base, description=description)
        self.links: list[Link] = []
        self._mechanism: Mechanism | None = None
        self.material_name: str | None = None
        self.material_density: float | None = None  # kg/m^3
        self.marker_size = float(marker_size)
        if parameters is not None:
            self.metadata["parameters"] = dataclasses.asdict(parameters)

    def link(self, name: str, points: Sequence[Any], radius: float = 5.0, body: str | None = None) -> None:
        """Declare a link as bars through ``points``: joint / frame names or (x, y, z) in mm.

        ``body`` names the joint whose moving body the link is part of; with a declared
        :meth:`material`, its mass and centre of mass come from the solid
        (:mod:`hyperstat.cad_plugin.masses`).
        """
        self.links.append(Link(name, tuple(points), float(radius), body))

    def material(self, name: str, density_kg_m3: float | None = None) -> None:
        """Declare the links' material: a name of :data:`MATERIALS` or a density (kg/m^3)."""
        from hyperstat.solver.errors import TemplateError

        if density_kg_m3 is None:
            if name not in MATERIALS:
                raise TemplateError(f"material '{name}' has no known density; give density_kg_m3 or one of "
                                    f"{', '.join(MATERIALS)}.")
            density_kg_m3 = MATERIALS[name]
        from hyperstat.solver.kinematics.masses import check_material_density

        if isinstance(density_kg_m3, bool) or not isinstance(density_kg_m3, (int, float)):
            raise TemplateError(f"material '{name}': density_kg_m3 must be a number (kg/m^3), got {density_kg_m3!r}.")
        rho = check_material_density(name, density_kg_m3, "sk.material", TemplateError)  # finite, plausible
        self.material_name, self.material_density = name, rho

    def point(self, ref: Any) -> np.ndarray:
        """World position of a joint, fixed transform or frame name, or of a coordinate triple."""
        if isinstance(ref, str):
            if ref in self._items:
                return np.asarray(self._items[ref].origin, float)
            if ref in self._frames:
                return np.asarray(self._frames[ref].origin, float)
            from hyperstat.solver.errors import TemplateError

            known = ", ".join(sorted(set(self._items) | set(self._frames)))
            raise TemplateError(f"link point '{ref}' is not a declared joint or frame (declared: {known}).")
        return np.asarray(ref, float)

    def mechanism(self) -> Mechanism:
        """The solver model of this skeleton (built once, then cached).

        The declared links travel with it in ``metadata["links"]`` (name, points in world
        coordinates at home, mm, and bar radius), so that a model file and a STEP file draw the
        template's base, platform and legs as the template itself does.
        """
        if self._mechanism is None:
            if self.links:
                self.metadata["links"] = [{"name": link.name, "radius": link.radius,
                                           "points": [[float(c) for c in self.point(p)] for p in link.points]}
                                          for link in self.links]
            self._mechanism = self.build()
        return self._mechanism

