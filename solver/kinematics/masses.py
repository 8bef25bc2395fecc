"""Plausibility of link masses and centres of mass: URDF ``<inertial>``, ``metadata.masses``, CAD materials.

Units: lengths in mm, masses in kg, densities in kg/m^3.

Gravity effects (joint compliance, gravity-side backlash) are sized from the masses a model
declares; a mass that is a unit slip (grams read as kilograms: every mass times 1000), a typing
error (1e30 kg) or a centre of mass far from its link makes them wrong by as much, with no
warning.  Each declared body is therefore checked against its size:

* **the link's extent**: the points it is known to span, in the base frame at home (its joint
  origin, the origins of the joints it carries, the geometry a URDF gives it), their bounding
  box, widened on every side by a margin of :data:`EXTENT_MARGIN` of the chain's reach (the
  sum of the joint-to-joint distances along it: motors, counterweights and covers hang off a
  link's axis line, and a link with two coincident joints, a wrist's, still has a body);
* **mass range**: from 0 to the mass of a ball around that box (radius half its diagonal plus
  the margin) filled at :data:`DENSITY_MAX_KG_M3`, the density of solid copper.  No robot
  link is denser on average over such an envelope: structural metals are lighter (steel 7850,
  cast iron 7200, aluminium 2700 kg/m^3; copper 8960 kg/m^3, the densest in common machine
  structures, CRC Handbook of Chemistry and Physics, 97th ed., "Density of metals"), and a link
  fills a small part of the ball.  No lower bound but 0: a carbon tube of a metre weighs a few
  hundred grams;
* **centre of mass**: inside the widened box;
* every value finite, a mass >= 0.

A CAD material (``Skeleton.material``) has a density between :data:`MATERIAL_DENSITY_KG_M3`
(100 kg/m^3, below the lightest structural woods and foams used for arms, to 22 590 kg/m^3,
osmium, the densest element; CRC Handbook): a density of 7.85 "kg/m^3" is steel in g/cm^3.

A body that moves and has no declared mass is *unknown*: gravity effects then cannot be sized
(the diagnosis says ``cannot_size``), never computed as if it were massless.

Examples
--------
>>> round(mass_limit(350.0))
1609
>>> check_body_mass(12000.0, [200.0, 0.0, 350.0], [[0.0, 0.0, 350.0], [400.0, 0.0, 350.0]], 1150.0, "link 'upper'")
Traceback (most recent call last):
...
hyperstat.solver.errors.DataError: link 'upper': a mass of 12000 kg is not plausible for its size: a ball of radius 0.43 m around its extent (0.4 m, plus 0.23 m) holds at most 2984 kg of solid copper (8960 kg/m^3, denser than any robot link's envelope); is the mass in grams?
"""

from __future__ import annotations

import math

import numpy as np

from hyperstat.solver.errors import DataError
from hyperstat.solver.plausibility import finite

__all__ = ["DENSITY_MAX_KG_M3", "MATERIAL_DENSITY_KG_M3", "EXTENT_MARGIN", "mass_limit", "check_body_mass",
           "check_material_density", "check_declared_masses", "chain_reach"]

#: densest average over a link's envelope (kg/m^3): solid copper (CRC Handbook, 97th ed.)
DENSITY_MAX_KG_M3 = 8960.0
#: plausible densities of a CAD link material (kg/m^3): light woods and foams to osmium (CRC Handbook)
MATERIAL_DENSITY_KG_M3 = (100.0, 22590.0)
#: a link's extent is widened by this share of the chain's reach (motors, counterweights, covers)
EXTENT_MARGIN = 0.2


def mass_limit(radius_mm: float) -> float:
    """The largest plausible mass (kg) of a body within a ball of ``radius_mm``: the ball in solid copper."""
    r = radius_mm / 1000.0
    return DENSITY_MAX_KG_M3 * 4.0 / 3.0 * math.pi * r**3


def check_body_mass(mass: float, com, points, reach_mm: float, where: str, error: type = DataError) -> None:
    """Refuse a body's mass (kg) or centre of mass (mm, base frame at home) implausible for its extent.

    Parameters
    ----------
    mass : float
        Declared mass (kg).
    com : array_like, (3,)
        Declared centre of mass (mm).
    points : array_like, (K, 3)
        Points the body spans (mm): its joint origin, the origins of the joints it carries, its geometry.
    reach_mm : float
        The chain's reach (mm): the margin is :data:`EXTENT_MARGIN` of it.
    where : str
        What the message names (file and link or field).

    Raises
    ------
    DataError
        One sentence naming ``where``.
    """
    m = finite(mass, f"{where}: mass", "kg", error)
    if m < 0.0:
        raise error(f"{where}: a mass of {m:g} kg is negative; a mass is >= 0 (kg).")
    c = np.array([finite(v, f"{where}: centre of mass", "mm", error) for v in np.ravel(com)], dtype=float)
    if c.shape != (3,):
        raise error(f"{where}: a centre of mass has 3 coordinates (mm), got {len(c)}.")
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    margin = EXTENT_MARGIN * reach_mm
    size = float(np.linalg.norm(hi - lo))
    radius = 0.5 * size + margin
    limit = mass_limit(radius)
    if m > limit:
        hint = "; is the mass in grams?" if m / 1000.0 <= limit else "."
        raise error(f"{where}: a mass of {m:g} kg is not plausible for its size: a ball of radius {radius / 1000:.2g} m "
                    f"around its extent ({size / 1000:.2g} m, plus {margin / 1000:.2g} m) holds at most {limit:.0f} kg "
                    f"of solid copper ({DENSITY_MAX_KG_M3:g} kg/m^3, denser than any robot link's envelope){hint}")
    out = np.maximum(np.maximum(lo - margin - c, c - hi - margin), 0.0)
    if np.any(out > 0.0):
        far = float(np.linalg.norm(np.maximum(lo - c, 0.0) + np.maximum(c - hi, 0.0)))
        raise error(f"{where}: its centre of mass [{', '.join(f'{v:g}' for v in c)}] mm (base frame at home) lies "
                    f"{far / 1000:.3g} m outside the link, which spans [{', '.join(f'{v:g}' for v in lo)}] to "
                    f"[{', '.join(f'{v:g}' for v in hi)}] mm; at most {margin / 1000:.2g} m beyond is plausible "
                    f"({100 * EXTENT_MARGIN:g} % of the chain's reach).")


