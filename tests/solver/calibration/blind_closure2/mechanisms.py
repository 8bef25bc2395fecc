"""The seven mechanisms of blind closure set 2 (mm, rad), designed from absolute home geometry.

Every element's placement is derived from the absolute frames of the home configuration, so the
nominal model closes at home by construction.  Each mechanism also has a truth recipe: defect
values (by public name) that keep the machine mobile (planar loops stay planar, the spherical
five-bar stays concurrent, the triple parallel crank keeps three equal parallel cranks).
"""
from __future__ import annotations

import math

import numpy as np

from .kin import Hmat, Rz, Tz, inv_h, rot_axis_angle, unit

ALL_J = ("I", "J", "K", "a", "b", "c")
ALL_F = ("I", "J", "K", "a", "b", "c", "G")
RANGE_R = [-3.1, 3.1]


def frame(origin, z, xh):
    z = unit(z)
    xh = np.asarray(xh, float)
    x = unit(xh - np.dot(xh, z) * z)
    y = np.cross(z, x)
    return Hmat(np.column_stack([x, y, z]), np.asarray(origin, float))


def _pl(D):
    def r(v):
        return [float(t) for t in v]
    return {"origin": r(D[:3, 3]), "z_axis": r(D[:3, 2]), "x_axis": r(D[:3, 0])}


class CB:
    """Chain builder: absolute frames at home in, relative placements out."""

    def __init__(self, name, start, end, P=None):
        self.name, self.start, self.end = name, start, end
        self.P = np.eye(4) if P is None else P.copy()
        self.els = []
        self.info = {}

    def _defects(self, name, comps):
        return [{"component": c, "name": "d%s%s" % (c, name)} for c in comps]

    def joint(self, name, jt, role, rng, home, origin, z, xh, comps=ALL_J):
        L = frame(origin, z, xh)
        D = inv_h(self.P) @ L
        self.info[name] = {"Rprev": self.P[:3, :3].copy(), "z0": D[:3, 2].copy(), "kind": "joint"}
        el = {"kind": "joint", "name": name, "type": jt, "role": role, "range": [float(rng[0]), float(rng[1])],
              "home": float(home), "placement": _pl(D), "defects": self._defects(name, comps)}
        self.els.append(el)
        self.P = L @ (Rz(home) if jt == "R" else Tz(home))
        return self

    def fixed(self, name, origin, z, xh, comps=ALL_F):
        L = frame(origin, z, xh)
        D = inv_h(self.P) @ L
        self.info[name] = {"Rprev": self.P[:3, :3].copy(), "z0": D[:3, 2].copy(), "kind": "fixed"}
        self.els.append({"kind": "fixed", "name": name, "placement": _pl(D), "defects": self._defects(name, comps)})
        self.P = L
        return self

    def frame_abs(self, name, T):
        D = inv_h(self.P) @ T
        self.els.append({"kind": "frame", "name": name, "placement": _pl(D)})
        self.P = T.copy()
        return self

    def chain(self):
        return {"name": self.name, "start": self.start, "end": self.end, "elements": self.els}


def model(name, desc, chains, output="TOOL"):
    return {"format": "hyperstat-model", "version": 1, "units": {"length": "mm", "angle": "rad"},
            "name": name, "description": desc, "base": "R0", "output": output,
            "chains": [c.chain() for c in chains], "metadata": {"author": "blind closure set 2 generator"}}


def circles(c1, r1, c2, r2, pick):
    """Intersection of two circles in the x-y plane; pick(pA, pB) chooses."""
    c1 = np.asarray(c1, float)[:2]
    c2 = np.asarray(c2, float)[:2]
    d = np.linalg.norm(c2 - c1)
    a = (r1 * r1 - r2 * r2 + d * d) / (2 * d)
    h = math.sqrt(r1 * r1 - a * a)
    m = c1 + a * (c2 - c1) / d
    perp = np.array([-(c2 - c1)[1], (c2 - c1)[0]]) / d
    pA, pB = m + h * perp, m - h * perp
    p = pick(pA, pB)
    return np.array([p[0], p[1], 0.0])


