"""Two robot arms, written from scratch (no hyperstat import): URDF text and forward kinematics.

Units inside: mm, rad, kg, N.  URDF files are written in metres.

Arms (geometry and masses are this generator's own choices, "published-like"):

* ``longarm6``: a medium industrial 6R (about 425 kg, 60 kg payload class) with a long forearm and a
  wrist whose joint-5 axis is offset 60 mm sideways (not a spherical wrist). Lengths and total mass
  follow the order of magnitude of the ABB IRB 4600-60/2.05 product specification (base height
  495 mm, shoulder offset 175 mm, upper arm 1095 mm, elbow offset 175 mm, forearm 1270 mm,
  total mass 425 kg); the split of the mass between links is this generator's estimate
  (rotating column 120 kg, upper arm 60 kg, forearm with wrist motors 80 kg, wrist 25 + 8 + 2 kg).
* ``cobot6``: a light 6R cobot (about 18 kg moving, 5 kg payload class) whose forearm rolls about
  its own axis (joint 4 along the forearm) and whose wrist has a 100 mm lateral offset.  Link
  masses are those of the Universal Robots UR5e dynamics table (3.761, 8.058, 2.846, 1.37, 1.3,
  0.365 kg) placed on this different geometry (shoulder height 155 mm, upper arm 411 mm, forearm
  368 mm, as in the Doosan M0609 datasheet's order of magnitude).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

G = 9.81  # m/s^2; forces in N with masses in kg


def rot_axis(axis, angle):
    """Rodrigues rotation matrix about a unit axis."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def rpy_matrix(r, p, y):
    """URDF convention: R = Rz(y) Ry(p) Rx(r)."""
    return rot_axis([0, 0, 1], y) @ rot_axis([0, 1, 0], p) @ rot_axis([1, 0, 0], r)


def rotvec(v):
    v = np.asarray(v, float)
    n = np.linalg.norm(v)
    return np.eye(3) if n == 0 else rot_axis(v / n, n)


def hom(R=None, p=None):
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


@dataclass
class Arm:
    name: str
    origins_xyz: list          # per joint (6) + tool: xyz in mm in the parent link frame
    origins_rpy: list          # rpy (rad)
    axes: list                 # 6 joint axes in the joint frame
    lower: list
    upper: list
    masses: list               # per moving link 1..6: (mass kg, com xyz mm in that link frame)
    base_mass: tuple           # fixed base (kg, com)
    targets1: list             # single reflector offset in the tool frame (mm)
    targets3: list             # three reflector offsets (mm)
    payload_com: tuple = (0.0, 0.0, 80.0)  # payload centre of mass in the tool frame (mm)
    designs: dict = field(default_factory=dict)  # pose design name -> list of (low, high) per joint
    payload_values: tuple = (0.0,)
    tracker: tuple = ((0, 0, 0), (0, 0, 0))   # position (mm), rotation vector in the base frame
    size_class: str = ""


LONGARM = Arm(
    name="longarm6",
    origins_xyz=[(0, 0, 495), (175, 0, 0), (0, 0, 1095), (400, 0, 175), (870, 60, 0), (135, 0, 0), (0, 0, 0)],
    origins_rpy=[(0, 0, 0)] * 6 + [(0, np.pi / 2, 0)],    # tool z along the last axis (x of link 6)
    axes=[(0, 0, 1), (0, 1, 0), (0, 1, 0), (1, 0, 0), (0, 1, 0), (1, 0, 0)],
    lower=[-3.0, -1.6, -3.0, -3.0, -2.1, -3.1],
    upper=[3.0, 2.6, 1.3, 3.0, 2.1, 3.1],
    masses=[(120.0, (-40, 0, 150)), (60.0, (0, 0, 520)), (80.0, (250, 0, 175)),
            (25.0, (420, 0, 0)), (8.0, (40, 30, 0)), (2.0, (30, 0, 0))],
    base_mass=(130.0, (0, 0, 200)),
    targets1=[(60.0, 0.0, 150.0)],                      # tool frame: z along the flange normal
    targets3=[(60.0, 0.0, 150.0), (-50.0, 55.0, 110.0), (-40.0, -70.0, 190.0)],
    designs={"full": [(-2.6, 2.6), (-0.9, 1.3), (-1.4, 0.8), (-2.6, 2.6), (-1.9, 1.9), (-3.0, 3.0)],
             "short2": [(-2.6, 2.6), (0.0, 1.4), (-0.6, 0.2), (-2.6, 2.6), (-1.9, 1.9), (-3.0, 3.0)]},
    payload_values=(0.0, 30.0, 60.0),
    tracker=((2600.0, -1900.0, 350.0), (0.0, 0.0, 0.6)),
    size_class="medium",
)