def check_material_density(name: str, density: float, where: str, error: type = DataError) -> float:
    """A CAD material's density (kg/m^3) within :data:`MATERIAL_DENSITY_KG_M3`, refused otherwise in one sentence."""
    rho = finite(density, f"{where}: density_kg_m3", "kg/m^3", error)
    low, high = MATERIAL_DENSITY_KG_M3
    if not low <= rho <= high:
        hint = " (it looks like g/cm^3: multiply by 1000)" if 0.1 <= rho <= high / 1000.0 else ""
        raise error(f"{where}: material '{name}' has a density of {rho:g} kg/m^3, not a plausible link material "
                    f"(between {low:g} and {high:g} kg/m^3, light woods to osmium){hint}.")
    return rho


def chain_reach(points) -> float:
    """The reach of a chain (mm): the sum of the distances between its consecutive joint origins."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1))) if len(pts) > 1 else 0.0


def check_declared_masses(mechanism, source: str, error: type = DataError) -> None:
    """Check a model's ``metadata.masses`` (per joint: the body it moves, ``mass`` kg and ``com`` mm, base frame
    at home): finite values, each body plausible for its extent (:func:`check_body_mass`), and, on a serial
    chain, a body for every joint (one left out would be massless: declare 0 for a negligible one).

    The extent of joint ``j``'s body spans the frame origins from ``j`` to the next joint (or the chain's end) at
    the home configuration.

    Raises
    ------
    DataError
        One sentence naming ``source`` and the field.
    """
    masses = mechanism.metadata.get("masses") if isinstance(mechanism.metadata, dict) else None
    if not masses:
        return
    if not isinstance(masses, dict):
        raise error(f"{source}: metadata.masses must map joint names to {{mass, com}}.")
    joints = {j.name for j in mechanism.joints}
    for name, spec in masses.items():
        where = f"{source}: metadata.masses['{name}']"
        if name not in joints:
            raise error(f"{where} names joint '{name}', which the model lacks.")
        if not isinstance(spec, dict) or "mass" not in spec or "com" not in spec:
            raise error(f"{where} needs 'mass' (kg) and 'com' [x, y, z] (mm, base frame at home).")
        for key in ("mass",):
            if isinstance(spec[key], bool) or not isinstance(spec[key], (int, float)):
                raise error(f"{where}.{key} must be a number (kg), got {spec[key]!r}.")
        com = spec["com"]
        if not isinstance(com, (list, tuple)) or len(com) != 3 or any(
                isinstance(v, bool) or not isinstance(v, (int, float)) for v in com):
            raise error(f"{where}.com must be [x, y, z] (mm, base frame at home), got {com!r}.")
        if finite(spec["mass"], f"{where}.mass", "kg", error) < 0.0:
            raise error(f"{where}: a mass of {spec['mass']:g} kg is negative; a mass is >= 0 (kg).")
        for v in com:
            finite(v, f"{where}.com", "mm", error)
    if len(mechanism.chains) != 1:
        return  # distributed masses are used on serial chains only (the diagnosis says so)
    from hyperstat.solver.kinematics.closure import Kinematics

    chain = mechanism.chains[0]
    kin = Kinematics(mechanism)
    st = kin.evaluate(mechanism.home[None, :], None, jacobians=False)
    origins = [np.asarray(st.element_frames[(0, ei)][0, :3, 3], dtype=float) for ei in range(len(chain.elements))]
    origins.append(np.asarray(st.output_pose[0, :3, 3], dtype=float))
    reach = chain_reach(origins)
    moving = [ei for ei, el in enumerate(chain.elements) if getattr(el, "type", None) in ("R", "P")]
    names = [chain.elements[ei].name for ei in moving]
    missing = [n for n in names if n not in masses]
    if missing:
        raise error(f"{source}: metadata.masses gives no mass for joint '{missing[0]}', which moves a body: a "
                    f"body left out would be massless; declare it (mass 0 for a negligible one) or declare no masses "
                    f"(gravity effects then cannot be sized).")
    for k, ei in enumerate(moving):
        end = moving[k + 1] if k + 1 < len(moving) else len(origins) - 1
        pts = origins[ei:end + 1]
        spec = masses[chain.elements[ei].name]
        check_body_mass(float(spec["mass"]), spec["com"], pts, reach,
                        f"{source}: metadata.masses['{chain.elements[ei].name}']", error)
