"""The blind set's mechanisms: nominal model files and their families of mobile true machines.

Own designs (mm, rad).  Every model places each element in the previous frame; the home
configuration is solved by our own code (kin.py).  Every mechanism has a `true_defects(rng,
so, st)` that returns defect values (in the model's own defect parameters, so the true machine
is representable) that keep the true machine EXACTLY mobile:

* planar linkages written in space (fourbar, slidercrank, fivebar, watt6): in-plane origin
  shifts of every joint (free), one common tilt of the ground axes (all ground revolute axes
  stay parallel), normal shifts with one normal shift per loop solved so that the loop closes
  (the normal mismatch of a planar loop is constant), actuated zero offsets (G);
* bennett: perturbed Bennett parameters that still satisfy a1 = a3, a2 = a4, alpha1 = alpha3,
  alpha2 = alpha4, a1 / sin(alpha1) = a2 / sin(alpha2), offsets zero, plus one rigid
  displacement of the whole linkage;
* spherical: every axis tilted about the common centre (concurrency kept), plus one rigid
  displacement of the whole linkage;
* rsur (not over-constrained): every defect free.
"""
import math

import numpy as np

from . import kin

COMPS6 = ["I", "J", "K", "a", "b", "c"]


def T_of(R=None, o=(0, 0, 0)):
    return kin.hom(np.eye(3) if R is None else R, np.asarray(o, float))


def Rz(a):
    return kin.rot_axis([0, 0, 1], a)


def Rx(a):
    return kin.rot_axis([1, 0, 0], a)


def planar_world(p, ang):
    """World frame at point p (z = (0,0,1)), x turned by ang."""
    return T_of(Rz(ang), [p[0], p[1], p[2] if len(p) > 2 else 0.0])


def jel(name, T, role="passive", rng=(-3.14, 3.14), home=0.0, typ="R", comps=None):
    comps = list(COMPS6 if comps is None else comps)
    if role == "actuated" and typ == "R" and "G" not in comps:
        comps.append("G")
    return {"kind": "joint", "name": name, "type": typ, "role": role,
            "range": [float(rng[0]), float(rng[1])], "home": float(home),
            "placement": kin.placement_from_T(T),
            "defects": [{"component": c, "name": "d%s_%s" % (c, name)} for c in comps]}


def fel(name, T, comps=("I", "J", "K", "a", "b", "c", "G")):
    return {"kind": "fixed", "name": name, "placement": kin.placement_from_T(T),
            "defects": [{"component": c, "name": "d%s_%s" % (c, name)} for c in comps]}


def frel(name, T):
    return {"kind": "frame", "name": name, "placement": kin.placement_from_T(T)}


def model(name, desc, chains, output="TCP"):
    return {"format": "hyperstat-model", "version": 1,
            "units": {"length": "mm", "angle": "rad"},
            "name": name, "description": desc, "base": "R0", "output": output,
            "chains": chains, "metadata": {"origin": "blind_closure generator (own design)"}}


def chain(name, start, end, elements):
    return {"name": name, "start": start, "end": end, "elements": elements}


def rel(Wprev, W):
    return np.linalg.inv(Wprev) @ W


def circle_inter(P, r1, Q, r2, upper=True):
    P, Q = np.asarray(P, float)[:2], np.asarray(Q, float)[:2]
    d = np.linalg.norm(Q - P)
    a = (r1 ** 2 - r2 ** 2 + d ** 2) / (2 * d)
    h = math.sqrt(r1 ** 2 - a ** 2)
    m = P + a * (Q - P) / d
    perp = np.array([-(Q - P)[1], (Q - P)[0]]) / d
    return m + h * perp if upper else m - h * perp


def ang(P, Q):
    return math.atan2(Q[1] - P[1], Q[0] - P[0])


TOOL = T_of(Rz(0.3), [28.0, 17.0, 24.0])


