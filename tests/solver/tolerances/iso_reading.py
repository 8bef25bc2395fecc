"""A drawing checker's own reading of part drawings (ISO 1101 zones, ISO 5459 datum systems), from the JSON alone.

Units: mm and rad.

Nothing of hyperstat's tolerance code is used: the frames are read from ``report.json``'s ``drawings`` (the
contract of ``docs/drawing-format.md``), the parts' geometry from the mechanism's *data* (chains, placements,
defect names), the defect model from ``tests/solver/tolerances/independent.py`` (its own element matrices), and
the linear programmes are this module's.

The reading (what a frame admits):

* a feature is realised by a joint's frame: the part before the joint (``side`` ``fixed``) carries ``L_j``, the
  part after it (``moving``) ``P_j = L_j M_j(q_home)``; a tool seat (``side`` ``output``) by the output frame the
  element named reaches; its small displacement is read from the part's own chain of element matrices, relative
  to the frame of its datum ``A`` (central differences);
* the datum reference frame of a frame: ``A`` (an axis) locks the two tilts across it and the two shifts across
  it at its point; ``B`` (a plane normal to ``A``) the translation along ``A``; ``C`` the rotation about ``A``
  (a plane containing ``A``'s direction: by its own turn about ``A``; an axis parallel to ``A``: by its shift
  across the plane of both; another axis: by its direction's turn about ``A``).  A degree of freedom no datum
  of the frame locks is free for that frame (ISO 5459: the datum system constrains only what its features
  lock); an orientation zone is never located (its translations are free);
* an axis of length ``L`` toleranced by an orientation zone of two planes ``t`` apart with normal ``m``:
  ``|m . (w x n)| L <= t``; by a cylinder ``⌀t``: ``|(w x n)_perp| L <= t``; by a position zone: every point
  of the segment within ``t / 2`` of its true position (along ``m``, or radially for a cylinder); a plane by a
  position zone: its centre within ``t / 2`` along its normal;
* a round zone is replaced by the circumscribed polygon of :data:`SIDES` sides (a superset: the check is
  then on the safe side, to ``1 / cos(pi / SIDES) - 1`` = 7.5e-5);
* an assembly requirement bounds its statement directly;
* the direction of a two-plane zone is derived from the frame and compared with the stated one: without an
  indicator, a tilt zone's normal is the part of ``A``'s direction across the feature (a perpendicularity or
  angularity to ``A``), a position zone's normal is ``A``'s direction (located by ``B``) or the feature's own
  normal (a plane); with an orientation-plane indicator naming ``X``, the normal of the plane through ``A`` and
  ``X``, or that normal turned about the feature (``perpendicular``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import linprog

from tests.solver.tolerances.independent import _element, _placement, _rot_z, _trans_z

__all__ = ["DrawingReader", "SIDES"]

SIDES = 256


def _unit(v):
    return np.asarray(v, float) / np.linalg.norm(v)


class _Bodies:
    """The mechanism's rigid bodies from its chains, each frame reached once (closures joined)."""

    def __init__(self, m) -> None:
        self.m = m
        self.parent: dict = {}  # node -> (parent node, element, forward)
        self.edges: list = []  # (a, b, element or None (constant), constant matrix)
        home = {}
        k = 0
        for ch in m.chains:
            for el in ch.elements:
                if el.kind == "joint":
                    home[el.name] = float(m.home[k])
                    k += 1
        ends = {m.base: m.base}
        self.same: dict = {}
        defined = {m.base}
        order, left = [], list(range(len(m.chains)))
        while left:
            for ci in left:
                if m.chains[ci].start in defined:
                    order.append(ci)
                    defined.add(m.chains[ci].end)
                    left.remove(ci)
                    break
        self.world = {m.base: np.eye(4)}
        self.cut: set = set()  # joint motions: not edges of a body
        for ci in order:
            ch = m.chains[ci]
            cur = ends[ch.start]
            for el in ch.elements:
                if el.kind == "joint":
                    node = f"L:{el.name}"
                    self._edge(cur, node, el)
                    moving = f"P:{el.name}"
                    mot = _rot_z(np.array(home[el.name])) if el.type == "R" else _trans_z(np.array(home[el.name]))
                    self.world[moving] = self.world[node] @ mot
                    cur = moving
                else:
                    node = f"F:{el.name}"
                    self._edge(cur, node, el)
                    cur = node
            if ch.end in ends:
                self.same[cur] = ends[ch.end]
            else:
                ends[ch.end] = cur

    def _edge(self, a: str, b: str, el) -> None:
        self.world[b] = self.world[a] @ _placement(el.placement)
        self.edges.append((a, b, el))

    def canon(self, node: str) -> str:
        while node in self.same:
            node = self.same[node]
        return node

    def path(self, start: str) -> dict:
        """node -> list of (element, forward) from ``start`` within its body."""
        adj: dict = {}
        for a, b, el in self.edges:
            a, b = self.canon(a), self.canon(b)
            adj.setdefault(a, []).append((b, el, True))
            adj.setdefault(b, []).append((a, el, False))
        out = {self.canon(start): []}
        todo = [self.canon(start)]
        while todo:
            n = todo.pop()
            for nb, el, fw in adj.get(n, []):
                if nb not in out:
                    out[nb] = out[n] + [(el, fw)]
                    todo.append(nb)
        return out


