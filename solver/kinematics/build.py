"""Build a :class:`~hyperstat.solver.kinematics.model.Mechanism` from frames given in world coordinates.

Units: lengths in mm, angles in rad.

A skeleton is drawn at its *home* configuration: every joint frame ``L_i`` and
every configuration frame (base, platform, tool) has a pose in the world.  The
builder walks each chain and turns those poses into the relative matrices of the
joint-invariant model: ``D_i = P_{i-1}^{-1} L_i`` (paper 1, Fig. 1) and
``T = P_N^{-1} F`` for a configuration frame ``F``.  The CAD side
(``hyperstat.cad_plugin.skeleton``) and hand-written templates both go through here, so
there is one place where world poses become the model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Literal, Sequence

import numpy as np

from hyperstat.solver.errors import ModelError
from hyperstat.solver.kinematics.frames import axis_frame, invert_transform, make_transform, motion_matrix
from hyperstat.solver.kinematics.model import (
    Chain,
    ConfigurationFrame,
    Defect,
    FixedTransform,
    Joint,
    Mechanism,
    Placement,
)

__all__ = ["MechanismBuilder", "JointSpec", "FrameSpec"]


@dataclass
class FrameSpec:
    """A named frame in world coordinates at the home configuration."""

    name: str
    origin: np.ndarray
    z_axis: np.ndarray
    x_axis: np.ndarray | None = None
    defects: str = ""
    defect_names: dict = field(default_factory=dict)
    fixed: bool = False  # a fixed geometric transform (D with defects) rather than a frame
    target: str | None = None  # a fixed transform placed where another chain put this frame


@dataclass
class JointSpec:
    """A joint in world coordinates at the home configuration."""

    name: str
    type: Literal["R", "P"]
    role: Literal["actuated", "passive"]
    origin: np.ndarray
    z_axis: np.ndarray
    x_axis: np.ndarray | None
    defects: str
    defect_names: dict
    range: tuple[float, float]
    home: float


def _unit(v: Iterable[float], what: str) -> np.ndarray:
    a = np.asarray(list(v), dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ModelError(f"{what} must be three finite numbers.")
    n = np.linalg.norm(a)
    if n < 1e-12:
        raise ModelError(f"{what} must not be the zero vector.")
    return a / n


def _clean(t: np.ndarray) -> np.ndarray:
    """Snap round-off (|x| < 1e-13 relative) to exact zeros and +-1 so files read well."""
    out = t.copy()
    r = out[:3, :3]
    r[np.abs(r) < 1e-14] = 0.0
    r[np.abs(np.abs(r) - 1.0) < 1e-14] = np.sign(r[np.abs(np.abs(r) - 1.0) < 1e-14])
    scale = max(1.0, float(np.max(np.abs(out[:3, 3]))))
    p = out[:3, 3]
    p[np.abs(p) < 1e-12 * scale] = 0.0
    return out


class MechanismBuilder:
    """Declare joints, frames and chains in world coordinates, then :meth:`build`.

    Parameters
    ----------
    name : str
        Mechanism name.
    base : str
        Name of the base (reference) frame; it is the world frame.
    description : str
        Free text.

    Examples
    --------
    >>> b = MechanismBuilder("pendulum")
    >>> b.revolute("1", point=(0, 0, 0), axis=(0, 0, 1), role="actuated", defects="")
    >>> b.frame("tip", origin=(100, 0, 0), z_axis=(0, 0, 1), x_axis=(1, 0, 0))
    >>> b.chain("arm", "R0", "tip", ["1"])
    >>> b.build().count()["R"]
    1
    """

    def __init__(self, name: str, base: str = "R0", description: str = "") -> None:
        self.name = name
        self.base = base
        self.description = description
        self._items: dict[str, JointSpec | FrameSpec] = {}
        self._frames: dict[str, FrameSpec] = {
            base: FrameSpec(base, np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
        }
        self._chains: list[tuple[str, str, str, list[str]]] = []
        self.metadata: dict = {}
        self.output: str | None = None
        #: world pose at home of every element's L frame and of every frame, filled by build()
        self.poses: dict[str, np.ndarray] = {}
        #: the chain that defines each frame, filled by build()
        self.frame_chain: dict[str, str] = {}

    # ------------------------------------------------------------------ declarations
    def _joint(self, type_, name, point, axis, role, x_axis, defects, defect_names, range, home):
        if name in self._items or name in self._frames:
            raise ModelError(f"joint name '{name}' is declared twice.")
        if role not in ("actuated", "passive"):
            raise ModelError(f"joint '{name}': role must be 'actuated' or 'passive', got '{role}'.")
        z = _unit(axis, f"joint '{name}' axis")
        x = None if x_axis is None else _unit(x_axis, f"joint '{name}' x_axis")
        if range is None:
            range = (-np.pi, np.pi) if type_ == "R" else (-100.0, 100.0)
        self._items[name] = JointSpec(
            name, type_, role, np.asarray(point, float), z, x, defects, dict(defect_names or {}),
            (float(range[0]), float(range[1])), float(home),
        )

    def revolute(
        self,
        name: str,
        point: Sequence[float],
        axis: Sequence[float],
        role: Literal["actuated", "passive"] = "passive",
        x_axis: Sequence[float] | None = None,
        defects: str = "IJKabc",
        defect_names: dict | None = None,
        range: tuple[float, float] | None = None,
        home: float = 0.0,
    ) -> None:
        """Declare a revolute joint by a point of its axis and the axis direction (world, home).

        ``defects`` lists the defect components ``D`` carries (``"IJKabc"`` by default,
        ``""`` for the reference joint); ``defect_names`` renames some of them
        (``{"J": "alpha2"}``).
        """
        self._joint("R", name, point, axis, role, x_axis, defects, defect_names, range, home)

    def prismatic(
        self,
        name: str,
        point: Sequence[float],
        axis: Sequence[float],
        role: Literal["actuated", "passive"] = "passive",
        x_axis: Sequence[float] | None = None,
        defects: str = "IJK",
        defect_names: dict | None = None,
        range: tuple[float, float] | None = None,
        home: float = 0.0,
    ) -> None:
        """Declare a prismatic joint: ``point`` is the origin of ``L_i`` (the slide at zero travel)."""
        self._joint("P", name, point, axis, role, x_axis, defects, defect_names, range, home)

    def frame(
        self,
        name: str,
        origin: Sequence[float],
        z_axis: Sequence[float],
        x_axis: Sequence[float],
    ) -> None:
        """Declare a configuration frame (base, platform, tool: paper 1, eq. 6) in world coordinates."""
        if name in self._items or (name in self._frames and name != self.base):
            raise ModelError(f"frame name '{name}' is declared twice.")
        self._frames[name] = FrameSpec(name, np.asarray(origin, float), _unit(z_axis, f"frame '{name}' z_axis"),
                                       _unit(x_axis, f"frame '{name}' x_axis"))

    def fixed(
        self,
        name: str,
        origin: Sequence[float] | None = None,
        z_axis: Sequence[float] | None = None,
        x_axis: Sequence[float] | None = None,
        defects: str = "IJKabc",
        defect_names: dict | None = None,
        target: str | None = None,
    ) -> None:
        """Declare a fixed geometric transform (a ``D`` without motion, with defects).

        Its pose is the world pose of the frame it leads to, given either explicitly
        (``origin``, ``z_axis``, ``x_axis``) or as ``target``: the name of a frame that
        another chain reaches first (e.g. ``"R51"`` for the paper's ``D_R52^R51``).
        It is placed inside a chain like a joint.
        """
        if name in self._items or name in self._frames:
            raise ModelError(f"element name '{name}' is declared twice.")
        if target is None and (origin is None or z_axis is None):
            raise ModelError(f"fixed transform '{name}' needs an origin and a z_axis, or a target frame.")
        self._items[name] = FrameSpec(
            name, np.zeros(3) if origin is None else np.asarray(origin, float),
            np.array([0.0, 0.0, 1.0]) if z_axis is None else _unit(z_axis, f"fixed transform '{name}' z_axis"),
            None if x_axis is None else _unit(x_axis, f"fixed transform '{name}' x_axis"),
            defects, dict(defect_names or {}), fixed=True, target=target,
        )

    def chain(self, name: str, start: str, end: str, elements: Sequence[str]) -> None:
        """Declare a chain from frame ``start`` to frame ``end`` through joints / fixed transforms."""
        self._chains.append((name, start, end, list(elements)))

    # ------------------------------------------------------------------ build
    @staticmethod
    def _defects(element: str, comps: str, names: dict) -> tuple[Defect, ...]:
        return tuple(Defect(c, names.get(c, f"d{c}{element}")) for c in comps)

    def _world(self, name: str) -> np.ndarray:
        f = self._frames[name]
        rot = axis_frame(f.z_axis, f.x_axis)
        return make_transform(rot, f.origin)

    def build(self) -> Mechanism:
        """Turn the world declarations into a :class:`Mechanism`.

        A chain ending at a declared frame gets the configuration frame ``T`` that
        places it; a chain ending at an undeclared name defines that frame as the
        frame after its last element (e.g. ``R51``); a closing chain gets the ``T``
        from its last frame to the frame placed by the defining chain (identity, and
        then omitted, when the declarations already meet).

        Raises
        ------
        ModelError
            If a chain names an undeclared item or an unreachable start frame, or an
            item is declared but used by no chain.
        """
        used: set[str] = set()
        reached: dict[str, np.ndarray] = {self.base: np.eye(4)}
        self.poses = {self.base: np.eye(4)}
        self.frame_chain = {}
        chains = []
        pending = list(self._chains)
        while pending:
            for idx, (name, start, end, names) in enumerate(pending):
                if start in reached:
                    break
            else:
                raise ModelError(
                    f"chain '{pending[0][0]}' starts at frame '{pending[0][1]}', which no chain reaches from '{self.base}'."
                )
            pending.pop(idx)
            w_prev = reached[start]
            elements = []
            for el_name in names:
                if el_name not in self._items:
                    raise ModelError(f"chain '{name}' names '{el_name}', which is not a declared joint or fixed transform.")
                if el_name in used:
                    raise ModelError(f"'{el_name}' appears in two chains; every joint belongs to one chain.")
                used.add(el_name)
                spec = self._items[el_name]
                if getattr(spec, "target", None) is not None:
                    if spec.target not in reached:
                        raise ModelError(
                            f"fixed transform '{el_name}' targets frame '{spec.target}', which no earlier chain reaches."
                        )
                    d = _clean(invert_transform(w_prev) @ reached[spec.target])
                else:
                    z_rel = w_prev[:3, :3].T @ spec.z_axis
                    x_rel = None if spec.x_axis is None else w_prev[:3, :3].T @ spec.x_axis
                    rot = axis_frame(z_rel, x_rel)
                    origin = w_prev[:3, :3].T @ (spec.origin - w_prev[:3, 3])
                    d = _clean(make_transform(rot, origin))
                placement = Placement.from_matrix(d)
                # a targeted transform ends exactly on its target (w_prev @ d is only that to round-off)
                lw = reached[spec.target] if getattr(spec, "target", None) is not None else w_prev @ d
                self.poses[el_name] = lw
                if isinstance(spec, JointSpec):
                    elements.append(
                        Joint(
                            spec.name, spec.type, spec.role, placement,
                            self._defects(spec.name, spec.defects, spec.defect_names),
                            spec.range, spec.home,
                        )
                    )
                    w_prev = lw @ motion_matrix(spec.type, np.asarray(spec.home))
                else:
                    elements.append(FixedTransform(spec.name, placement,
                                                   self._defects(spec.name, spec.defects, spec.defect_names)))
                    w_prev = lw
            if end in reached:
                target = reached[end]  # closing chain: the frame is placed by its defining chain
            elif end in self._frames:
                target = self._world(end)
            else:
                target = w_prev  # the chain's end is the frame after its last element (e.g. R51)
            t = _clean(invert_transform(w_prev) @ target)
            if not np.allclose(t, np.eye(4), rtol=0.0, atol=1e-12) or not elements:
                elements.append(ConfigurationFrame(f"T_{name}_{end}", Placement.from_matrix(t)))
            reached.setdefault(end, w_prev @ t)
            self.poses.setdefault(end, reached[end])
            self.frame_chain.setdefault(end, name)
            chains.append(Chain(name, start, end, tuple(elements)))
        unused = [n for n in self._items if n not in used]
        if unused:
            raise ModelError(f"joint or fixed transform '{unused[0]}' is declared but belongs to no chain.")
        output = self.output or chains[-1].end
        return Mechanism(self.name, self.base, output, tuple(chains), self.description, dict(self.metadata))