# --------------------------------------------------------------------------- planar four-bar
def fourbar():
    A, D = np.array([50.0, 30.0]), np.array([210.0, 40.0])
    lab, lbc, ldc = 45.0, 150.0, 110.0
    th = math.radians(60)
    B = A + lab * np.array([math.cos(th), math.sin(th)])
    C = circle_inter(B, lbc, D, ldc, upper=True)
    WA, WB = planar_world(A, ang(A, B)), planar_world(B, ang(B, C))
    WC = planar_world(C, ang(B, C))
    WD = planar_world(D, ang(D, C))
    WCr = planar_world(C, ang(D, C))
    chains = [
        chain("crank", "R0", "C", [jel("A", WA, "actuated", (-3.1, 3.1)), jel("B", rel(WA, WB)),
                                   frel("Cc", rel(WB, WC))]),
        chain("rocker", "R0", "C", [jel("D", WD), jel("Cj", rel(WD, WCr)), frel("Cr", rel(WCr, WC))]),
        chain("tool", "C", "TCP", [frel("tool", TOOL)]),
    ]
    m = model("bc_fourbar", "planar crank-rocker four-bar written as a spatial model (over-constrained)", chains)
    fam = {"kind": "planar", "ground": ["A", "D"], "inplane": {"A": "ab", "B": "ab", "D": "ab", "Cj": "ab"},
           "normal": {"A": "c", "B": "c", "D": "c"}, "pivots": ["dc_Cj"], "actuated_G": ["A"]}
    return m, fam


# --------------------------------------------------------------------------- slider-crank
def slidercrank():
    O = np.array([0.0, 0.0])
    r, L, e = 40.0, 130.0, 12.0
    th = math.radians(60)
    B = O + r * np.array([math.cos(th), math.sin(th)])
    s = B[0] + math.sqrt(L ** 2 - (e - B[1]) ** 2)
    C = np.array([s, e])
    WO, WB = planar_world(O, ang(O, B)), planar_world(B, ang(B, C))
    WC = planar_world(C, ang(B, C))
    # prismatic joint: axis along base x, frame x = base z
    RP = np.column_stack([[0, 0, 1.0], [0, -1.0, 0], [1.0, 0, 0]])
    WP = T_of(RP, [0.0, e, 0.0])       # slide at zero travel
    WPs = WP @ T_of(None, [0, 0, s])   # at home travel s
    W3 = planar_world(C, ang(B, C))
    chains = [
        chain("crank", "R0", "C", [jel("O", WO), jel("B", rel(WO, WB)), frel("Cc", rel(WB, WC))]),
        chain("slide", "R0", "C", [jel("S", WP, "actuated", (100.0, 168.5), home=s, typ="P"),
                                   jel("Cj", rel(WPs, W3)), frel("Cs", rel(W3, WC))]),
        chain("tool", "C", "TCP", [frel("tool", TOOL)]),
    ]
    m = model("bc_slidercrank", "offset slider-crank driven by its slider, planar written in space (over-constrained)", chains)
    fam = {"kind": "slider", "pivots": ["da_Cj"]}
    return m, fam


# --------------------------------------------------------------------------- five-bar (2 dof)
def fivebar():
    A, E = np.array([0.0, 0.0]), np.array([90.0, 0.0])
    l1, l2 = 70.0, 110.0
    B = A + l1 * np.array([math.cos(math.radians(115)), math.sin(math.radians(115))])
    D = E + l1 * np.array([math.cos(math.radians(65)), math.sin(math.radians(65))])
    C = circle_inter(B, l2, D, l2, upper=True)
    WA, WB, WC = planar_world(A, ang(A, B)), planar_world(B, ang(B, C)), planar_world(C, ang(B, C))
    WE, WD, WCd = planar_world(E, ang(E, D)), planar_world(D, ang(D, C)), planar_world(C, ang(D, C))
    chains = [
        chain("left", "R0", "C", [jel("A", WA, "actuated", (-0.45, 0.45)), jel("B", rel(WA, WB)),
                                  frel("Cl", rel(WB, WC))]),
        chain("right", "R0", "C", [jel("E", WE, "actuated", (-0.45, 0.45)), jel("D", rel(WE, WD)),
                                   jel("Cj", rel(WD, WCd)), frel("Cr", rel(WCd, WC))]),
        chain("tool", "C", "TCP", [frel("tool", TOOL)]),
    ]
    m = model("bc_fivebar", "planar 2-dof five-bar written as a spatial model (over-constrained)", chains)
    fam = {"kind": "planar", "ground": ["A", "E"], "inplane": {"A": "ab", "B": "ab", "E": "ab", "D": "ab", "Cj": "ab"},
           "normal": {"A": "c", "B": "c", "E": "c", "D": "c"}, "pivots": ["dc_Cj"], "actuated_G": ["A", "E"]}
    return m, fam