class DrawingReader:
    """The admitted defects of a drawing and the statements' extremes over them (see the module docstring).

    Parameters
    ----------
    mechanism
        Its data only.
    report : dict
        ``report.json`` (``drawings``, ``assembly_requirements``, ``tolerances.items``).
    """

    def __init__(self, mechanism, report: dict) -> None:
        self.m = mechanism
        self.rep = report
        self.names = [d.name for ch in mechanism.chains for el in ch.elements for d in getattr(el, "defects", ())]
        self.col = {n: i for i, n in enumerate(self.names)}
        self.n = len(self.names)
        self.bodies = _Bodies(mechanism)
        self.elements = {el.name: el for ch in mechanism.chains for el in ch.elements}
        self.features = {f["id"]: (d, f) for d in report["drawings"] for f in d["features"]}
        self.units = ["rad" if d.component in "IJKG" else "mm" for ch in mechanism.chains for el in ch.elements
                      for d in getattr(el, "defects", ())]
        self.free_units: np.ndarray = np.zeros(0)

    # ------------------------------------------------------------------------------------------- geometry
    def node_of(self, feature: dict) -> str:
        if feature["side"] == "output":  # a tool seat: the output frame, reached by the element named
            return self.bodies.canon("F:" + feature["element"])
        return self.bodies.canon(("L:" if feature["side"] == "fixed" else "P:") + feature["element"])

    def displacement(self, ref: str, node: str, point: np.ndarray, h: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
        """(rotation rows (3, n), displacement rows of ``point`` (3, n)) of ``node`` relative to ``ref``, base frame."""
        steps = self.bodies.path(ref)[self.bodies.canon(node)]
        w0 = self.bodies.world[self.bodies.canon(ref)]

        def pose(xi):
            t = w0.copy()
            for el, fw in steps:
                vals = np.zeros((1, 7))
                for d in getattr(el, "defects", ()):
                    vals[0, "IJKabcG".index(d.component)] = xi[self.col[d.name]]
                d_m = _element(el.placement, vals)[0] if getattr(el, "defects", ()) else _placement(el.placement)
                t = t @ (d_m if fw else np.linalg.inv(d_m))
            return t

        rot, disp = np.zeros((3, self.n)), np.zeros((3, self.n))
        used = {self.col[d.name] for el, _ in steps for d in getattr(el, "defects", ())}
        for i in used:
            xi = np.zeros(self.n)
            xi[i] = h
            a = pose(xi)
            xi[i] = -h
            b = pose(xi)
            dr = a[:3, :3] @ b[:3, :3].T
            rot[:, i] = 0.5 * np.array([dr[2, 1] - dr[1, 2], dr[0, 2] - dr[2, 0], dr[1, 0] - dr[0, 1]]) / (2 * h)
            pa = a[:3, :3] @ (b[:3, :3].T @ (point - b[:3, 3])) + a[:3, 3]  # the point carried by the relative motion
            disp[:, i] = (pa - point) / (2 * h)
        return rot, disp

    # ------------------------------------------------------------------------------------------- datums
    def plane_of(self, drawing: dict, letter: str) -> np.ndarray:
        """The normal of the plane through A and datum ``letter`` (the orientation plane of an indicator)."""
        a = self.datum_feature(drawing, "A")
        x = self.datum_feature(drawing, letter)
        na = _unit(a["direction"])
        nx = _unit(x["direction"])
        if x["kind"] != "axis":
            return _unit(nx - (nx @ na) * na)
        if abs(abs(nx @ na) - 1) < 1e-9:
            d = np.asarray(x["point_mm"]) - np.asarray(a["point_mm"])
            return _unit(np.cross(na, d - (d @ na) * na))
        return _unit(np.cross(na, nx))

    def datum_feature(self, drawing: dict, letter: str) -> dict:
        fid = next(d["feature"] for d in drawing["datums"] if d["letter"] == letter)
        return next(f for f in drawing["features"] if f["id"] == fid)

    def expected_direction(self, drawing: dict, frame: dict) -> np.ndarray | None:
        """The zone normal the frame states through its characteristic, datums and indicator."""
        if frame["zone_shape"] == "cylinder":
            return None
        feat = next(f for f in drawing["features"] if f["id"] == frame["feature"])
        n = _unit(feat["direction"])
        a = _unit(self.datum_feature(drawing, "A")["direction"])
        ind = frame.get("indicator")
        if feat["kind"] == "plane":
            return n
        if ind:
            nu = self.plane_of(drawing, ind["datum"])
            if ind["relation"] == "parallel":
                return _unit(nu - (nu @ n) * n)
            if ind["relation"] == "perpendicular":
                m = np.cross(a, nu)  # in the orientation plane, across A
                return _unit(m) if abs(_unit(m) @ n) < 1e-9 else None
            return None
        if frame["characteristic"] in ("parallelism", "perpendicularity", "angularity"):
            p = a - (a @ n) * n
            return _unit(p) if np.linalg.norm(p) > 1e-9 else None
        return a if abs(a @ n) < 1e-9 else None

    # ------------------------------------------------------------------------------------------- constraints
    def constraints(self) -> tuple[np.ndarray, np.ndarray, int]:
        """``A_ub z <= b_ub`` over ``z = (defects, free datum variables)``: every frame and requirement."""
        rows, rhs, extra, free_units = [], [], [], []
        ring = np.stack([np.cos(2 * np.pi * np.arange(SIDES) / SIDES), np.sin(2 * np.pi * np.arange(SIDES) / SIDES)],
                        axis=1)  # unit outward normals: the polygon circumscribed about the round zone
        for d in self.rep["drawings"]:
            a_f = self.datum_feature(d, "A") if d["datums"] else None
            if a_f is None:
                continue
            ref = self.node_of(a_f)
            na, pa = _unit(a_f["direction"]), np.asarray(a_f["point_mm"], float)
            for fr in d["frames"]:
                feat = next(f for f in d["features"] if f["id"] == fr["feature"])
                letters = fr["datum_system"]
                w_d, v_d = self._drf(d, ref, letters, na, pa)  # functions of a point: rows (3, n)
                n = _unit(feat["direction"])
                p = np.asarray(feat["point_mm"], float)
                orient = fr["characteristic"] in ("parallelism", "perpendicularity", "angularity")
                # free variables of this frame: rotation about A (no C), translation along A (no B), and for an
                # orientation zone every translation (it is not located)
                free = []
                if not self._locks_rotation(d, letters):
                    free.append(("rot", na))
                if orient:
                    free += [("tr", e) for e in np.eye(3)]
                elif "B" not in letters or not self._is_b_plane(d):
                    free.append(("tr", na))
                n_free = len(free)
                base = self.n + sum(extra)
                extra.append(n_free)
                free_units += [1e-3 if kind == "rot" else 1.0 for kind, _ in free]

                def rel_at(point: np.ndarray):
                    w_f, v_f = self.displacement(ref, self.node_of(feat), point)
                    w = w_f - w_d
                    v = v_f - v_d(point)
                    fw = np.zeros((3, n_free))
                    fv = np.zeros((3, n_free))
                    for j, (kind, e) in enumerate(free):
                        if kind == "rot":
                            fw[:, j] = -e
                            fv[:, j] = -np.cross(e, point - pa)
                        else:
                            fv[:, j] = -e
                    return w, v, fw, fv

                t = fr["zone_mm"]
                if feat["kind"] == "axis":
                    length = float(feat["length_mm"])
                    if orient:
                        w, _, fw, _ = rel_at(p)
                        tilt, tilt_f = np.cross(w.T, n).T, np.cross(fw.T, n).T  # (3, n): the direction's change
                        lines = self._zone_lines(fr, n, ring, t / length)
                        for g, r in lines:
                            rows.append(self._row(g @ tilt, g @ tilt_f, base, extra[-1])), rhs.append(r)
                    else:
                        for s in (-0.5 * length, 0.5 * length):
                            q = p + s * n
                            w, v, fw, fv = rel_at(q)
                            for g, r in self._zone_lines(fr, n, ring, t / 2.0):
                                rows.append(self._row(g @ v, g @ fv, base, extra[-1])), rhs.append(r)
                else:
                    w, v, fw, fv = rel_at(p)
                    for sgn in (1.0, -1.0):
                        rows.append(self._row(sgn * n @ v, sgn * n @ fv, base, extra[-1])), rhs.append(t / 2.0)
        total = self.n + sum(extra)
        self.free_units = np.array(free_units)
        a_ub = np.zeros((len(rows), total))
        for i, (cols, vals) in enumerate(rows):
            a_ub[i, :len(vals)] = 0.0
            a_ub[i, cols] = vals
        a_ub, b_ub = list(a_ub), list(rhs)
        for req in self.rep.get("assembly_requirements", []):
            s = self.statement(req["tolerances"][0])
            for sgn in (1.0, -1.0):
                r = np.zeros(total)
                r[:self.n] = sgn * s
                a_ub.append(r), b_ub.append(float(req["value"]))
        return np.array(a_ub), np.array(b_ub), total

    def _row(self, coef: np.ndarray, free_coef: np.ndarray, base: int, n_free: int):
        cols = list(range(self.n)) + list(range(base, base + n_free))
        return cols, np.r_[coef, free_coef]

    def _zone_lines(self, fr: dict, n: np.ndarray, ring: np.ndarray, half: float) -> list:
        """``(g, r)`` with ``g . x <= r``: a slab along the stated normal, or a polygon around a round zone."""
        if fr["zone_shape"] == "cylinder":
            e1 = _unit(np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))]))
            e2 = np.cross(n, e1)
            return [(c[0] * e1 + c[1] * e2, half) for c in ring]
        m = _unit(fr["zone_direction"])
        return [(m, half), (-m, half)]

    def _is_b_plane(self, d: dict) -> bool:
        return any(x["letter"] == "B" and self.datum_feature(d, "B")["kind"] == "plane" and abs(abs(
            _unit(self.datum_feature(d, "B")["direction"]) @ _unit(self.datum_feature(d, "A")["direction"])) - 1) < 1e-9
            for x in d["datums"])

    def _locks_rotation(self, d: dict, letters: list) -> bool:
        """A datum of the frame other than A that locks the rotation about A (a plane containing A's direction, or
        an axis not coaxial with A)."""
        a = self.datum_feature(d, "A")
        na = _unit(a["direction"])
        for x in letters:
            if x == "A":
                continue
            f = self.datum_feature(d, x)
            nx = _unit(f["direction"])
            if f["kind"] != "axis" and abs(nx @ na) < 1e-9:
                return True
            if f["kind"] == "axis":
                dd = np.asarray(f["point_mm"]) - np.asarray(a["point_mm"])
                if abs(abs(nx @ na) - 1) > 1e-9 or np.linalg.norm(dd - (dd @ na) * na) > 1e-6:
                    return True
        return False

    def _drf(self, d: dict, ref: str, letters: list, na: np.ndarray, pa: np.ndarray):
        """The datum frame's displacement relative to A's node: rotation rows (3, n) and a function point -> rows."""
        perp = np.eye(3) - np.outer(na, na)
        a_f = self.datum_feature(d, "A")
        w_a, v_a = self.displacement(ref, self.node_of(a_f), pa)
        w0 = perp @ w_a
        v0 = perp @ v_a
        if "B" in letters and self._is_b_plane(d):
            b = self.datum_feature(d, "B")
            pb = np.asarray(b["point_mm"], float)
            _, v_b = self.displacement(ref, self.node_of(b), pb)
            # the datum frame's point pa moves along A so that B's plane moves as datum B does
            v0 = v0 + np.outer(na, na @ v_b - na @ np.cross(w0.T, pb - pa).T)
        theta = np.zeros(self.n)
        for x in letters:
            if x in ("A", "B") and not (x == "B" and not self._is_b_plane(d)):
                continue
            f = self.datum_feature(d, x)
            nx = _unit(f["direction"])
            pf = np.asarray(f["point_mm"], float)
            w_c, v_c = self.displacement(ref, self.node_of(f), pf)
            if f["kind"] != "axis":
                if abs(nx @ na) < 1e-9:
                    theta = na @ w_c
            elif abs(abs(nx @ na) - 1) < 1e-9:
                e = perp @ (pf - pa)
                r = float(np.linalg.norm(e))
                if r > 1e-6:
                    v_at = v0 + np.cross(w0.T, pf - pa).T
                    theta = np.cross(na, e / r) @ (v_c - v_at) / r
            else:
                ac = np.cross(na, nx)
                theta = ac @ np.cross((w_c - w0).T, nx).T / float(ac @ ac)
        w_d = w0 + np.outer(na, theta)

        def v_d(point: np.ndarray) -> np.ndarray:
            return v0 + np.cross(w_d.T, point - pa).T

        return w_d, v_d

    # ------------------------------------------------------------------------------------------- statements
    def statement(self, tid: str) -> np.ndarray:
        item = next(t for t in self.rep["tolerances"]["items"] if t["id"] == tid)
        s = np.zeros(self.n)
        for name, c in item["terms"].items():
            s[self.col[name]] += c
        # a merged shift (printed "dc22 ≡ da12") is read as its equivalent: the same shift on the other element
        for g, r in (self.rep["tolerances"].get("redundant") or {}).items():
            if g in item["parameters"]:
                s[self.col[g]] = sum(s[self.col[p]] * c for p, c in r["coefficients"].items())
        return s

    def feature_rows(self) -> np.ndarray:
        """Every feature's displacement relative to its part's full datum system (tilts, shifts, along-axis), rows."""
        out = []
        for d in self.rep["drawings"]:
            if not d["datums"]:
                continue
            a_f = self.datum_feature(d, "A")
            ref = self.node_of(a_f)
            na, pa = _unit(a_f["direction"]), np.asarray(a_f["point_mm"], float)
            letters = [x["letter"] for x in d["datums"]]
            w_d, v_d = self._drf(d, ref, letters, na, pa)
            for f in d["features"]:
                p = np.asarray(f["point_mm"], float)
                w_f, v_f = self.displacement(ref, self.node_of(f), p)
                w, v = w_f - w_d, v_f - v_d(p)
                n = _unit(f["direction"])
                if f["kind"] == "axis":
                    out += list(np.cross(w.T, n).T) + list((np.eye(3) - np.outer(n, n)) @ v)
                elif f["kind"] == "plane":
                    out += [n @ v] + list(np.cross(w.T, n).T)
        return np.array(out)

    def physical(self, s: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, float]:
        """The statement read on what the features see: its orthogonal projection on their rows; and the share left
        out (motions no feature sees)."""
        coef = np.linalg.lstsq(rows.T, s, rcond=None)[0]
        sp = rows.T @ coef
        return sp, float(np.linalg.norm(s - sp) / max(np.linalg.norm(s), 1e-300))

    def extremes(self, s: np.ndarray, a_ub: np.ndarray, b_ub: np.ndarray, total: int) -> tuple[float, str]:
        """max |s . x| over the admitted defects: (value, status) with status ``bounded`` or ``unbounded``."""
        best = 0.0
        scale = np.maximum(b_ub, 1e-300)  # every row as a share of its zone: the solver's tolerance is relative
        # columns in comparable units: an angle in mrad, a length in mm (a free rotation as an angle)
        col = np.ones(total)
        col[:self.n] = [1e-3 if self.units[i] == "rad" else 1.0 for i in range(self.n)]
        col[self.n:] = self.free_units[:total - self.n]
        a_s = a_ub / scale[:, None] * col[None, :]
        for sgn in (1.0, -1.0):
            c = np.zeros(total)
            c[:self.n] = -sgn * s
            c = c * col
            for method, opts in (("highs-ds", {}), ("highs-ipm", {}), ("highs", {}), ("highs-ds", {"presolve": False})):
                res = linprog(c, A_ub=a_s, b_ub=b_ub / scale, bounds=[(None, None)] * total, method=method,
                              options=opts)
                if res.status in (0, 3):
                    break
            if res.status == 3:
                return math.inf, "unbounded"
            if not res.success:
                return math.nan, res.message
            best = max(best, -res.fun)
        return best, "bounded"
