"""Values a drawing can carry: ISO 1101 callouts derived from the geometry, values rounded to the safe side.

Units: mm and rad; a callout's zone is a length in mm.

A tolerance of hyperstat is a statement about defect parameters (``dK21 - dK23 = 0 +- 9.3e-4 rad``).
A drawing carries geometric tolerances on features (ISO 1101:2017, ASME Y14.5): "axis of joint 23
parallel to the axis of joint 21 (datum A) within 0.37 mm over 400 mm".  :func:`callouts` derives them
from the model's geometry at its home configuration:

* the **feature** a defect moves: the axis of a joint (its ``I, J, K`` turn it, its ``a, b, c`` shift
  it), or a fixed frame; the **datum** it is measured from: the previous element of its chain (the
  frame the defect is expressed in, paper 1 Fig. 1), i.e. the other bore of the same link, or the
  chain's start frame;
* a **tilt** becomes an orientation tolerance: *parallelism* when the feature's axis is nominally
  parallel to the datum axis, *perpendicularity* when perpendicular, *angularity* otherwise; the zone
  is the tilt times the feature's length (the span of the joint's supports declared with its
  clearance: where the axis is realised), so ``+- 1e-3 rad`` over a 400 mm axis is a 0.4 mm zone;
* a **shift** becomes a *position* tolerance of the feature, zone twice the shift (ISO 1101: the zone
  is centred on the true position), or *coaxiality* (a cylindrical zone) when the feature's axis is
  nominally collinear with the datum axis;
* a relation that says two like defects of two features are equal (``dK21 - dK23 = 0``) is one callout
  of the second feature relative to the first; any other relation gets one callout per term, each
  with an equal share of the relation's value (``value / (n |coefficient|)``), which keeps the
  relation whatever the signs.

Zones and values are rounded *towards the safe side* (down, to three significant digits:
:func:`safe_round`), never to the nearest.
"""

from __future__ import annotations

import math

import numpy as np

from hyperstat.solver.kinematics.model import Joint, Mechanism

__all__ = ["safe_round", "callouts", "SYMBOLS"]

#: ISO 1101 symbols
SYMBOLS = {"parallelism": "\u2225", "perpendicularity": "\u27c2", "angularity": "\u2220", "position": "\u2316",
           "coaxiality": "\u25ce"}
_AXES = "xyz"


def safe_round(value: float | None, digits: int = 3) -> float | None:
    """``value`` rounded towards zero to ``digits`` significant digits: a tolerance never opens by rounding.

    >>> safe_round(1.76777e-3)
    0.00176
    >>> safe_round(0.0999999)
    0.0999
    """
    if value is None or not math.isfinite(value) or value == 0:
        return value
    exponent = math.floor(math.log10(abs(value))) - digits + 1
    step = 10.0 ** exponent
    out = math.floor(abs(value) / step * (1 + 1e-12)) * step  # the 1e-12 keeps 0.00176 from reading 0.00175999
    if out > abs(value):
        out -= step
    return float(f"{math.copysign(out, value):.{digits}g}")


