"""The parts of a mechanism and their features: what a part drawing is made of.

Units: mm and rad; points and directions in the base frame at the home configuration.

A **part** is a rigid body of the mechanism: the body of the base frame, the body between two
consecutive joints of a chain (a link carrying the bore of one joint and the journal of the next, a
universal joint's cross, a leg's ram), the body where chains close (the platform).  Walking the chains
(paper 1, eq. 2: ``T = prod D_i M_i``), every joint ``j`` ends the body before it and starts a new one;
a fixed transform ``D`` (paper 1's ``D_R52^R51``) and a configuration frame ``T`` stay on the body they
follow; a chain that reaches a frame already defined (a closure, eqs. 7 and 9) joins its last body to
that frame's body.

A joint ``j`` puts features on the two bodies it joins (:class:`Feature`):

* on the body **before** it (its fixed side): the **bore** of a revolute (an axis, where its bearing
  seat is) with its **end face** (the plane that locates the joint along its axis: a shoulder), or the
  **guide way** of a prismatic joint with its **flank** (the face that keeps the slide from turning);
  the bore of a driven (actuated) revolute also has a **drive reference** (the slot or pin hole that
  locates its motor's angle on this part);
* on the body **after** it: the **journal** (with its **shoulder**; a driven journal's **keyway**: the
  slot that fixes the part's angle on the driving shaft) or the **slide** (with its flank and its
  **stop**, the face the actuator's zero is taken on).

An axis is realised over the span of the joint's supports (the declared clearance's ``span_mm``,
centred ``centre_mm`` along the axis on its ``side``: the bearings, the carriage's pads); the other
half of a prismatic joint (the rail, the ram) is as long as the stroke plus that span.  The frame of a
feature is a node of its part; :func:`node_displacements` gives every node's small displacement
relative to the part's root node per unit of every defect parameter (a first-order map, by central
differences of the exact element matrices of the model, paper 1 eq. 4).

>>> import importlib, sys
>>> sys.path.insert(0, ".")
>>> from hyperstat.solver.tolerances.declaration import declaration_of
>>> m = importlib.import_module("templates.slider_crank").build().mechanism()
>>> [p.id for p in find_parts(m, declaration_of(m))]
['base', 'crank', 'rod', 'block']
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hyperstat.solver.kinematics.model import ConfigurationFrame, FixedTransform, Joint, Mechanism

__all__ = ["Feature", "Part", "find_parts", "node_displacements"]

_ROLE_WORDS = {"bore": "bore of joint {j}", "face": "end face of the bore of joint {j}",
               "drive": "drive reference of joint {j} (the slot locating its motor's angle)",
               "journal": "journal of joint {j}", "shoulder": "shoulder of the journal of joint {j}",
               "keyway": "keyway of the journal of joint {j} (the part's angle on the driving shaft)",
               "guide": "guide way of joint {j}", "flank": "flank of the guide way of joint {j}",
               "slide": "slide of joint {j}", "sflank": "flank of the slide of joint {j}",
               "stop": "stop of the slide of joint {j} (where its zero is taken)",
               "mounting": "mounting face of the base (the face its machine frame {j} is set on about datum A)",
               "seat": "tool seat (the bore the tool or effector is mounted in; it carries the output frame {j})",
               "seatface": "end face of the tool seat (it locates the output frame {j} along the seat)",
               "seatflat": "flat of the tool seat (it locates the turn of the output frame {j} about the seat)"}
_KIND = {"bore": "axis", "journal": "axis", "guide": "axis", "slide": "axis", "face": "plane", "shoulder": "plane",
         "stop": "plane", "flank": "plane", "sflank": "plane", "drive": "median plane", "keyway": "median plane",
         "mounting": "plane", "seat": "axis", "seatface": "plane", "seatflat": "plane"}


@dataclass
class Feature:
    """A real feature of a part: an axis, a plane or a median plane, at the home configuration (mm).

    ``point`` is an axis' middle (the centre of its supports) or a plane's centre; ``direction`` an
    axis' direction or a plane's normal; ``node`` the part's frame that carries it.
    """

    id: str
    part: str
    role: str
    kind: str
    name: str
    element: str
    side: str
    node: str
    point: np.ndarray
    direction: np.ndarray
    length: float | None = None
    diameter: float | None = None
    length_source: str | None = None

    def to_dict(self) -> dict:
        """JSON form of ``docs/drawing-format.md``."""
        return {"id": self.id, "kind": self.kind, "name": self.name, "element": self.element, "side": self.side,
                "point_mm": [float(v) for v in self.point], "direction": [float(v) for v in self.direction],
                "length_mm": self.length, "diameter_mm": self.diameter, "length_source": self.length_source}


@dataclass
class Part:
    """A rigid body: its nodes (frames), the edges between them, and its features."""

    id: str
    title: str
    chain: str
    root: str
    elements: list = field(default_factory=list)
    links: list = field(default_factory=list)
    features: list = field(default_factory=list)
    nodes: dict = field(default_factory=dict)  # node -> world pose at home (4, 4)
    edges: list = field(default_factory=list)  # (node a, node b, element key or None, constant matrix or None)
    entry: str | None = None  # the joint whose moving side starts this part (None for the base)

    def feature(self, fid: str) -> Feature:
        """Feature by id."""
        return next(f for f in self.features if f.id == fid)


class _Walk:
    """The chains walked once: nodes, their world poses at home, bodies (union-find) and edges."""

    def __init__(self, m: Mechanism) -> None:
        self.m = m
        self.world: dict = {}
        self.body: dict = {}  # node -> body label (union-find parent)
        self.edges: list = []  # (a, b, key, constant): b = a @ D(key) (or the constant)
        self.alias: dict = {m.base: m.base}
        self.chain_of_body: dict = {}
        self.entry: dict = {}  # body -> joint that starts it
        self.features: list = []  # (body node, role, joint, side, node)
        self.world[m.base] = np.eye(4)
        self.body[m.base] = m.base
        self.chain_of_body[m.base] = m.chains[m.topology["order"][0]].name
        home = m.home
        for ci in m.topology["order"]:
            ch = m.chains[ci]
            cur = self.alias[ch.start]
            for ei, el in enumerate(ch.elements):
                d0 = el.placement.matrix()
                if isinstance(el, Joint):
                    lname = f"L:{el.name}"
                    self._add(lname, cur, (ci, ei), d0)
                    q = float(home[m.joint_index[el.name]])
                    motion = np.eye(4)
                    if el.type == "R":
                        motion[:2, :2] = [[math.cos(q), -math.sin(q)], [math.sin(q), math.cos(q)]]
                    else:
                        motion[2, 3] = q
                    pname = f"P:{el.name}"
                    self.world[pname] = self.world[lname] @ motion
                    self.body[pname] = pname  # a new body
                    self.chain_of_body[pname] = ch.name
                    self.entry[pname] = el.name
                    cur = pname
                else:
                    name = f"F:{el.name}"
                    self._add(name, cur, (ci, ei) if isinstance(el, FixedTransform) else None, d0)
                    cur = name
            if ch.end not in self.alias:
                self.alias[ch.end] = cur
            else:
                self._merge(cur, self.alias[ch.end])

    def _add(self, name: str, parent: str, key, d0: np.ndarray) -> None:
        self.world[name] = self.world[parent] @ d0
        self.body[name] = self.find(parent)
        self.edges.append((parent, name, key, d0))

    def find(self, node: str) -> str:
        while self.body[node] != node:
            node = self.body[node]
        return node

    def _merge(self, node: str, target: str) -> None:
        """``node`` is the frame ``target`` reached again (a closure): one node, one body."""
        if node == target:
            return
        b_node, b_target = self.find(node), self.find(target)
        self.edges = [(target if a == node else a, target if b == node else b, k, c) for a, b, k, c in self.edges]
        self.world.pop(node, None)
        self.body.pop(node, None)
        for n in list(self.body):
            if self.body[n] == node:
                self.body[n] = target
        if b_node != node and b_node != b_target and b_node in self.body:
            self.body[b_node] = b_target
        for n, b in list(self.alias.items()):
            if b == node:
                self.alias[n] = target


def _support(decl, joint: Joint) -> dict:
    return decl.clearance(joint.name, joint.type)


def find_parts(mechanism: Mechanism, declaration) -> list[Part]:
    """The parts of ``mechanism`` with their features (see the module docstring), base first, in chain order.

    Parameters
    ----------
    declaration : Declaration
        For the supports' spans and centres (the features' lengths and middles).
    """
    m = mechanism
    w = _Walk(m)
    bodies: dict = {}
    for node in w.world:
        bodies.setdefault(w.find(node), []).append(node)
    order = list(dict.fromkeys(w.find(n) for n in w.world))
    joints = {j.name: j for j in m.joints}
    elements_of: dict = {b: [] for b in order}
    feats: dict = {b: [] for b in order}
    closing = {w.find(w.alias[c.frame]) for c in m.closures}
    for ci in m.topology["order"]:
        for el in m.chains[ci].elements:
            if isinstance(el, Joint):
                fixed_body, moving_body = w.find(f"L:{el.name}"), w.find(f"P:{el.name}")
                for b in (fixed_body, moving_body):
                    if el.name not in elements_of[b]:
                        elements_of[b].append(el.name)
                feats[fixed_body].append(("fixed", el, f"L:{el.name}"))
                feats[moving_body].append(("moving", el, f"P:{el.name}"))
            elif isinstance(el, FixedTransform):
                b = w.find(f"F:{el.name}") if f"F:{el.name}" in w.body else None
                if b is None:  # merged into the frame it reaches: the edge's start is on the same body
                    b = next(w.find(a) for a, _, k, _ in w.edges if k is not None and
                             m.chains[k[0]].elements[k[1]].name == el.name)
                elements_of[b].append(el.name)
    links = m.metadata.get("links") or []
    parts: list = []
    used_ids: set = set()
    for b in order:
        nodes = {n: w.world[n] for n in bodies[b]}
        entry = w.entry.get(b)
        chain = w.chain_of_body.get(b, "")
        js = [e for e in elements_of[b] if e in joints]
        on = []
        for link in links:
            pts = np.asarray(link.get("points") or [], float).reshape(-1, 3)
            if len(pts) >= 2 and all(any(np.linalg.norm(p - t[:3, 3]) < 1e-6 for t in nodes.values()) for p in pts):
                on.append(link["name"])
        if b == m.base:
            pid, title = "base", f"base (the body of the base frame {m.base})"
        elif b in closing:
            pid, title = "platform", "platform (where the chains close: " + ", ".join(js) + ")"
        else:
            pid = f"{chain}_" + "_".join(js)
            title = _title(js, joints, w, b, chain)
        unique = [name for name in on if sum(1 for other in order if other != b and name in _links_on(
            links, {n: w.world[n] for n in bodies[other]})) == 0]
        if unique:
            pid = unique[0]
        while pid in used_ids:
            pid += "_"
        used_ids.add(pid)
        part = Part(pid, title, chain, b if b == m.base else b, elements=list(elements_of[b]), links=unique or on,
                    nodes=nodes, edges=[e for e in w.edges if w.find(e[1]) == b], entry=entry)
        part.root = _root(b, w, m)
        part.features = _features(part, feats[b], declaration, m)
        if b == m.base:
            _mounting_face(part, m)
        parts.append(part)
    _tool_seat(parts, w, m)
    return parts


def _links_on(links: list, nodes: dict) -> list:
    out = []
    for link in links:
        pts = np.asarray(link.get("points") or [], float).reshape(-1, 3)
        if len(pts) >= 2 and all(any(np.linalg.norm(p - t[:3, 3]) < 1e-6 for t in nodes.values()) for p in pts):
            out.append(link["name"])
    return out


def _root(body: str, w: _Walk, m: Mechanism) -> str:
    """The node the part's defects are written from: the base frame, or the moving frame of its first joint."""
    return body