def mount(normal, xh, origin):
    T = frame(origin, normal, xh)
    c = CB("mount", "R0", "PL")
    c.frame_abs("TPL", T)
    return c


Z = np.array([0.0, 0.0, 1.0])


def p3(x, y, z=0.0):
    return np.array([x, y, z], float)


# ------------------------------------------------------------------ 1. PRRRP five-bar
def five_bar_prrrp():
    m = mount(unit([0.25, -0.35, 1.0]), [1, 0.1, 0], [100.0, -50.0, 40.0])
    s1 = 200.0
    u1 = p3(1, 0)
    R2 = p3(s1, 30.0)
    S5 = p3(520.0, -20.0)
    u5 = p3(math.cos(math.radians(160)), math.sin(math.radians(160)))
    s5 = 180.0
    R4 = S5 + s5 * u5 + p3(0, 25.0)
    E = circles(R2, 260.0, R4, 220.0, lambda a, b: a if a[1] > b[1] else b)
    C = frame(E, Z, R4 - E)
    a = CB("legA", "PL", "C")
    a.joint("11", "P", "actuated", [110.0, 290.0], s1, p3(0, 0), u1, Z, comps=())
    a.joint("12", "R", "passive", RANGE_R, 0.0, R2, Z, E - R2)
    a.joint("13", "R", "passive", RANGE_R, 0.0, E, Z, R4 - E)
    a.frame_abs("TC", C)
    b = CB("legB", "PL", "C")
    b.joint("21", "P", "actuated", [100.0, 260.0], s5, S5, u5, Z)
    b.joint("22", "R", "passive", RANGE_R, 0.0, R4, Z, E - R4)
    b.fixed("23", E, Z, R4 - E)
    b.frame_abs("TC2", C)
    t = CB("tool", "C", "TOOL", C)
    tp = E - 70.0 * unit(R4 - E) + p3(0, 0, 45.0)
    t.fixed("31", tp, unit([0.1, 0.0, 1.0]), R4 - E)
    t.frame_abs("TT", frame(tp, unit([0.1, 0.0, 1.0]), R4 - E))
    mdl = model("bc2_five_bar_prrrp", "planar five-bar P-R-R-R-P, two sliders, unequal links, in a tilted plane",
                [m, a, b, t])
    return mdl, {"planar": ["12", "13", "21", "22", "23"], "tool": ["31"]}, [m, a, b, t]


# ------------------------------------------------------------------ 2. 3-RPR
def rpr3():
    m = mount(unit([-0.2, 0.3, 1.0]), [1, 0, 0.2], [-80.0, 60.0, 0.0])
    A = [p3(0, 0), p3(420, 0), p3(180, 360)]
    Pc = p3(200, 170)
    phi = 1.6
    B = [Pc + 110.0 * p3(math.cos(phi + t), math.sin(phi + t)) for t in (math.radians(210), math.radians(330), math.radians(90))]
    PF = frame(Pc, Z, p3(math.cos(phi), math.sin(phi)))
    chains = [m]
    for i in range(3):
        c = CB("leg%d" % (i + 1), "PL", "PF")
        li = float(np.linalg.norm(B[i] - A[i]))
        u = unit(B[i] - A[i])
        c.joint("%d1" % (i + 1), "R", "passive", RANGE_R, 0.0, A[i], Z, u, comps=() if i == 0 else ALL_J)
        c.joint("%d2" % (i + 1), "P", "actuated", [li - 50.0, li + 50.0], li, A[i], u, Z)
        c.joint("%d3" % (i + 1), "R", "passive", RANGE_R, 0.0, B[i], Z, p3(1, 0))
        if i == 0:
            c.frame_abs("TPF", PF)
        else:
            c.fixed("%d4" % (i + 1), Pc, Z, p3(math.cos(phi), math.sin(phi)))
            c.frame_abs("TPF%d" % (i + 1), PF)
        chains.append(c)
    t = CB("tool", "PF", "TOOL", PF)
    tp = Pc + p3(30.0, -20.0, 60.0)
    t.fixed("51", tp, Z, p3(1, 0))
    t.frame_abs("TT", frame(tp, Z, p3(1, 0)))
    chains.append(t)
    mdl = model("bc2_rpr3", "planar 3-RPR parallel manipulator, three prismatic actuators, tilted plane", chains)
    planar = ["12", "13", "21", "22", "23", "24", "31", "32", "33", "34"]
    return mdl, {"planar": planar, "tool": ["51"]}, chains