# --------------------------------------------------------------------------- Watt II six-bar
def watt6():
    A, D, G = np.array([0.0, 0.0]), np.array([120.0, -10.0]), np.array([215.0, 95.0])
    lab, lbc, ldc = 35.0, 110.0, 80.0
    th = math.radians(30)
    B = A + lab * np.array([math.cos(th), math.sin(th)])
    C = circle_inter(B, lbc, D, ldc, upper=True)
    phi = ang(D, C)
    E = D + 70.0 * np.array([math.cos(phi - 0.9), math.sin(phi - 0.9)])
    lef, lgf = 100.0, 75.0
    F = circle_inter(E, lef, G, lgf, upper=True)
    WA, WB, WC = planar_world(A, ang(A, B)), planar_world(B, ang(B, C)), planar_world(C, ang(B, C))
    WD = planar_world(D, phi)
    WCj = planar_world(C, ang(B, C))
    WE = planar_world(E, ang(E, F))
    WF = planar_world(F, ang(E, F))
    WG = planar_world(G, ang(G, F))
    chains = [
        chain("crank", "R0", "C", [jel("A", WA, "actuated", (-3.1, 3.1)), jel("B", rel(WA, WB)),
                                   frel("Cc", rel(WB, WC))]),
        chain("rock", "R0", "ROCK", [jel("D", WD), frel("rk", np.eye(4))]),
        chain("cpl", "ROCK", "C", [jel("Cj", rel(WD, WCj)), frel("Ck", rel(WCj, WC))]),
        chain("ext", "ROCK", "CP2", [jel("E", rel(WD, WE)), frel("e2", np.eye(4))]),
        chain("cpl2", "CP2", "F", [jel("F", rel(WE, WF)), frel("Fe", np.eye(4))]),
        chain("rock2", "R0", "F", [jel("G", WG), frel("Fg", rel(WG, WF))]),
        chain("tool", "CP2", "TCP", [frel("tool", T_of(Rz(-0.2), [52.0, 21.0, 26.0]))]),
    ]
    m = model("bc_watt6", "planar Watt II six-bar (two loops) written as a spatial model (over-constrained)", chains)
    fam = {"kind": "planar", "ground": ["A", "D", "G"],
           "inplane": {"A": "ab", "B": "ab", "D": "ab", "Cj": "ab", "E": "ab", "F": "ab", "G": "ab"},
           "normal": {"A": "c", "B": "c", "D": "c", "E": "c", "G": "c"}, "pivots": ["dc_Cj", "dc_F"],
           "actuated_G": ["A"]}
    return m, fam


# --------------------------------------------------------------------------- Bennett / spherical
def loop_mats(a, al):
    return [T_of(Rx(al[i]), [a[i], 0, 0]) for i in range(4)]


def dh_loop_model(name, desc, a, al, q1_home, rng1, tool, loop_chain_fn=None):
    A1, A2, A3, A4 = loop_mats(a, al)
    chains = [
        chain("loop1", "R0", "E", [jel("J1", np.eye(4), "actuated", rng1, home=q1_home), jel("J2", A1),
                                   jel("J3", A2), fel("L3", A3), frel("Ea", np.eye(4))]),
        chain("loop2", "R0", "E", [jel("J4", np.linalg.inv(A4)), frel("Eb", np.eye(4))]),
        chain("tool", "E", "TCP", [frel("tool", tool)]),
    ]
    return model(name, desc, chains)


BENNETT = dict(a=[120.0, 0.0, 120.0, 0.0], al=[0.7, 1.2, 0.7, 1.2])
BENNETT["a"][1] = BENNETT["a"][3] = 120.0 * math.sin(1.2) / math.sin(0.7)
SPHERE = dict(a=[0.0, 0.0, 0.0, 0.0], al=[0.35, 1.2, 0.9, 1.0])