class _Geometry:
    """Home-configuration frames of every element, its parent frame and its chain neighbours."""

    def __init__(self, mechanism: Mechanism, declaration) -> None:
        from hyperstat.solver.kinematics.closure import Kinematics

        self.m, self.decl = mechanism, declaration
        kin = Kinematics(mechanism)
        st = kin.evaluate(mechanism.home[None], None, jacobians=False)
        frames = {mechanism.chains[ci].elements[ei].name: f[0] for (ci, ei), f in st.element_frames.items()}
        self.frame = frames
        self.parent: dict = {}
        self.parent_frame: dict = {}
        for ch in mechanism.chains:
            start = st.frames[ch.start][0] if ch.start in st.frames else np.eye(4)
            prev, prev_frame = None, start
            for el in ch.elements:
                self.parent[el.name] = prev if prev is not None else ("frame", ch.start)
                # the frame the element's defects are written in: the previous element's moving frame
                self.parent_frame[el.name] = prev_frame
                f = frames[el.name]
                if isinstance(el, Joint):
                    motion = np.eye(4)
                    q = mechanism.home[mechanism.joint_index[el.name]]
                    if el.type == "R":
                        c, s = math.cos(q), math.sin(q)
                        motion[:2, :2] = [[c, -s], [s, c]]
                    else:
                        motion[2, 3] = q
                    prev_frame = f @ motion
                else:
                    prev_frame = f
                prev = ("element", el.name)
        self.kind = {el.name: el for ch in mechanism.chains for el in ch.elements}

    def axis(self, name: str) -> np.ndarray:
        return self.frame[name][:3, 2]

    def origin(self, name: str) -> np.ndarray:
        return self.frame[name][:3, 3]

    def feature(self, name: str) -> str:
        el = self.kind[name]
        return f"axis of joint {name}" if isinstance(el, Joint) else f"frame {name}"

    def length(self, name: str) -> tuple[float, str]:
        """The length a tilt of the element's axis is toleranced over (mm) and where it comes from."""
        el = self.kind[name]
        if isinstance(el, Joint):
            c = self.decl.clearance(el.name, el.type)
            if math.isfinite(c["span_mm"]):
                return float(c["span_mm"]), "the span of its supports"
        parent = self.parent[name]
        if parent[0] == "element":
            d = float(np.linalg.norm(self.origin(name) - self.origin(parent[1])))
            if d > 0:
                return d, f"its distance to {self.feature(parent[1])}"
        return 100.0, "assumed (no support span declared)"

    def datum(self, name: str) -> tuple[str, np.ndarray | None, np.ndarray]:
        """The datum feature of an element in words, its axis (None for a frame) and a point of it (mm)."""
        parent = self.parent[name]
        if parent[0] == "element":
            return self.feature(parent[1]), self.axis(parent[1]), self.origin(parent[1])
        frame = self.parent_frame[name]
        axis = self.axis(name)
        k = int(np.argmax(np.abs(frame[:3, :3].T @ axis)))
        base = "base frame" if parent[1] == self.m.base else "frame"
        return f"the {_AXES[k]} axis of the {base} {parent[1]}", frame[:3, k], frame[:3, 3]

    def direction_words(self, name: str, component: str) -> str:
        """World direction of a defect component (the parent frame's axis it is written along) in words."""
        frame = self.parent_frame[name]
        v = frame[:3, "IJKabc".index(component) % 3]
        k = int(np.argmax(np.abs(v)))
        return f"along the base {_AXES[k]} axis" if abs(abs(v[k]) - 1) < 1e-9 else \
            "along (" + ", ".join(f"{x:.3g}" for x in v) + ") in the base frame"


def _relation(a: np.ndarray, b: np.ndarray | None) -> tuple[str, float]:
    """Characteristic of an orientation callout from the nominal angle between two axes."""
    if b is None:
        return "angularity", float("nan")
    c = abs(float(np.clip(a @ b, -1.0, 1.0)))
    if c > 1 - 1e-9:
        return "parallelism", 0.0
    if c < 1e-9:
        return "perpendicularity", math.pi / 2
    return "angularity", math.acos(c)