# ------------------------------------------------------------------ 3. Stephenson III six-bar
def stephenson():
    m = mount(unit([0.0, 0.4, 1.0]), [1, 0, 0], [0.0, 0.0, 100.0])
    A0, B0, D0 = p3(0, 0), p3(240, 0), p3(330, 200)
    th = math.radians(70)
    A = 70.0 * p3(math.cos(th), math.sin(th))
    B = circles(A, 210.0, B0, 160.0, lambda a, b: a if a[1] > b[1] else b)
    uAB = unit(B - A)
    nAB = np.cross(Z, uAB)
    Cp = A + 120.0 * uAB + 80.0 * nAB
    E = circles(Cp, 190.0, D0, 150.0, lambda a, b: a if a[0] > b[0] else b)
    CPL = frame(A, Z, uAB)
    CE = frame(Cp, Z, E - Cp)
    c1 = CB("crank", "PL", "CPL")
    c1.joint("11", "R", "actuated", [th - 0.6, th + 0.6], th, A0, Z, p3(1, 0), comps=())
    c1.joint("12", "R", "passive", RANGE_R, 0.0, A, Z, uAB)
    c1.frame_abs("TCPL", CPL)
    c2 = CB("rocker", "PL", "CPL")
    c2.joint("21", "R", "passive", RANGE_R, 0.0, B0, Z, B - B0)
    c2.joint("22", "R", "passive", RANGE_R, 0.0, B, Z, A - B)
    c2.fixed("23", A, Z, uAB)
    c2.frame_abs("TCPL2", CPL)
    c3 = CB("dyad1", "CPL", "CE", CPL)
    c3.joint("31", "R", "passive", RANGE_R, 0.0, Cp, Z, E - Cp)
    c3.frame_abs("TCE", CE)
    c4 = CB("dyad2", "PL", "CE")
    c4.joint("41", "R", "passive", RANGE_R, 0.0, D0, Z, E - D0)
    c4.joint("42", "R", "passive", RANGE_R, 0.0, E, Z, Cp - E)
    c4.fixed("43", Cp, Z, E - Cp)
    c4.frame_abs("TCE2", CE)
    t = CB("tool", "CE", "TOOL", CE)
    tp = 0.5 * (Cp + E) + 40.0 * np.cross(Z, unit(E - Cp)) + p3(0, 0, 50.0)
    t.fixed("51", tp, Z, E - Cp)
    t.frame_abs("TT", frame(tp, Z, E - Cp))
    chains = [m, c1, c2, c3, c4, t]
    mdl = model("bc2_stephenson3", "Stephenson III six-bar: crank-rocker four-bar plus a dyad from the coupler point to the ground", chains)
    return mdl, {"planar": ["12", "21", "22", "23", "31", "41", "42", "43"], "tool": ["51"]}, chains


# ------------------------------------------------------------------ 4. triple parallel crank
TC_R = 90.0