def bennett():
    m = dh_loop_model("bc_bennett", "Bennett linkage (over-constrained spatial 4R): a1=a3, a2=a4, "
                      "alpha1=alpha3, alpha2=alpha4, a/sin(alpha) equal", BENNETT["a"], BENNETT["al"],
                      0.9, (0.2, 1.9), T_of(Rz(0.4), [40.0, 35.0, 30.0]))
    return m, {"kind": "bennett"}


def spherical():
    m = dh_loop_model("bc_spherical", "spherical crank-rocker four-bar, four concurrent axes (over-constrained)",
                      SPHERE["a"], SPHERE["al"], 0.5, (-3.1, 3.1), T_of(Rz(0.2), [70.0, 45.0, 90.0]))
    return m, {"kind": "spherical"}


# --------------------------------------------------------------------------- RSUR
def rsur():
    A = np.zeros(3)
    r, rho = 40.0, 110.0
    D = np.array([40.0, -10.0, 150.0])
    nD = np.array([0.3, 0.95, 0.06])
    nD /= np.linalg.norm(nD)
    u = np.cross(nD, [0.3, 0.5, 0.8])
    u /= np.linalg.norm(u)
    v = np.cross(nD, u)
    th = np.linspace(0, 2 * np.pi, 181)
    ph = np.linspace(0, 2 * np.pi, 1441)
    Bs = r * np.stack([np.cos(th), np.sin(th), 0 * th], 1)
    Cs = D[None, :] + rho * (np.cos(ph)[:, None] * u + np.sin(ph)[:, None] * v)
    d = np.sqrt(((Bs[:, None, :] - Cs[None, :, :]) ** 2).sum(-1))
    Lrod = 0.5 * (d.min(1).max() + d.max(1).min())
    B = np.array([r, 0.0, 0.0])
    # home: rocker angle with |BC| = Lrod, first sign change of the distance along the rocker circle
    f = np.sqrt(((Cs - B) ** 2).sum(1)) - Lrod
    k = int(np.nonzero(np.sign(f[:-1]) != np.sign(f[1:]))[0][0])
    lo_, hi_ = ph[k], ph[k + 1]
    for _ in range(80):
        mid = 0.5 * (lo_ + hi_)
        fm = np.linalg.norm(D + rho * (math.cos(mid) * u + math.sin(mid) * v) - B) - Lrod
        if np.sign(fm) == np.sign(f[k]):
            lo_ = mid
        else:
            hi_ = mid
    C = D + rho * (math.cos(lo_) * u + math.sin(lo_) * v)
    WA = T_of(None, A)
    WS1 = T_of(None, B)
    WS2 = WS1 @ T_of(np.column_stack([[0, 1.0, 0], [0, 0, 1.0], [1.0, 0, 0]]))  # z along S1's x
    WS3 = WS2 @ T_of(np.column_stack([[0, 1.0, 0], [0, 0, 1.0], [1.0, 0, 0]]))  # z along S2's x
    rod = C - B
    u1 = np.cross(rod, nD)
    u1 /= np.linalg.norm(u1)
    u2 = np.cross(rod, u1)
    u2 /= np.linalg.norm(u2)
    r_hat = rod / np.linalg.norm(rod)
    WU1 = T_of(np.column_stack([r_hat, np.cross(u1, r_hat), u1]), C)
    WU2 = T_of(np.column_stack([u1, np.cross(u2, u1), u2]), C)
    xD = (C - D) / np.linalg.norm(C - D)
    WD = T_of(np.column_stack([xD, np.cross(nD, xD), nD]), D)
    chains = [
        chain("rod", "R0", "ROD", [jel("A", WA, "actuated", (-3.1, 3.1)), jel("S1", rel(WA, WS1)),
                                   jel("S2", rel(WS1, WS2)), jel("S3", rel(WS2, WS3)), frel("rd", np.eye(4))]),
        chain("u", "ROD", "K", [jel("U1", rel(WS3, WU1)), jel("U2", rel(WU1, WU2)), frel("Ku", np.eye(4))]),
        chain("rocker", "R0", "K", [jel("D", WD), frel("Kd", rel(WD, WU2))]),
        chain("tool", "ROD", "TCP", [frel("tool", T_of(Rz(0.5), [70.0, 30.0, 40.0]))]),
    ]
    m = model("bc_rsur", "spatial RSUR four-bar: spherical joint as three concurrent revolutes, universal as two "
              "(not over-constrained: 7 joints, 6 closure equations)", chains)
    return m, {"kind": "free"}


