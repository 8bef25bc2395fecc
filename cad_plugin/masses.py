"""Link masses and centres of mass from the template's CadQuery solids (volume x density).

Units: lengths in mm, volumes in mm^3, densities in kg/m^3, masses in kg.

A template declares the material of its links (``Skeleton.material``) and the body each
link belongs to (``Skeleton.link(..., body=JOINT)``: the body joint ``JOINT`` moves, up to
the next joint).  :func:`link_masses` builds the same solids :func:`~hyperstat.cad_plugin.assembly.build_assembly`
draws (the bars of every link, fused), and takes the mass ``rho V`` and the centre of
mass (the solid's centroid, uniform density) of each body, in the base frame at the home
configuration.  :func:`apply_link_masses` writes them into the model's metadata
(``metadata.masses``: ``{joint: {"mass", "com", "source"}}``), the field the solver's
compliance and gravity-side backlash read; a mass the template declares itself
(``skeleton.metadata["masses"][joint]``) is kept (declared values override).  The solver
never imports CadQuery: it only reads the numbers.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hyperstat.cad_plugin.skeleton import MATERIALS
from hyperstat.solver.errors import TemplateError

if TYPE_CHECKING:  # pragma: no cover
    from hyperstat.cad_plugin.skeleton import Skeleton

__all__ = ["MATERIALS", "body_solids", "link_masses", "apply_link_masses"]



def body_solids(skeleton: "Skeleton") -> dict:
    """CadQuery solid of every body (fused bars of its links), keyed by the joint that moves it."""
    from hyperstat.cad_plugin.assembly import _bar

    joints = {j.name for j in skeleton.mechanism().joints}
    out: dict = {}
    for link in skeleton.links:
        if link.body is None:
            continue
        if link.body not in joints:
            raise TemplateError(f"link '{link.name}': body '{link.body}' is not a joint of the mechanism "
                                f"({', '.join(sorted(joints))}).")
        pts = [skeleton.point(p) for p in link.points]
        for i in range(len(pts) - 1):
            bar = _bar(pts[i], pts[i + 1], link.radius)
            if bar is not None:
                out[link.body] = bar if link.body not in out else out[link.body].fuse(bar)
    return {k: v.clean() for k, v in out.items()}


def link_masses(skeleton: "Skeleton") -> dict:
    """Mass (kg) and centre of mass (mm, base frame at home) of every body, from its solid and the material.

    Raises
    ------
    TemplateError
        If links name a body but the template declares no material, or a body is not a joint.
    """
    if skeleton.material_density is None:
        raise TemplateError(f"'{skeleton.name}': links name their bodies but no material is declared "
                            f"(Skeleton.material(name) or material(name, density_kg_m3=...)).")
    rho = skeleton.material_density * 1e-9  # kg/mm^3
    out = {}
    for joint, solid in body_solids(skeleton).items():
        volume = float(solid.Volume())
        centre = solid.Center()  # centre of mass of the solid (uniform density)
        out[joint] = {"mass": rho * volume, "com": [float(centre.x), float(centre.y), float(centre.z)],
                      "source": f"CAD solids: {volume:.6g} mm^3 of {skeleton.material_name} "
                                f"({skeleton.material_density:g} kg/m^3)"}
    return out


def apply_link_masses(skeleton: "Skeleton") -> dict:
    """Write the computed masses into the model's metadata (declared masses kept); returns ``metadata.masses``."""
    if not any(link.body is not None for link in skeleton.links):
        return dict(skeleton.metadata.get("masses", {}))
    declared = dict(skeleton.metadata.get("masses", {}))
    computed = link_masses(skeleton)
    masses = {**computed, **declared}
    skeleton.metadata["masses"] = masses
    if skeleton._mechanism is not None:  # already built: its metadata is a copy
        skeleton._mechanism.metadata["masses"] = masses
    return masses