COBOT = Arm(
    name="cobot6",
    origins_xyz=[(0, 0, 155), (0, 0, 0), (0, 0, 411), (0, 0, 368), (0, 100, 0), (0, 0, 120), (0, 0, 0)],
    origins_rpy=[(0, 0, 0)] * 7,
    axes=[(0, 0, 1), (0, 1, 0), (0, 1, 0), (0, 0, 1), (0, 1, 0), (0, 0, 1)],
    lower=[-3.1, -2.0, -2.6, -3.1, -2.6, -3.1],
    upper=[3.1, 2.0, 2.6, 3.1, 2.6, 3.1],
    masses=[(3.761, (0, 0, -20)), (8.058, (0, 0, 205)), (2.846, (0, 0, 180)),
            (1.37, (0, 20, 0)), (1.3, (0, 0, 50)), (0.365, (0, 0, -10))],
    base_mass=(4.0, (0, 0, 60)),
    targets1=[(70.0, 0.0, 60.0)],
    targets3=[(70.0, 0.0, 60.0), (-45.0, 60.0, 45.0), (-40.0, -65.0, 80.0)],
    designs={"full": [(-2.8, 2.8), (-1.5, 1.5), (-2.3, 2.3), (-3.0, 3.0), (-2.2, 2.2), (-3.0, 3.0)],
             "short2": [(-2.8, 2.8), (-0.2, 1.2), (0.6, 1.4), (-3.0, 3.0), (-2.2, 2.2), (-3.0, 3.0)]},
    payload_values=(0.0, 2.0, 5.0),
    tracker=((1500.0, -1100.0, 100.0), (0.0, 0.0, 0.4)),
    size_class="light",
)

ARMS = {a.name: a for a in (LONGARM, COBOT)}


def urdf_text(arm: Arm, with_masses: bool) -> str:
    """URDF of the arm (metres), links base_link, link1..link6, tool0; inertials optional."""
    def inertial(m, c):
        if not with_masses:
            return ""
        i = 0.01 * m  # kg m^2, a plausible order (only the masses and centres matter here)
        return (f'    <inertial><origin xyz="{c[0]/1e3:.6f} {c[1]/1e3:.6f} {c[2]/1e3:.6f}" rpy="0 0 0"/>'
                f'<mass value="{m}"/><inertia ixx="{i}" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{i}"/></inertial>\n')
    out = [f'<?xml version="1.0"?>\n<robot name="{arm.name}">\n']
    out.append(f'  <link name="base_link">\n{inertial(*arm.base_mass)}  </link>\n')
    for i in range(6):
        out.append(f'  <link name="link{i+1}">\n{inertial(*arm.masses[i])}  </link>\n')
    out.append('  <link name="tool0"/>\n')
    names = ["base_link"] + [f"link{i+1}" for i in range(6)] + ["tool0"]
    for i in range(7):
        x, y, z = (v / 1e3 for v in arm.origins_xyz[i])
        r, p, yw = arm.origins_rpy[i]
        if i < 6:
            ax = arm.axes[i]
            out.append(f'  <joint name="j{i+1}" type="revolute">\n    <parent link="{names[i]}"/><child link="{names[i+1]}"/>\n'
                       f'    <origin xyz="{x:.6f} {y:.6f} {z:.6f}" rpy="{r:.9f} {p:.9f} {yw:.9f}"/>\n'
                       f'    <axis xyz="{ax[0]} {ax[1]} {ax[2]}"/>\n'
                       f'    <limit lower="{arm.lower[i]}" upper="{arm.upper[i]}" effort="1000" velocity="2"/>\n  </joint>\n')
        else:
            out.append(f'  <joint name="flange" type="fixed">\n    <parent link="{names[i]}"/><child link="{names[i+1]}"/>\n'
                       f'    <origin xyz="{x:.6f} {y:.6f} {z:.6f}" rpy="{r:.9f} {p:.9f} {yw:.9f}"/>\n  </joint>\n')
    out.append("</robot>\n")
    return "".join(out)