BUILDERS = {"fourbar": fourbar, "slidercrank": slidercrank, "fivebar": fivebar, "watt6": watt6,
            "bennett": bennett, "spherical": spherical, "rsur": rsur}
OVERCONSTRAINED = {"fourbar": True, "slidercrank": True, "fivebar": True, "watt6": True,
                   "bennett": True, "spherical": True, "rsur": False}


def solve_home(m, seed=0):
    """Solve the passive home values of a nominal model (home of the actuated joints fixed)."""
    mech = kin.Mechanism(m)
    q, nr, ok = mech.solve(mech.home)
    if ok:
        return q, mech
    rng = np.random.default_rng(seed)
    best = None
    for _ in range(200):
        q0 = mech.home.copy()
        q0[mech.pas] = rng.uniform(-math.pi, math.pi, len(mech.pas))
        q, nr, ok = mech.solve(q0, maxit=200)
        if ok and mech.passive_jacobian_sv(q) > 1e-2:
            return q, mech
        if best is None or nr < best[1]:
            best = (q, nr)
    raise RuntimeError("no home for %s (best %.3g)" % (m["name"], best[1]))


def build(name):
    m, fam = BUILDERS[name]()
    q, mech = solve_home(m)
    # write the solved home into the model
    for ch in m["chains"]:
        for el in ch["elements"]:
            if el["kind"] == "joint":
                v = float(q[mech.jindex[el["name"]]])
                v = math.remainder(v, 2 * math.pi) if el["type"] == "R" else v
                el["home"] = v
                if el["role"] != "actuated":
                    el["range"] = [-math.pi, math.pi] if el["type"] == "R" else el["range"]
    return m, fam


# --------------------------------------------------------------------------- true machines
def _element(m, name):
    for ch in m["chains"]:
        for el in ch["elements"]:
            if el["name"] == name:
                return el
    raise KeyError(name)


def _static_T(el):
    return kin.hom(kin.placement_R(el["placement"]), el["placement"]["origin"])


def _set_from_T(defs, el, T, keepG):
    R0 = kin.placement_R(el["placement"])
    o0 = np.asarray(el["placement"]["origin"], float)
    dn, do, G = kin.placement_to_defects(R0, o0, T[:3, :3], T[:3, 3])
    n = el["name"]
    for c, v in zip("IJK", dn):
        defs["d%s_%s" % (c, n)] = float(v)
    for c, v in zip("abc", do):
        defs["d%s_%s" % (c, n)] = float(v)
    if keepG:
        defs["dG_%s" % n] = float(G)