def _title(js: list, joints: dict, w: _Walk, body: str, chain: str) -> str:
    if len(js) == 2 and all(joints[j].type == "R" for j in js):
        a, b = (w.world[f"{'P' if k == 0 else 'L'}:{j}"] for k, j in enumerate(js))
        if np.linalg.norm(a[:3, 3] - b[:3, 3]) < 1e-6 and abs(float(a[:3, 2] @ b[:3, 2])) < 1e-9:
            return f"cross of the universal joint {js[0]}-{js[1]} ({chain})"
    if len(js) >= 2:
        kinds = {"R": "revolute", "P": "prismatic"}
        return (f"link of {chain} between joints {js[0]} ({kinds[joints[js[0]].type]}) and "
                + ", ".join(f"{j} ({kinds[joints[j].type]})" for j in js[1:]))
    return f"end of {chain} after joint {js[0]}" if js else f"body of {chain}"


def _features(part: Part, items: list, decl, m: Mechanism) -> list:
    out = []
    for side, joint, node in items:
        frame = part.nodes[node]
        origin, axis, x_axis, y_axis = frame[:3, 3], frame[:3, 2], frame[:3, 0], frame[:3, 1]
        c = _support(decl, joint)
        span = float(c["span_mm"]) if math.isfinite(c["span_mm"]) else None
        declared = "clearances" in decl.declared
        travel = float(joint.range[1] - joint.range[0]) if joint.type == "P" else 0.0
        on_supports = c["side"] == side
        if joint.type == "R" or on_supports:
            length = span
        else:  # the rail under a carriage, the ram through a guide: the stroke plus the supports' span
            length = None if span is None else travel + span
        mean = 0.5 * (joint.range[0] + joint.range[1])
        if joint.type == "R" or on_supports:
            centre = float(c["centre_mm"])
        elif side == "fixed":  # the rail: every place of the carriage over the range
            centre = mean + float(c["centre_mm"])
        else:  # the ram: every place of it that passes through the guide
            centre = float(c["centre_mm"]) - mean
        mid = origin + centre * axis
        source = ("declared support span" if declared else "assumed support span") if length is not None else None
        if joint.type == "R":
            roles = (("bore", "face") if side == "fixed" else ("journal", "shoulder"))
            extra = ("drive" if side == "fixed" else "keyway") if joint.role == "actuated" else None
        else:
            roles = (("guide", "flank") if side == "fixed" else ("slide", "sflank"))
            extra = "stop" if side == "moving" else None
        axis_role, plane_role = roles
        out.append(_feature(part, axis_role, joint, side, node, mid, axis, length, source))
        if joint.type == "R":
            out.append(_feature(part, plane_role, joint, side, node, origin, axis, None, None))
        else:
            out.append(_feature(part, plane_role, joint, side, node, mid, y_axis, None, None))
        if extra == "stop":
            out.append(_feature(part, "stop", joint, side, node, origin, axis, None, None))
        elif extra is not None:
            out.append(_feature(part, extra, joint, side, node, origin, y_axis, None, None))
    return out