@dataclass
class Geometry:
    """A (possibly perturbed) geometry: 7 placements (4x4, mm) in the parent frame, 6 axes, zero offsets."""
    placements: list
    axes: list
    zero: np.ndarray


def nominal_geometry(arm: Arm) -> Geometry:
    pl = [hom(rpy_matrix(*arm.origins_rpy[i]), np.array(arm.origins_xyz[i], float)) for i in range(7)]
    return Geometry(pl, [np.array(a, float) for a in arm.axes], np.zeros(6))


def perturbed_geometry(arm: Arm, rng, dpos=0.05, drot=3e-4) -> Geometry:
    """True machine: each placement shifted by U(+-dpos) mm per axis and turned by U(+-drot) rad per axis,
    plus joint zero offsets U(+-drot)."""
    g = nominal_geometry(arm)
    pl = []
    for T in g.placements:
        D = hom(rotvec(rng.uniform(-drot, drot, 3)), rng.uniform(-dpos, dpos, 3))
        pl.append(T @ D)
    return Geometry(pl, g.axes, rng.uniform(-drot, drot, 6))


def frames(geo: Geometry, q, placement_hook=None):
    """Forward kinematics by composing URDF transforms: returns [F_link1..F_link6, F_tool] in the base frame.

    ``placement_hook(i, T_parent_world, placement) -> placement`` may modify a placement (deformations)."""
    T = np.eye(4)
    out = []
    for i in range(7):
        P = geo.placements[i]
        if placement_hook is not None:
            P = placement_hook(i, T, P)
        T = T @ P
        if i < 6:
            T = T @ hom(rot_axis(geo.axes[i], q[i] + geo.zero[i]))
        out.append(T)
    return out


def poe_tool(geo: Geometry, q):
    """Second, independent composition: product of exponentials with space screw axes taken at home."""
    home = frames(geo, np.zeros(6) - geo.zero)       # joint angles that make the true joints zero
    T = np.eye(4)
    for i in range(6):
        # joint frame i sits at home[i] (after its own rotation of zero)
        w = home[i][:3, :3] @ geo.axes[i]
        p = home[i][:3, 3]
        R = rot_axis(w, q[i] + geo.zero[i])
        T = T @ hom(R, p - R @ p)
    return T @ home[6]


def body_coms(arm: Arm, F):
    """World centres of mass (mm) of the 6 moving links for the frames F."""
    return [F[i][:3, :3] @ np.array(arm.masses[i][1], float) + F[i][:3, 3] for i in range(6)]


def potential(arm: Arm, F, payload_kg=0.0):
    """Gravitational potential energy (N mm) of the moving links and the payload."""
    V = sum(arm.masses[i][0] * G * c[2] for i, c in enumerate(body_coms(arm, F)))
    pc = F[6][:3, :3] @ np.array(arm.payload_com) + F[6][:3, 3]
    return V + payload_kg * G * pc[2]


def gravity_torque(arm: Arm, geo: Geometry, q, payload_kg=0.0, h=1e-6):
    """Gravity load tau_j = -dV/dq_j (N mm) by central differences of the potential energy."""
    tau = np.zeros(6)
    for j in range(6):
        dq = np.zeros(6)
        dq[j] = h
        tau[j] = -(potential(arm, frames(geo, q + dq), payload_kg) - potential(arm, frames(geo, q - dq), payload_kg)) / (2 * h)
    return tau


def gravity_torque_cross(arm: Arm, geo: Geometry, q, payload_kg=0.0):
    """Second method (self-check): tau_j = axis_j . sum_b (c_b - o_j) x (m_b g) over downstream bodies."""
    F = frames(geo, q)
    cs = body_coms(arm, F)
    pc = F[6][:3, :3] @ np.array(arm.payload_com) + F[6][:3, 3]
    g = np.array([0, 0, -G])
    tau = np.zeros(6)
    for j in range(6):
        w = F[j][:3, :3] @ geo.axes[j]
        o = F[j][:3, 3]
        m = sum(np.cross(cs[b] - o, arm.masses[b][0] * g) for b in range(j, 6))
        m = m + np.cross(pc - o, payload_kg * g)
        tau[j] = w @ m
    return tau