def triple_crank():
    m = mount(unit([0.3, 0.0, 1.0]), [0, 1, 0], [50.0, 50.0, 0.0])
    G = [p3(0, 0), p3(260, 0), p3(40, 200)]
    th = math.radians(40)
    u = p3(math.cos(th), math.sin(th))
    Cs = [g + TC_R * u for g in G]
    CPL = frame(Cs[0], Z, p3(1, 0))
    chains = [m]
    for i in range(3):
        c = CB("crank%d" % (i + 1), "PL", "CPL")
        if i == 0:
            c.joint("11", "R", "actuated", [0.2, 1.2], th, G[0], Z, p3(1, 0), comps=())
        else:
            c.joint("%d1" % (i + 1), "R", "passive", RANGE_R, 0.0, G[i], Z, u)
        # crank frame of chain 1 has x along PL x at q = 0, along the crank at home
        c.joint("%d2" % (i + 1), "R", "passive", RANGE_R, 0.0, Cs[i], Z, p3(1, 0))
        if i == 0:
            c.frame_abs("TCPL", CPL)
        else:
            c.fixed("%d3" % (i + 1), Cs[0], Z, p3(1, 0))
            c.frame_abs("TCPL%d" % (i + 1), CPL)
        chains.append(c)
    t = CB("tool", "CPL", "TOOL", CPL)
    tp = Cs[0] + p3(60.0, 30.0, 50.0)
    t.fixed("41", tp, Z, p3(1, 0))
    t.frame_abs("TT", frame(tp, Z, p3(1, 0)))
    chains.append(t)
    mdl = model("bc2_triple_crank", "three equal parallel cranks carrying a translating coupler (over-constrained even in the plane)", chains)
    return mdl, {"custom": True, "tool": ["41"]}, chains


def triple_crank_truth(rng, s_len, s_ang, chains):
    d = {}
    # crank 1 (chain 1): length and zero offset, in the frame of joint 11 (x along PL x at q = 0)
    # joint 12's origin in the joint-11 frame is r (cos th, sin th): perturb along and across the crank
    # the frame after joint 11 at home has x along the crank: joint 12's origin is (r, 0, 0) there
    dr, dt = rng.uniform(-1, 1, 2) * s_len
    d["da12"], d["db12"] = float(dr), float(dt)
    r1 = math.hypot(TC_R + dr, dt)
    for i in (2, 3):
        # joint i1's frame has x along the crank: joint i2's origin is (r, 0, 0) there
        d["da%d2" % i] = r1 - TC_R
        g = rng.uniform(-1, 1, 2) * s_len
        d["da%d1" % i], d["db%d1" % i] = float(g[0]), float(g[1])
        # coupler pivot i in the coupler frame (PL-aligned): follows the ground pivot
        d["da%d3" % i], d["db%d3" % i] = float(-g[0]), float(-g[1])
    return d


# ------------------------------------------------------------------ 5. spherical five-bar
def spherical_5bar():
    O = p3(0, 0, 250.0)
    a = math.radians(35)
    u1 = p3(-math.sin(a), 0, math.cos(a))
    u5 = p3(math.sin(a), 0, math.cos(a))
    al1, al2 = math.radians(55), math.radians(70)
    # proximal axes: u1 tilted by al1 away from the vertical plane, then turned about u1
    w1 = rot_axis_angle(p3(0, 1, 0), -al1) @ u1
    w5 = rot_axis_angle(p3(0, 1, 0), al1) @ u5
    ph = math.radians(60)
    u2 = rot_axis_angle(u1, -ph) @ w1
    u4 = rot_axis_angle(u5, ph) @ w5
    # u3: angle al2 from u2 and from u4, upper solution
    n = unit(np.cross(u2, u4))
    c = math.cos(al2)
    Mx = np.vstack([u2, u4])
    base = np.linalg.lstsq(Mx, np.array([c, c]), rcond=None)[0]
    h = math.sqrt(max(0.0, 1 - base @ base))
    cand = [base + h * n, base - h * n]
    u3 = max(cand, key=lambda v: v[2])
    D = frame(O, u3, u4 - np.dot(u4, u3) * u3)
    ca = CB("legA", "R0", "D")
    ca.joint("1", "R", "actuated", [-0.5, 0.5], 0.0, O, u1, u2, comps=())
    ca.joint("2", "R", "passive", RANGE_R, 0.0, O, u2, u3)
    ca.joint("3", "R", "passive", RANGE_R, 0.0, O, u3, u4 - np.dot(u4, u3) * u3)
    ca.frame_abs("TD", D)
    cb = CB("legB", "R0", "D")
    cb.joint("5", "R", "actuated", [-0.5, 0.5], 0.0, O, u5, u4)
    cb.joint("4", "R", "passive", RANGE_R, 0.0, O, u4, u3)
    cb.fixed("43", O, u3, u4 - np.dot(u4, u3) * u3)
    cb.frame_abs("TD2", D)
    t = CB("tool", "D", "TOOL", D)
    tp = D[:3, :3] @ p3(30.0, -20.0, 200.0) + O
    t.fixed("61", tp, u3, D[:3, 0])
    t.frame_abs("TT", frame(tp, u3, D[:3, 0]))
    chains = [ca, cb, t]
    mdl = model("bc2_spherical_5bar", "spherical five-bar, two actuated base joints, all five axes through one point", chains)
    return mdl, {"spherical": ["2", "3", "5", "4", "43"], "tool": ["61"]}, chains