def _mounting_face(part: Part, m: Mechanism) -> None:
    """The base's mounting face: the plane through the reference bore's axis that sets the base frame's turn about it.

    Added when the reference joint (the first of the first chain) is a passive revolute: nothing else on the base
    fixes the turn of the machine frame about that axis (a driven joint has its drive reference, a slide its flank).
    """
    first = next((el for ci in m.topology["order"] for el in m.chains[ci].elements
                  if isinstance(el, Joint) and f"L:{el.name}" in part.nodes), None)
    if first is None or first.type != "R" or first.role == "actuated":
        return
    bore = next(f for f in part.features if f.role == "bore" and f.element == first.name)
    a = bore.direction
    axes = [e for e in np.eye(3) if abs(e @ a) < 1e-9]
    if not axes:
        return
    normal = axes[-1]
    part.features.append(Feature(f"{part.id}.mounting", part.id, "mounting", "plane",
                                 _ROLE_WORDS["mounting"].format(j=m.base), first.name, "fixed", f"L:{first.name}",
                                 bore.point.copy(), normal, None, None, None))


def _tool_seat(parts: list, w: _Walk, m: Mechanism) -> None:
    """The tool seat on the part that carries the output frame: a bore along the frame's ``z`` at its origin, its end
    face, and a flat (normal to the frame's ``y``, one seat length from its axis along ``x``) that locates the turn
    about it.

    The output frame sits on a part through fixed transforms (a platform's centre, a wrist's flange): without a
    feature there, defects that move none of the part's joint features can still move the output (on a 3-RRR, the
    platform's in-plane geometry with a passive joint's zero turns the platform about one journal and moves its
    centre), and no frame would bound them.  The seat's length is not in the model: it is taken as the longest
    support span of the part's joints (``length_source`` says so).
    """
    node = w.alias.get(m.output)
    if node is None or node.startswith("L:") or node.startswith("P:"):
        return  # the output is a joint's own frame: that joint's features carry it
    part = next((p for p in parts if node in p.nodes), None)
    if part is None:
        return
    frame = part.nodes[node]
    origin, x_axis, y_axis, z_axis = frame[:3, 3], frame[:3, 0], frame[:3, 1], frame[:3, 2]
    spans = [f.length for f in part.features if f.kind == "axis" and f.length]
    length = max(spans) if spans else None
    source = "assumed: the longest support span of the part's joints" if length is not None else None
    element = node[2:]
    radius = length if length else 20.0  # beside the seat's boss (a bore of the seat's length in diameter at most)
    for role, point, direction, size, src in (
            ("seat", origin, z_axis, length, source), ("seatface", origin, z_axis, None, None),
            ("seatflat", origin + radius * x_axis, y_axis, None, None)):
        part.features.append(Feature(f"{part.id}.{role}{element}", part.id, role, _KIND[role],
                                     _ROLE_WORDS[role].format(j=m.output), element, "output", node,
                                     np.asarray(point, float), np.asarray(direction, float), size, None, src))


