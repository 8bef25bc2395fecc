"""The joint-invariant kinematic model: joints, chains, mechanisms (paper 1, section 2).

Units: lengths in mm, angles in rad.

A mechanism is a set of *chains*.  Each chain starts at a named frame (the base
or the end of another chain) and ends at a named frame, through an ordered list of
*elements*:

* :class:`Joint`: a geometric-parameter matrix ``D`` (the joint frame ``L_i`` in the
  previous frame ``P_{i-1}``) followed by the motion matrix ``M`` of a revolute
  (``"R"``, rotation about z) or prismatic (``"P"``, translation along z) joint;
* :class:`FixedTransform`: a ``D`` without motion (e.g. the paper's ``D_R52^R51``
  that carries leg 2's platform frame onto leg 1's, with its own defects);
* :class:`ConfigurationFrame`: a configuration-frame matrix ``T`` (no defect).

The first chain (in dependency order) that reaches a frame defines it; every
other chain reaching the same frame closes a loop (paper 1, eqs. 7 and 9).  A chain
that continues from the platform to the tool is the serial tail (the wrist).

Defect parameters are named as in the paper: ``d`` + component + element name,
e.g. ``dI21``, ``da52``.  Components ``I, J, K`` perturb the axis (in ``P_{i-1}``
coordinates), ``a, b, c`` the origin, and ``G`` (not in the paper) turns the frame
about its own z axis, which a fixed transform needs to be a complete rigid
transform (eq. 1 counts 6 parameters for the last frame).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Literal, Union

import numpy as np

from hyperstat.solver.errors import ModelError
from hyperstat.solver.kinematics.frames import axis_frame, make_transform
from hyperstat.solver.plausibility import JOINT_ANGLE_LIMIT, plausible_angle, plausible_length

__all__ = [
    "DEFECT_COMPONENTS",
    "ORIENTATION_COMPONENTS",
    "POSITION_COMPONENTS",
    "Placement",
    "Defect",
    "Joint",
    "FixedTransform",
    "ConfigurationFrame",
    "Element",
    "Chain",
    "Mechanism",
    "ParameterInfo",
    "Closure",
    "full_defects",
]

DEFECT_COMPONENTS = ("I", "J", "K", "a", "b", "c", "G")
ORIENTATION_COMPONENTS = ("I", "J", "K")
POSITION_COMPONENTS = ("a", "b", "c")
_ORTHO_TOL = 1e-9


@dataclass(frozen=True)
class Placement:
    """Nominal pose of a frame in its parent frame (mm).

    Parameters
    ----------
    origin : tuple of float
        Origin ``(A, B, C)`` in the parent frame, mm.
    z_axis : tuple of float
        Unit z axis ``(I, J, K)`` in the parent frame (the joint axis for a joint).
    x_axis : tuple of float
        Unit x axis, orthogonal to ``z_axis``.
    """

    origin: tuple[float, float, float]
    z_axis: tuple[float, float, float]
    x_axis: tuple[float, float, float]

    def matrix(self) -> np.ndarray:
        """Homogeneous 4x4 matrix of the placement."""
        z = np.asarray(self.z_axis, dtype=float)
        x = np.asarray(self.x_axis, dtype=float)
        return make_transform(np.stack([x, np.cross(z, x), z], axis=-1), np.asarray(self.origin, float))

    @classmethod
    def from_matrix(cls, t: np.ndarray) -> "Placement":
        """Placement of a rigid 4x4 transform."""
        t = np.asarray(t, dtype=float)
        return cls(
            tuple(float(v) for v in t[:3, 3]),
            tuple(float(v) for v in t[:3, 2]),
            tuple(float(v) for v in t[:3, 0]),
        )

    @classmethod
    def from_axis(
        cls, origin: Any, z_axis: Any, x_axis: Any | None = None
    ) -> "Placement":
        """Placement from an axis and a point, x axis by the paper's convention.

        See :func:`hyperstat.solver.kinematics.frames.axis_frame` for the convention (common
        perpendicular with the previous z axis, paper 1 Fig. 1).
        """
        rot = axis_frame(np.asarray(z_axis, float), None if x_axis is None else np.asarray(x_axis, float))
        return cls(
            tuple(float(v) for v in np.asarray(origin, float)),
            tuple(float(v) for v in rot[:, 2]),
            tuple(float(v) for v in rot[:, 0]),
        )

    def check(self, where: str) -> None:
        """Raise :class:`ModelError` naming ``where`` if the axes are not orthonormal."""
        for label, vec in (("origin", self.origin), ("z_axis", self.z_axis), ("x_axis", self.x_axis)):
            if len(vec) != 3 or not all(np.isfinite(v) for v in vec):
                raise ModelError(f"{where}.{label} must be three finite numbers, got {list(vec)}.")
        for i, v in enumerate(self.origin):
            plausible_length(v, "mm", f"{where}.origin[{i}]", error=ModelError)
        z = np.asarray(self.z_axis, float)
        x = np.asarray(self.x_axis, float)
        if abs(np.linalg.norm(z) - 1.0) > _ORTHO_TOL:
            raise ModelError(
                f"{where}.z_axis must be a unit vector, its norm is {np.linalg.norm(z):.12g}."
            )
        if abs(np.linalg.norm(x) - 1.0) > _ORTHO_TOL:
            raise ModelError(
                f"{where}.x_axis must be a unit vector, its norm is {np.linalg.norm(x):.12g}."
            )
        if abs(float(np.dot(x, z))) > _ORTHO_TOL:
            raise ModelError(
                f"{where}.x_axis must be orthogonal to z_axis, their dot product is {np.dot(x, z):.3g}."
            )


@dataclass(frozen=True)
class Defect:
    """One defect parameter of an element: a component and its public name."""

    component: str
    name: str


def full_defects(element_name: str, components: str = "IJKabc") -> tuple[Defect, ...]:
    """Defects named as in the paper: ``full_defects("21")`` gives ``dI21 ... dc21``."""
    return tuple(Defect(c, f"d{c}{element_name}") for c in components)


@dataclass(frozen=True)
class Joint:
    """A one-degree-of-freedom joint: ``D_{P_{i-1}}^{L_i}`` then ``M_{L_i}^{P_i}``.

    Parameters
    ----------
    name : str
        The paper's joint number (``"2"``, ``"21"``); defect names derive from it.
    type : {"R", "P"}
        Revolute (variable in rad) or prismatic (variable in mm).
    role : {"actuated", "passive"}
        Actuated joints are inputs; passive joints are solved by assembly.
    placement : Placement
        Nominal ``L_i`` frame in ``P_{i-1}``; its z axis is the joint axis.
    defects : tuple of Defect
        Defect parameters carried by ``D`` (see :data:`DEFECT_COMPONENTS`).
    range : tuple of float
        Joint range used for sampling configurations (rad or mm).
    home : float
        Joint value of the nominal assembled *home* configuration.
    """

    name: str
    type: Literal["R", "P"]
    role: Literal["actuated", "passive"]
    placement: Placement
    defects: tuple[Defect, ...] = ()
    range: tuple[float, float] = (-np.pi, np.pi)
    home: float = 0.0
    kind: Literal["joint"] = field(default="joint", init=False)


@dataclass(frozen=True)
class FixedTransform:
    """A geometric-parameter matrix ``D`` without motion, carrying defects."""

    name: str
    placement: Placement
    defects: tuple[Defect, ...] = ()
    kind: Literal["fixed"] = field(default="fixed", init=False)


@dataclass(frozen=True)
class ConfigurationFrame:
    """A configuration-frame matrix ``T`` (paper 1, eq. 6): a rigid transform, no defect."""

    name: str
    placement: Placement
    kind: Literal["frame"] = field(default="frame", init=False)


Element = Union[Joint, FixedTransform, ConfigurationFrame]


@dataclass(frozen=True)
class Chain:
    """An ordered list of elements from frame ``start`` to frame ``end``."""

    name: str
    start: str
    end: str
    elements: tuple[Element, ...]


@dataclass(frozen=True)
class ParameterInfo:
    """Where a defect parameter lives and what it means."""

    name: str
    element: str
    component: str
    chain: int
    index: int  # element index in its chain

    @property
    def unit(self) -> str:
        """``"mm"`` for position components, ``"rad"`` otherwise."""
        return "mm" if self.component in POSITION_COMPONENTS else "rad"

    @property
    def group(self) -> str:
        """``"orientation"``, ``"position"`` or ``"roll"``."""
        if self.component in ORIENTATION_COMPONENTS:
            return "orientation"
        return "position" if self.component in POSITION_COMPONENTS else "roll"


@dataclass(frozen=True)
class Closure:
    """A loop closure: chain ``chain`` reaches frame ``frame`` already defined elsewhere."""

    chain: int
    frame: str
    path: tuple[tuple[int, int], ...]  # elements of the closing path, base to frame
    reference_path: tuple[tuple[int, int], ...]  # elements of the defining path

    def label(self, mechanism: "Mechanism") -> str:
        """Readable name, e.g. ``"leg2 -> R51"``."""
        return f"{mechanism.chains[self.chain].name} -> {self.frame}"


@dataclass(frozen=True)
class Mechanism:
    """A mechanism in the joint-invariant formalism (paper 1, eqs. 2, 7, 9).

    Parameters
    ----------
    name : str
        Mechanism name.
    base : str
        Name of the reference frame (``R_{P_0}``, ``ICS``).
    output : str
        Name of the output frame whose pose the analysis follows (tool, slider).
    chains : tuple of Chain
        Chains; order only matters for naming order and tie-breaking.
    description : str
        Free text.
    metadata : dict
        Free-form provenance (template, parameters); kept verbatim in the model file.
    """

    name: str
    base: str
    output: str
    chains: tuple[Chain, ...]
    description: str = ""
    metadata: dict = field(default_factory=dict, compare=True, hash=False)

    def __post_init__(self) -> None:
        self._validate()

    # ------------------------------------------------------------------ validation
    def _validate(self) -> None:
        if not self.chains:
            raise ModelError("chains must hold at least one chain.")
        seen_elements: dict[str, str] = {}
        seen_defects: dict[str, str] = {}
        chain_names: set[str] = set()
        for ci, chain in enumerate(self.chains):
            where_c = f"chains[{ci}]"
            if not chain.name:
                raise ModelError(f"{where_c}.name must not be empty.")
            if chain.name in chain_names:
                raise ModelError(f"{where_c}.name '{chain.name}' is used by two chains.")
            chain_names.add(chain.name)
            if not chain.elements:
                raise ModelError(f"{where_c}.elements of chain '{chain.name}' is empty.")
            for ei, el in enumerate(chain.elements):
                where = f"{where_c}.elements[{ei}]"
                if not el.name:
                    raise ModelError(f"{where}.name must not be empty.")
                if el.name in seen_elements:
                    raise ModelError(
                        f"{where}.name '{el.name}' is already used by {seen_elements[el.name]}; element names must be unique."
                    )
                seen_elements[el.name] = where
                el.placement.check(f"{where}.placement")
                if isinstance(el, Joint):
                    if el.type not in ("R", "P"):
                        raise ModelError(f"{where}.type must be 'R' or 'P', got '{el.type}'.")
                    if el.role not in ("actuated", "passive"):
                        raise ModelError(f"{where}.role must be 'actuated' or 'passive', got '{el.role}'.")
                    lo, hi = el.range
                    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                        raise ModelError(f"{where}.range must be [low, high] with low < high, got {list(el.range)}.")
                    for i, v in enumerate(el.range):
                        if el.type == "R":
                            plausible_angle(v, "rad", f"{where}.range[{i}]", JOINT_ANGLE_LIMIT, error=ModelError)
                        else:
                            plausible_length(v, "mm", f"{where}.range[{i}]", error=ModelError)
                    if not (lo <= el.home <= hi):
                        raise ModelError(
                            f"{where}.home {el.home:g} of joint '{el.name}' lies outside its range [{lo:g}, {hi:g}]."
                        )
                defects = getattr(el, "defects", ())
                comps: set[str] = set()
                for di, d in enumerate(defects):
                    if d.component not in DEFECT_COMPONENTS:
                        raise ModelError(
                            f"{where}.defects[{di}] has unknown component '{d.component}'; use one of {', '.join(DEFECT_COMPONENTS)}."
                        )
                    if d.component in comps:
                        raise ModelError(f"{where}.defects lists component '{d.component}' twice.")
                    comps.add(d.component)
                    if d.name in seen_defects:
                        raise ModelError(
                            f"{where}.defects[{di}] name '{d.name}' is already used at {seen_defects[d.name]}."
                        )
                    seen_defects[d.name] = f"{where}.defects[{di}]"
        _ = self.topology  # raises on cycles / unknown frames
        if self.output not in self.topology["defined"]:
            raise ModelError(f"output frame '{self.output}' is not reached by any chain.")

    # ------------------------------------------------------------------ topology
    @cached_property
    def topology(self) -> dict:
        """Dependency order of chains, frame definitions and loop closures."""
        defined: dict[str, tuple[tuple[int, int], ...]] = {self.base: ()}
        defining_chain: dict[str, int] = {}
        order: list[int] = []
        closures: list[Closure] = []
        remaining = list(range(len(self.chains)))
        while remaining:
            progress = False
            for ci in list(remaining):
                chain = self.chains[ci]
                if chain.start not in defined:
                    continue
                path = defined[chain.start] + tuple((ci, ei) for ei in range(len(chain.elements)))
                if chain.end in defined:
                    closures.append(Closure(ci, chain.end, path, defined[chain.end]))
                else:
                    defined[chain.end] = path
                    defining_chain[chain.end] = ci
                order.append(ci)
                remaining.remove(ci)
                progress = True
                break
            if not progress:
                ends = {self.chains[ci].end for ci in remaining}
                stuck = [self.chains[ci] for ci in remaining]
                cyc = [c for c in stuck if c.start in ends]
                if cyc:
                    names = " -> ".join(f"'{c.name}' ({c.start} to {c.end})" for c in cyc)
                    raise ModelError(
                        f"chains form a cycle that never reaches the base frame '{self.base}': {names}."
                    )
                c = stuck[0]
                raise ModelError(
                    f"chain '{c.name}' starts at frame '{c.start}', which is neither the base '{self.base}' nor the end of another chain."
                )
        return {"defined": defined, "order": order, "closures": tuple(closures), "defining_chain": defining_chain}

    @property
    def closures(self) -> tuple[Closure, ...]:
        """Loop closures, one per chain that reaches an already defined frame."""
        return self.topology["closures"]

    @property
    def frames(self) -> tuple[str, ...]:
        """Names of all frames reached (base first)."""
        return tuple(self.topology["defined"])

    def path_to(self, frame: str) -> tuple[tuple[int, int], ...]:
        """Elements ``(chain, index)`` from the base to ``frame`` along its defining chains."""
        try:
            return self.topology["defined"][frame]
        except KeyError:
            raise ModelError(f"frame '{frame}' is not reached by any chain.") from None

    # ------------------------------------------------------------------ joints / parameters
    @cached_property
    def joints(self) -> tuple[Joint, ...]:
        """All joints, chains in file order."""
        return tuple(el for ch in self.chains for el in ch.elements if isinstance(el, Joint))

    @cached_property
    def joint_index(self) -> dict[str, int]:
        """Position of each joint in the configuration vector ``q``."""
        return {j.name: i for i, j in enumerate(self.joints)}

    @cached_property
    def actuated(self) -> np.ndarray:
        """Indices of actuated joints in ``q``."""
        return np.array([i for i, j in enumerate(self.joints) if j.role == "actuated"], dtype=int)

    @cached_property
    def passive(self) -> np.ndarray:
        """Indices of passive joints in ``q``."""
        return np.array([i for i, j in enumerate(self.joints) if j.role == "passive"], dtype=int)

    @cached_property
    def parameters(self) -> tuple[ParameterInfo, ...]:
        """All defect parameters, chains in file order, components in I J K a b c G order."""
        out = []
        for ci, ch in enumerate(self.chains):
            for ei, el in enumerate(ch.elements):
                defects = sorted(getattr(el, "defects", ()), key=lambda d: DEFECT_COMPONENTS.index(d.component))
                for d in defects:
                    out.append(ParameterInfo(d.name, el.name, d.component, ci, ei))
        return tuple(out)

    @cached_property
    def parameter_index(self) -> dict[str, int]:
        """Position of each defect parameter in the defect vector ``xi``."""
        return {p.name: i for i, p in enumerate(self.parameters)}

    @property
    def home(self) -> np.ndarray:
        """Home configuration ``q`` (rad / mm)."""
        return np.array([j.home for j in self.joints], dtype=float)

    @property
    def ranges(self) -> np.ndarray:
        """Joint ranges, shape ``(n_joints, 2)``."""
        return np.array([j.range for j in self.joints], dtype=float)

    def element(self, name: str) -> Element:
        """Element by name."""
        for ch in self.chains:
            for el in ch.elements:
                if el.name == name:
                    return el
        raise ModelError(f"no element named '{name}'.")

    def count(self) -> dict[str, int]:
        """Counts of joints by type and role, parameters and closures."""
        return {
            "R": sum(j.type == "R" for j in self.joints),
            "P": sum(j.type == "P" for j in self.joints),
            "actuated": len(self.actuated),
            "passive": len(self.passive),
            "parameters": len(self.parameters),
            "closures": len(self.closures),
        }
