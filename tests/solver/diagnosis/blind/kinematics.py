"""The blind generator's own robots: two 6R arms, their URDF files, forward kinematics and masses.

Written for issue 28 (item 7) without reading any of hyperstat's diagnosis, effects or
kinematics code; nothing here imports hyperstat.  Conventions are URDF's (the file format the
arms are handed to hyperstat in): every joint has an origin (xyz in metres, roll-pitch-yaw
``R = Rz(yaw) Ry(pitch) Rx(roll)``) in its parent link's frame, then a rotation ``q`` about its
unit ``axis``.  Internally everything is SI (m, rad, kg, N); the campaign writer converts to
the measurement file's units.

Arms
----
``ind6``: an industrial 6R with a shoulder offset, the size class of a 16 kg-payload arm
(base height 520 mm, shoulder offset 180 mm, upper arm 700 mm, elbow offset 120 mm, forearm
330 + 390 mm, wrist 110 mm, flange 50 mm); 164 kg of moving links.  Its link masses are
our own estimate for that size class (cast aluminium housings with motors), not a vendor's.

``cobot6``: a UR10-like collaborative arm (upper arm 612 mm, forearm 572.3 mm, the UR10's
lateral offsets 220.9 / 171.9 / 114.9 mm, wrist 115.7 mm, flange 92.2 mm) laid out in our own
frames (zero configuration: arm stretched horizontally along +x).  Masses 7.1, 12.7, 4.27,
2.0, 2.0, 0.365 kg: Universal Robots, "Parameters for calculations of kinematics and dynamics"
(UR10 table); centres of mass are our own placement along the links.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Dict, List, Optional, Sequence

import numpy as np

G = 9.80665  # m/s^2, standard gravity
GVEC = np.array([0.0, 0.0, -G])


# --------------------------------------------------------------------------- rotations

def rpy_matrix(rpy: Sequence[float]) -> np.ndarray:
    """URDF roll-pitch-yaw: ``Rz(y) @ Ry(p) @ Rx(r)`` (fixed axes x, then y, then z)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def rot_about(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: rotations by ``angle`` (K,) about the unit ``axis`` (3,); returns (K, 3, 3)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    t = np.asarray(angle, float)[:, None, None]
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * (k @ k)


def exp_so3(w: np.ndarray) -> np.ndarray:
    """Rotation matrices of rotation vectors ``w`` (K, 3) or (3,)."""
    w = np.asarray(w, float)
    single = w.ndim == 1
    w = np.atleast_2d(w)
    th = np.linalg.norm(w, axis=1)
    out = np.repeat(np.eye(3)[None], len(w), axis=0)
    nz = th > 1e-15
    if np.any(nz):
        out[nz] = rot_about_many(w[nz] / th[nz, None], th[nz])
    return out[0] if single else out


def rot_about_many(axes: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Rodrigues for one axis per angle: axes (K, 3) unit, angles (K,)."""
    k = np.zeros((len(axes), 3, 3))
    k[:, 0, 1], k[:, 0, 2] = -axes[:, 2], axes[:, 1]
    k[:, 1, 0], k[:, 1, 2] = axes[:, 2], -axes[:, 0]
    k[:, 2, 0], k[:, 2, 1] = -axes[:, 1], axes[:, 0]
    t = angles[:, None, None]
    return np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * (k @ k)


def log_so3(r: np.ndarray) -> np.ndarray:
    """Rotation vector of one rotation matrix (angle below pi)."""
    c = (np.trace(r) - 1) / 2
    th = math.acos(max(-1.0, min(1.0, c)))
    if th < 1e-12:
        return np.zeros(3)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return v * th / (2 * math.sin(th))


def homogeneous(r: np.ndarray, p: np.ndarray) -> np.ndarray:
    """4x4 (or (K,4,4)) transforms from rotations and translations."""
    r = np.asarray(r, float)
    p = np.asarray(p, float)
    if r.ndim == 2 and p.ndim == 1:
        t = np.eye(4)
        t[:3, :3], t[:3, 3] = r, p
        return t
    k = r.shape[0] if r.ndim == 3 else p.shape[0]
    t = np.repeat(np.eye(4)[None], k, axis=0)
    t[:, :3, :3] = r
    t[:, :3, 3] = p
    return t


# --------------------------------------------------------------------------- arms

@dataclasses.dataclass
class Joint:
    name: str
    xyz: np.ndarray          # m, origin in the parent link frame
    rpy: np.ndarray          # rad, URDF roll-pitch-yaw of the origin
    axis: np.ndarray         # unit axis in the joint frame
    lower: float             # rad
    upper: float             # rad


@dataclasses.dataclass
class Beam:
    """A link treated as an Euler-Bernoulli beam clamped at its root (in the link's own frame)."""
    link: int                # 1..6: the body of joint ``link``
    start: np.ndarray        # m, root of the beam in the link frame
    direction: np.ndarray    # unit vector along the beam in the link frame
    length: float            # m
    EI: float                # N m^2, bending stiffness
    GJ: float                # N m^2 / rad, torsional stiffness


@dataclasses.dataclass
class Arm:
    name: str
    joints: List[Joint]
    tool_xyz: np.ndarray      # m, flange -> tool0 (fixed joint)
    tool_rpy: np.ndarray
    masses: List[float]       # kg, bodies of joints 1..6 (link i moves with joint i)
    coms: List[np.ndarray]    # m, centre of mass of link i in its own frame
    payload_max: float        # kg
    stiffness: np.ndarray     # N m / rad per joint (true joint stiffness of the compliance cases)
    beams: Dict[str, Beam]
    pedestal_height: float    # m
    pedestal_EI: float        # N m^2
    tracker_distance: float   # m, from the base axis
    link_names: List[str]
    tool_length_hint: float   # m, reach from joint 2 to the flange (for scale)

    @property
    def n(self) -> int:
        return len(self.joints)

    def ranges(self) -> np.ndarray:
        return np.array([[j.lower, j.upper] for j in self.joints])


def _j(name, xyz, rpy, axis, lo, hi):
    return Joint(name, np.array(xyz, float), np.array(rpy, float), np.array(axis, float), lo, hi)


def make_ind6() -> Arm:
    joints = [
        _j("A1", [0, 0, 0.52], [0, 0, 0], [0, 0, 1], -2.95, 2.95),
        _j("A2", [0.18, 0, 0], [0, 0, 0], [0, 1, 0], -1.30, 1.55),
        _j("A3", [0, 0, 0.70], [0, 0, 0], [0, 1, 0], -1.25, 1.65),
        _j("A4", [0.33, 0, 0.12], [0, 0, 0], [1, 0, 0], -3.00, 3.00),
        _j("A5", [0.39, 0, 0], [0, 0, 0], [0, 1, 0], -2.00, 2.00),
        _j("A6", [0.11, 0, 0], [0, 0, 0], [1, 0, 0], -3.00, 3.00),
    ]
    masses = [88.0, 36.0, 27.0, 9.0, 3.5, 0.5]
    coms = [np.array(c, float) for c in ([0.06, 0.0, 0.10], [0.0, -0.035, 0.33], [0.10, 0.02, 0.10],
                                         [0.21, 0.0, 0.0], [0.05, 0.0, 0.0], [0.02, 0.0, 0.0])]
    # Upper arm: cast aluminium box section ~180 x 140 mm, 9 mm wall: I ~ 2.1e-5 m^4,
    # E = 70 GPa -> EI ~ 1.5e6 N m^2 (beam formula, not a vendor figure); forearm tube
    # (link 4) Ø130 x 6 mm aluminium: I = pi/64 (D^4 - d^4) = 4.5e-6 m^4 -> EI 3.2e5.
    beams = {
        "upper": Beam(2, np.zeros(3), np.array([0, 0, 1.0]), 0.70, 1.5e6, 1.2e6),
        "fore": Beam(4, np.zeros(3), np.array([1.0, 0, 0]), 0.39, 3.2e5, 2.4e5),
    }
    return Arm(
        name="blind_ind6", joints=joints, tool_xyz=np.array([0.05, 0, 0]),
        tool_rpy=np.array([0, math.pi / 2, 0]), masses=masses, coms=coms, payload_max=16.0,
        # Joint stiffness of a medium industrial arm, order 1e6 N m/rad on the main axes
        # (joint-stiffness identifications of industrial 6R arms, e.g. Dumas et al., Robotica
        # 2011, report this order for heavier KUKA arms); wrist axes softer.
        stiffness=np.array([3.0e6, 2.0e6, 1.2e6, 4.0e5, 3.0e5, 2.0e5]),
        beams=beams,
        # Pedestal: steel tube Ø200 x 8 mm, 0.8 m high: I = pi/64 (0.2^4 - 0.184^4) = 2.3e-5
        # m^4, E = 210 GPa -> EI = 4.9e6 N m^2 (cantilever with an end moment).
        pedestal_height=0.8, pedestal_EI=4.9e6,
        tracker_distance=2.6,
        link_names=["base_link", "turret", "upper_arm", "elbow_housing", "forearm", "wrist", "flange", "tool0"],
        tool_length_hint=1.6,
    )


def make_cobot6() -> Arm:
    joints = [
        _j("shoulder_pan", [0, 0, 0.1273], [0, 0, 0], [0, 0, 1], -3.05, 3.05),
        _j("shoulder_lift", [0, 0.2209, 0], [0, 0, 0], [0, 1, 0], -3.05, 0.05),
        _j("elbow", [0.612, -0.1719, 0], [0, 0, 0], [0, 1, 0], -2.70, 2.70),
        _j("wrist_1", [0.5723, 0, 0], [0, 0, 0], [0, 1, 0], -3.05, 3.05),
        _j("wrist_2", [0, 0.1149, 0], [0, 0, 0], [0, 0, -1], -3.05, 3.05),
        _j("wrist_3", [0, 0, -0.1157], [0, 0, 0], [0, 1, 0], -3.05, 3.05),
    ]
    masses = [7.1, 12.7, 4.27, 2.0, 2.0, 0.365]
    coms = [np.array(c, float) for c in ([0.0, 0.02, 0.0], [0.306, 0.0, 0.0], [0.27, 0.0, 0.0],
                                         [0.0, 0.05, 0.0], [0.0, 0.0, -0.05], [0.0, 0.07, 0.0])]
    # Upper-arm tube Ø100 x 4 mm aluminium: I = pi/64 (0.1^4 - 0.092^4) = 1.39e-6 m^4,
    # EI = 70e9 * I = 9.8e4 N m^2, GJ = 26e9 * 2 I = 7.2e4 N m^2/rad.  Forearm tube
    # Ø75 x 3.5 mm: I = 5.0e-7 m^4, EI = 3.5e4, GJ = 2.6e4.  (Beam formulas, our sections.)
    beams = {
        "upper": Beam(2, np.zeros(3), np.array([1.0, 0, 0]), 0.612, 9.8e4, 7.2e4),
        "fore": Beam(3, np.zeros(3), np.array([1.0, 0, 0]), 0.5723, 3.5e4, 2.6e4),
    }
    return Arm(
        name="blind_cobot6", joints=joints, tool_xyz=np.array([0, 0.0922, 0]),
        tool_rpy=np.array([-math.pi / 2, 0, 0]), masses=masses, coms=coms, payload_max=10.0,
        # Strain-wave (harmonic drive) joints: catalogue torsional stiffness K3 of order 1e5
        # N m/rad for sizes 32-40 (Harmonic Drive CSF/CSG tables), lower for the wrist sizes.
        stiffness=np.array([1.5e5, 1.5e5, 1.0e5, 3.0e4, 3.0e4, 3.0e4]),
        beams=beams,
        # A cobot on a welded steel stand 0.8 m high, 100 x 100 x 4 mm square tube:
        # I = (0.1^4 - 0.092^4)/12 = 2.4e-6 m^4, EI = 5.0e5 N m^2.
        pedestal_height=0.8, pedestal_EI=5.0e5,
        tracker_distance=2.2,
        link_names=["base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
                    "wrist_2_link", "wrist_3_link", "tool0"],
        tool_length_hint=1.3,
    )


ARMS = {"ind6": make_ind6, "cobot6": make_cobot6}


def get_arm(name: str) -> Arm:
    return ARMS[name]()


# --------------------------------------------------------------------------- URDF

def write_urdf(arm: Arm, path: str, with_masses: bool = True) -> None:
    """The arm as a URDF (metres, radians), with ``<inertial>`` per moving link or without any."""
    def fmt(v):
        return " ".join(repr(float(x)) for x in v)

    lines = ['<?xml version="1.0"?>', f'<robot name="{arm.name}{"" if with_masses else "_nomass"}">']
    for i, ln in enumerate(arm.link_names):
        if with_masses and 1 <= i <= arm.n:
            m = arm.masses[i - 1]
            c = arm.coms[i - 1]
            ii = max(m * 0.01, 1e-4)  # a plausible diagonal inertia (kg m^2); only the mass and CoM matter here
            lines.append(f'  <link name="{ln}"><inertial><origin xyz="{fmt(c)}" rpy="0 0 0"/>'
                         f'<mass value="{m!r}"/><inertia ixx="{ii!r}" ixy="0" ixz="0" iyy="{ii!r}" iyz="0" izz="{ii!r}"/>'
                         f'</inertial></link>')
        else:
            lines.append(f'  <link name="{ln}"/>')
    for i, jt in enumerate(arm.joints):
        lines.append(
            f'  <joint name="{jt.name}" type="revolute"><parent link="{arm.link_names[i]}"/>'
            f'<child link="{arm.link_names[i + 1]}"/><origin xyz="{fmt(jt.xyz)}" rpy="{fmt(jt.rpy)}"/>'
            f'<axis xyz="{fmt(jt.axis)}"/><limit lower="{jt.lower!r}" upper="{jt.upper!r}" effort="1000" velocity="2"/></joint>')
    lines.append(
        f'  <joint name="tool_fixed" type="fixed"><parent link="{arm.link_names[arm.n]}"/>'
        f'<child link="{arm.link_names[arm.n + 1]}"/><origin xyz="{fmt(arm.tool_xyz)}" rpy="{fmt(arm.tool_rpy)}"/></joint>')
    lines.append("</robot>")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


# --------------------------------------------------------------------------- geometry errors

@dataclasses.dataclass
class Geometry:
    """The true machine's placement errors (SI): per origin (6 joints + tool) a shift and a
    small rotation (applied after the origin's nominal rotation), and joint zero offsets."""
    dxyz: np.ndarray   # (7, 3) m
    drot: np.ndarray   # (7, 3) rad, rotation vector in the origin frame
    dq0: np.ndarray    # (6,) rad

    @staticmethod
    def nominal(n: int = 6) -> "Geometry":
        return Geometry(np.zeros((n + 1, 3)), np.zeros((n + 1, 3)), np.zeros(n))

    @staticmethod
    def random(rng: np.random.Generator, n: int = 6, shift: float = 5e-5, tilt: float = 3e-4,
               offset: float = 3e-4) -> "Geometry":
        # Placement errors uniform in +-0.05 mm and +-0.3 mrad per origin, zero offsets +-0.3 mrad:
        # machining of bearing seats (a few hundredths of a mm) and mastering (0.01-0.02 deg).
        return Geometry(rng.uniform(-shift, shift, (n + 1, 3)), rng.uniform(-tilt, tilt, (n + 1, 3)),
                        rng.uniform(-offset, offset, n))


# --------------------------------------------------------------------------- forward kinematics

def _origin(arm: Arm, geom: Geometry, i: int, k: int, scale: Optional[np.ndarray]) -> np.ndarray:
    """Origin transform of joint i (i = n: the tool) for k poses, (k, 4, 4)."""
    if i < arm.n:
        xyz, rpy = arm.joints[i].xyz, arm.joints[i].rpy
    else:
        xyz, rpy = arm.tool_xyz, arm.tool_rpy
    r = rpy_matrix(rpy) @ exp_so3(geom.drot[i])
    p = xyz + geom.dxyz[i]
    s = np.ones(k) if scale is None else scale[:, i]
    out = np.repeat(np.eye(4)[None], k, axis=0)
    out[:, :3, :3] = r
    out[:, :3, 3] = s[:, None] * p[None, :]
    return out


def frames(arm: Arm, geom: Geometry, q: np.ndarray, base: Optional[np.ndarray] = None,
           deform: Optional[Dict[int, np.ndarray]] = None, scale: Optional[np.ndarray] = None) -> List[np.ndarray]:
    """World frames of the base, of links 1..6 (after each joint's rotation) and of tool0.

    ``base`` (K,4,4): the robot base in the world (default identity).  ``deform[i]`` (K,4,4):
    a deformation of link i (0 = base) applied in its frame just before the next origin.
    ``scale`` (K, 7): per-pose factor on each origin's translation (thermal growth).
    Returns a list of n + 2 arrays (K, 4, 4).
    """
    q = np.atleast_2d(q)
    k = q.shape[0]
    t = np.repeat(np.eye(4)[None], k, axis=0) if base is None else base.copy()
    out = [t]
    for i in range(arm.n + 1):
        if deform and i in deform:
            t = t @ deform[i]
        t = t @ _origin(arm, geom, i, k, scale)
        if i < arm.n:
            rot = np.repeat(np.eye(4)[None], k, axis=0)
            rot[:, :3, :3] = rot_about(arm.joints[i].axis, q[:, i] + geom.dq0[i])
            t = t @ rot
        out.append(t)
    return out


def points(tool: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """World positions (K, T, 3) of target offsets (T, 3) or (K, T, 3) in the tool frame."""
    off = offsets if offsets.ndim == 3 else np.broadcast_to(offsets, (tool.shape[0],) + offsets.shape)
    return np.einsum("kij,ktj->kti", tool[:, :3, :3], off) + tool[:, None, :3, 3]


def com_positions(arm: Arm, fr: List[np.ndarray]) -> np.ndarray:
    """World centres of mass (K, 7, 3): links 1..6 then the payload (at the tool0 origin)."""
    k = fr[0].shape[0]
    out = np.zeros((k, arm.n + 1, 3))
    for i in range(arm.n):
        f = fr[i + 1]
        out[:, i] = np.einsum("kij,j->ki", f[:, :3, :3], arm.coms[i]) + f[:, :3, 3]
    out[:, arm.n] = fr[arm.n + 1][:, :3, 3]
    return out


def mass_vector(arm: Arm, payload: np.ndarray) -> np.ndarray:
    """(K, 7) masses of links 1..6 and the payload per pose."""
    k = len(payload)
    return np.concatenate([np.broadcast_to(np.array(arm.masses), (k, arm.n)), payload[:, None]], axis=1)


def potential(arm: Arm, geom: Geometry, q: np.ndarray, payload: np.ndarray) -> np.ndarray:
    """Gravity potential energy (J) per pose: sum m g z over the links and the payload."""
    fr = frames(arm, geom, q)
    z = com_positions(arm, fr)[:, :, 2]
    return G * np.sum(mass_vector(arm, payload) * z, axis=1)


def gravity_torques(arm: Arm, geom: Geometry, q: np.ndarray, payload: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """tau = -dV/dq (N m), central differences of the potential energy; (K, 6).

    tau_j is the torque gravity exerts on joint j in the direction of +q_j, i.e. the side
    a compliant joint or a clearance gives way to.
    """
    tau = np.zeros_like(q)
    for j in range(arm.n):
        dq = np.zeros(arm.n)
        dq[j] = h
        tau[:, j] = -(potential(arm, geom, q + dq, payload) - potential(arm, geom, q - dq, payload)) / (2 * h)
    return tau