def _feature(part: Part, role: str, joint: Joint, side: str, node: str, point, direction, length, source) -> Feature:
    return Feature(f"{part.id}.{role}{joint.name}", part.id, role, _KIND[role], _ROLE_WORDS[role].format(j=joint.name),
                   joint.name, side, node, np.asarray(point, float), np.asarray(direction, float), length, None, source)


def node_displacements(part: Part, kin, h: float = 1e-6) -> dict:
    """Small displacement of every node of ``part`` relative to its root, per unit of each defect, (6, n_xi).

    Rows ``(omega, v)`` in the base frame: the rotation (rad) and the displacement of the node's origin
    (mm), central differences of the exact element matrices (``Kinematics.element_matrices``).
    """
    m = kin.mechanism
    n_xi = kin.n_xi
    keys = {e[2] for e in part.edges if e[2] is not None}
    params = [i for i, p in enumerate(m.parameters) if (p.chain, p.index) in keys]
    # the tree from the root: node -> (parent, edge, forward)
    adj: dict = {}
    for a, b, key, const in part.edges:
        adj.setdefault(a, []).append((b, key, const, True))
        adj.setdefault(b, []).append((a, key, const, False))
    path = {part.root: []}
    todo = [part.root]
    while todo:
        n = todo.pop()
        for nb, key, const, forward in adj.get(n, []):
            if nb not in path:
                path[nb] = path[n] + [(key, const, forward)]
                todo.append(nb)

    def poses(xi: np.ndarray) -> dict:
        mats = kin.element_matrices(xi, keys) if np.any(xi) else None  # the part's own elements only
        out = {}
        for n, steps in path.items():
            t = part.nodes[part.root].copy()
            for key, const, forward in steps:
                d = const if key is None or mats is None else mats[key]
                t = t @ (d if forward else np.linalg.inv(d))
            out[n] = t
        return out

    disp = {n: np.zeros((6, n_xi)) for n in path}
    for i in params:
        xi = np.zeros(n_xi)
        xi[i] = h
        plus = poses(xi)
        xi[i] = -h
        minus = poses(xi)
        for n in path:
            dr = plus[n][:3, :3] @ minus[n][:3, :3].T
            w = 0.5 * np.array([dr[2, 1] - dr[1, 2], dr[0, 2] - dr[2, 0], dr[1, 0] - dr[0, 1]])
            disp[n][:3, i] = w / (2 * h)
            disp[n][3:, i] = (plus[n][:3, 3] - minus[n][:3, 3]) / (2 * h)
    return disp