# ------------------------------------------------------------------ 6. 2-RPR in a near-vertical plane
def rpr2():
    m = mount(unit([0.1, -1.0, 0.2]), [1, 0, 0], [0.0, 0.0, 300.0])
    A1, A2, T = p3(0, 0), p3(380, 0), p3(170, 260)
    u1, u2 = unit(T - A1), unit(T - A2)
    l1, l2 = float(np.linalg.norm(T - A1)), float(np.linalg.norm(T - A2))
    R2 = frame(T, Z, u2)
    c1 = CB("leg1", "PL", "ROD2")
    c1.joint("11", "R", "passive", RANGE_R, 0.0, A1, Z, u1, comps=())
    c1.joint("12", "P", "actuated", [l1 - 50.0, l1 + 50.0], l1, A1, u1, Z)
    c1.joint("13", "R", "passive", RANGE_R, 0.0, T, Z, u2)
    c1.frame_abs("TR", R2)
    c2 = CB("leg2", "PL", "ROD2")
    c2.joint("21", "R", "passive", RANGE_R, 0.0, A2, Z, u2)
    c2.joint("22", "P", "actuated", [l2 - 50.0, l2 + 50.0], l2, A2, u2, Z)
    c2.fixed("23", T, Z, u2)
    c2.frame_abs("TR2", R2)
    t = CB("tool", "ROD2", "TOOL", R2)
    tp = T + 60.0 * u2 + p3(0, 0, 40.0)
    t.fixed("31", tp, Z, u2)
    t.frame_abs("TT", frame(tp, Z, u2))
    chains = [m, c1, c2, t]
    mdl = model("bc2_rpr2", "planar 2-RPR (two prismatic legs meeting at one pivot) in a near-vertical plane", chains)
    return mdl, {"planar": ["12", "13", "21", "22", "23"], "tool": ["31"]}, chains


# ------------------------------------------------------------------ 7. spatial 8R loop, 2 dof (not over-constrained)
def spatial8r():
    J11 = (p3(0, 0, 0), p3(1, 0, 0))
    PA = p3(0, 110, 20)
    J12 = (PA, unit([0, 0.3, 1]))
    J13 = (PA, unit(np.cross(J12[1], [0.2, 1, 0.1])))
    M = p3(160, 220, 90)
    J14 = (M, unit([0.2, 1, 0.1]))
    J15 = (M, unit(np.cross(J14[1], [1, -0.2, 0.4])))
    PB = p3(330, 100, 60)
    J21 = (p3(320, 0, 0), unit([1, 0, 0.3]))
    J22 = (PB, unit([0, 0.2, 1]))
    J23 = (PB, unit(np.cross(J22[1], [0.3, 1, 0])))
    L3 = frame(M, J15[1], PB - M)
    ca = CB("legA", "R0", "L3")
    ca.joint("11", "R", "actuated", [-0.45, 0.45], 0.0, J11[0], J11[1], p3(0, 1, 0), comps=())
    for nm, (o, z) in (("12", J12), ("13", J13), ("14", J14), ("15", J15)):
        ca.joint(nm, "R", "passive", RANGE_R, 0.0, o, z, p3(0.3, 0.5, 0.8) if abs(np.dot(z, unit([0.3, 0.5, 0.8]))) < 0.9 else p3(1, 0, 0))
    ca.frame_abs("TL3", L3)
    cb = CB("legB", "R0", "L3")
    cb.joint("21", "R", "actuated", [-0.45, 0.45], 0.0, J21[0], J21[1], PB - J21[0])
    cb.joint("22", "R", "passive", RANGE_R, 0.0, J22[0], J22[1], M - PB)
    cb.joint("23", "R", "passive", RANGE_R, 0.0, J23[0], J23[1], M - PB)
    cb.fixed("24", M, J15[1], PB - M)
    cb.frame_abs("TL32", L3)
    t = CB("tool", "L3", "TOOL", L3)
    tp = M + p3(40.0, 60.0, 80.0)
    t.fixed("31", tp, p3(0, 0, 1), p3(1, 0, 0))
    t.frame_abs("TT", frame(tp, p3(0, 0, 1), p3(1, 0, 0)))
    chains = [ca, cb, t]
    mdl = model("bc2_spatial8r", "spatial single loop of eight revolute joints with generic axes, two actuated: mobility 2, not over-constrained", chains)
    return mdl, {"free": ["12", "13", "14", "15", "21", "22", "23", "24"], "tool": ["31"]}, chains