def _callout(geo: _Geometry, name: str, component: str, size: float, unit: str, datum_of: str | None = None,
             share: str = "") -> dict:
    """One callout for a defect component of element ``name`` of size ``size`` (rad or mm)."""
    if datum_of is not None:
        datum_words, datum_axis, datum_point = geo.feature(datum_of), geo.axis(datum_of), geo.origin(datum_of)
    else:
        datum_words, datum_axis, datum_point = geo.datum(name)
    feature = geo.feature(name)
    axis = geo.axis(name)
    length, length_from = geo.length(name)
    if component in "IJK" or unit == "rad":
        characteristic, angle = _relation(axis, datum_axis)
        zone = safe_round(size * length)
        verb = {"parallelism": "parallel to", "perpendicularity": "perpendicular to"}.get(
            characteristic, f"at {angle:.6g} rad to")
        text = (f"{feature} {verb} {datum_words} (datum A) within {zone:g} mm over {length:g} mm "
                f"(a tilt of {safe_round(size):g} rad; length: {length_from})")
        diameter, feature_length = False, length
    else:
        collinear = datum_axis is not None and abs(abs(float(axis @ datum_axis)) - 1) < 1e-9 and \
            float(np.linalg.norm(np.cross(geo.origin(name) - datum_point, datum_axis))) < 1e-6
        zone = safe_round(2 * size)
        shift_dir = geo.parent_frame[name][:3, "abc".index(component)] if component in "abc" else axis
        if component in "abc" and abs(abs(float(shift_dir @ axis)) - 1) < 1e-9:
            # a shift along the feature's own axis moves its mid-plane: a position of that plane
            characteristic, diameter = "position", False
            plane = f"mid-plane of joint {name} (normal to its axis)" if feature.startswith("axis") else feature
            text = (f"{plane} in position {geo.direction_words(name, component)} relative to {datum_words} "
                    f"(datum A) within {zone:g} mm (+- {safe_round(size):g} mm)")
            feature = plane
        elif collinear:
            characteristic, diameter = "coaxiality", True
            text = f"{feature} coaxial with {datum_words} (datum A) within \u2300{zone:g} mm"
        else:
            characteristic, diameter = "position", False
            text = (f"{feature} in position {geo.direction_words(name, component)} relative to {datum_words} "
                    f"(datum A) within {zone:g} mm (+- {safe_round(size):g} mm)")
        feature_length = None
    if share:
        text += f"; {share}"
    symbol = SYMBOLS[characteristic]
    return {"characteristic": characteristic, "symbol": symbol, "zone": zone, "unit": "mm",
            "diameter_zone": diameter, "feature": feature, "feature_length": feature_length, "datums": ["A"],
            "datum_features": {"A": datum_words}, "text": text,
            "frame": f"|{symbol}|{chr(0x2300) if diameter else ''}{zone:g}|A|"}


def callouts(mechanism: Mechanism, item, declaration, geometry: _Geometry | None = None) -> list:
    """The ISO 1101 callouts of one tolerance (see the module docstring); [] when it has no value.

    Parameters
    ----------
    item : Tolerance
        An assembly condition or an accuracy-critical tolerance with its value.
    declaration : Declaration
        For the supports' spans (the lengths of the features).
    """
    if item.value is None:
        return []
    geo = geometry or _Geometry(mechanism, declaration)
    where = {p.name: (p.element, p.component) for p in mechanism.parameters}
    terms = {n: c for n, c in item.terms.items() if n in where}
    value = float(item.value)
    kinds = {n: ("tilt" if where[n][1] in "IJK" else "shift" if where[n][1] in "abc" else "roll") for n in terms}
    names = list(terms)
    if len(names) == 2 and kinds[names[0]] == kinds[names[1]] == "tilt" and \
            where[names[0]][1] == where[names[1]][1] and abs(terms[names[0]] + terms[names[1]]) < 1e-9 * \
            abs(terms[names[0]]) and where[names[0]][0] != where[names[1]][0]:
        # the same tilt of two features must be equal: the second relative to the first
        size = value / abs(terms[names[0]])
        return [_callout(geo, where[names[1]][0], where[names[1]][1], size, item.unit, datum_of=where[names[0]][0])]
    out = []
    physical = [n for n in names if kinds[n] != "roll"]
    for n in physical:
        share = "" if len(physical) == 1 else f"a 1/{len(physical)} share of {item.id} ({item.statement})"
        size = value / (len(physical) * abs(terms[n]))
        unit = "rad" if kinds[n] == "tilt" else "mm"
        out.append(_callout(geo, where[n][0], where[n][1], size, unit, share=share))
    return out


def add_drawing(cl, mechanism: Mechanism) -> None:
    """Fill ``drawing`` of every assembly condition and accuracy-critical tolerance of a classification (in place)."""
    geo = _Geometry(mechanism, cl.declaration)
    for t in cl.items:
        t.drawing = callouts(mechanism, t, cl.declaration, geo) if t.cls in ("assembly", "accuracy-critical") else []