def true_defects(name, m, fam, rng, so, st):
    """Defect values of a mobile true machine; so: origin scale (mm), st: tilt scale (rad)."""
    defs = {}
    kind = fam["kind"]
    U = lambda s: float(rng.uniform(-s, s))
    if kind == "planar":
        for j, comps in fam["inplane"].items():
            for c in comps:
                defs["d%s_%s" % (c, j)] = U(so)
        for j, comps in fam["normal"].items():
            for c in comps:
                defs["d%s_%s" % (c, j)] = U(so)
        tI, tJ = U(st), U(st)
        for j in fam["ground"]:
            defs["dI_%s" % j] = tI
            defs["dJ_%s" % j] = tJ
        for j in fam["actuated_G"]:
            defs["dG_%s" % j] = U(st)
        solve_pivots(m, defs, fam["pivots"])
    elif kind == "slider":
        for j in ("O", "B"):
            defs["da_%s" % j] = U(so)
            defs["db_%s" % j] = U(so)
            defs["dc_%s" % j] = U(so)
        defs["da_S"], defs["db_S"], defs["dc_S"] = U(so), U(so), U(so)
        defs["dJ_S"] = U(st)  # in-plane turn of the slide (stays perpendicular to the normal)
        defs["db_Cj"], defs["dc_Cj"] = U(so), U(so)
        solve_pivots(m, defs, fam["pivots"])
    elif kind in ("bennett", "spherical"):
        base = BENNETT if kind == "bennett" else SPHERE
        a, al = list(base["a"]), list(base["al"])
        if kind == "bennett":
            a1 = a[0] + U(so)
            al1 = al[0] + U(st)
            al2 = al[1] + U(st)
            a2 = a1 * math.sin(al2) / math.sin(al1)
            a, al = [a1, a2, a1, a2], [al1, al2, al1, al2]
        else:
            al = [x + U(st) for x in al]
        A1, A2, A3, A4 = loop_mats(a, al)
        rv = np.array([U(st), U(st), U(st)])
        W = kin.hom(kin.rotvec(rv), [U(so), U(so), U(so)])
        _set_from_T(defs, _element(m, "J1"), W, keepG=True)
        _set_from_T(defs, _element(m, "J2"), A1, keepG=False)
        _set_from_T(defs, _element(m, "J3"), A2, keepG=False)
        _set_from_T(defs, _element(m, "L3"), A3, keepG=True)
        _set_from_T(defs, _element(m, "J4"), W @ np.linalg.inv(A4), keepG=False)
        defs["dG_J1"] += U(st)  # zero offset of the actuated crank on top of the rigid displacement
    elif kind == "free":
        for ch in m["chains"]:
            for el in ch["elements"]:
                if el["kind"] != "joint":
                    continue
                n0 = np.asarray(el["placement"]["z_axis"], float)
                t = rng.normal(size=3)
                t -= n0 * np.dot(t, n0)
                t *= U(st) / np.linalg.norm(t)
                for c, v in zip("IJK", t):
                    defs["d%s_%s" % (c, el["name"])] = float(v)
                for c in "abc":
                    defs["d%s_%s" % (c, el["name"])] = U(so)
                if el["role"] == "actuated":
                    defs["dG_%s" % el["name"]] = U(st)
    # drop the G of passive joints (absorbed by the joint value: same machine)
    for ch in m["chains"]:
        for el in ch["elements"]:
            if el["kind"] == "joint" and el["role"] != "actuated":
                defs.pop("dG_%s" % el["name"], None)
    declared = {d["name"] for ch in m["chains"] for el in ch["elements"] for d in el.get("defects", [])}
    unknown = set(defs) - declared
    assert not unknown, unknown
    return defs


def solve_pivots(m, defs, pivots, K=5):
    """Solve the pivot defects so that every loop closes at K configurations (Gauss-Newton on
    pivots + passive joints; the family guarantees a solution that closes everywhere)."""
    mech0 = kin.Mechanism(m)
    for p in pivots:
        defs[p] = 0.0
    # configurations: nominal followed from home to K actuated values
    qa_h = mech0.home[mech0.act]
    lo = np.array([mech0.joints[i][3][0] for i in mech0.act])
    hi = np.array([mech0.joints[i][3][1] for i in mech0.act])
    targets = [qa_h + (f - 0.5) * 0.3 * (hi - lo) for f in np.linspace(0.2, 0.8, K)]
    qs = mech0.follow(targets)
    x = np.zeros(len(pivots))
    for it in range(30):
        d = dict(defs)
        for p, v in zip(pivots, x):
            d[p] = v
        mech = kin.Mechanism(m, d)
        qs = [mech.solve(q)[0] for q in qs]
        r = np.concatenate([mech.residual(q) for q in qs])
        if np.linalg.norm(r) < 1e-12:
            break
        # Jacobian wrt pivots (passives re-solved): finite differences
        J = np.empty((len(r), len(pivots)))
        for k in range(len(pivots)):
            d2 = dict(d)
            d2[pivots[k]] += 1e-6
            mech2 = kin.Mechanism(m, d2)
            r2 = np.concatenate([mech2.residual(mech2.solve(q)[0]) for q in qs])
            J[:, k] = (r2 - r) / 1e-6
        x = x + np.linalg.lstsq(J, -r, rcond=None)[0]
    for p, v in zip(pivots, x):
        defs[p] = float(v)