MECHANISMS = {
    "five_bar_prrrp": five_bar_prrrp,
    "rpr3": rpr3,
    "stephenson3": stephenson,
    "triple_crank": triple_crank,
    "spherical_5bar": spherical_5bar,
    "rpr2": rpr2,
    "spatial8r": spatial8r,
}
OVER_CONSTRAINED = {"five_bar_prrrp": True, "rpr3": True, "stephenson3": True, "triple_crank": True,
                    "spherical_5bar": True, "rpr2": True, "spatial8r": False}


def _comps(el):
    return [d["component"] for d in el.get("defects", [])]


def truth_defects(key, rng, s_len, s_ang):
    """Defect values (public names) of a true machine that stays mobile."""
    mdl, groups, chains = MECHANISMS[key]()
    info = {}
    els = {}
    for c in chains:
        info.update(c.info)
        for el in c.els:
            els[el["name"]] = el
    d = {}

    def full(name):
        for comp in _comps(els[name]):
            s = s_len if comp in "abc" else s_ang
            d["d%s%s" % (comp, name)] = float(rng.uniform(-1, 1) * s)

    if groups.get("custom"):
        d.update(triple_crank_truth(rng, s_len, s_ang, chains))
    for name in groups.get("free", []):
        full(name)
    for name in groups.get("spherical", []):
        for comp in _comps(els[name]):
            if comp in "IJKG":
                d["d%s%s" % (comp, name)] = float(rng.uniform(-1, 1) * s_ang)
    for name in groups.get("planar", []):
        el = els[name]
        comps = _comps(el)
        n_loc = info[name]["Rprev"].T @ Z  # plane normal (PL z) in the previous frame
        z0 = info[name]["z0"]
        # origin shift inside the plane
        basis = [c for c in comps if c in "abc"]
        E = np.array([[1.0 if "abc".index(c) == k else 0.0 for k in range(3)] for c in basis]).T
        A = (n_loc @ E)[None, :]
        _, s, vt = np.linalg.svd(A)
        null = vt[int(np.sum(s > 1e-9)):]
        x = null.T @ rng.uniform(-1, 1, null.shape[0]) * s_len
        for c, v in zip(basis, x):
            d["d%s%s" % (c, name)] = float(v)
        # axis: parallel to the normal -> no tilt; in the plane (slide) -> tilt inside the plane
        if abs(abs(float(np.dot(z0, n_loc))) - 1.0) < 1e-9:
            if "G" in comps:
                d["dG%s" % name] = float(rng.uniform(-1, 1) * s_ang)
        elif abs(float(np.dot(z0, n_loc))) < 1e-9:
            dn = float(rng.uniform(-1, 1) * s_ang) * np.cross(n_loc, z0)
            for k, c in enumerate("IJK"):
                if c in comps:
                    d["d%s%s" % (c, name)] = float(dn[k])
                elif abs(dn[k]) > 1e-15:
                    raise ValueError("%s lacks component %s for an in-plane tilt" % (name, c))
        else:
            raise ValueError("element %s: axis neither normal to nor in the plane" % name)
    for name in groups.get("tool", []):
        full(name)
    return d
