"""The two serial arms of the fifth blind generator, with their own forward kinematics.

* ``kr_like``: a KUKA-like heavy 6R (KR 210 class), modified Denavit-Hartenberg (Craig) table in
  degrees, spherical wrist, declared link masses (726 kg of moving links), controller joints
  A1..A6 in degrees with a joint map (signs and zero offsets).  Imported into hyperstat from the
  modified-DH YAML this module writes (``hyperstat import-robot``); the masses are declared in the
  model file's ``metadata.masses`` (docs/diagnosis.md, "Gravity from the model's masses").
* ``lbr_like``: a 7-joint lightweight arm (LBR iiwa class: joints about z, +-90 deg twists between
  them, axes 5-6-7 meeting at the wrist centre), written as a URDF with ``<inertial>`` masses,
  imported with ``hyperstat import-robot robot.urdf``.

Every arm is a list of fixed transforms ``F_i`` followed by a rotation ``Rz(q_i)`` about the
joint's z axis, then the tool transform: ``T = F_1 Rz(q_1) ... F_n Rz(q_n) F_tool``.  For the
modified DH table ``F_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)`` (Rz(theta + q) Tz(d)
= Rz(theta) Tz(d) Rz(q)); for the URDF ``F_i = Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll)``.
Units: mm, rad (degrees only in the files written for the controller and the DH table).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import geom

G = 9.81  # m/s^2; forces in N, moments in N mm


@dataclass
class Arm:
    name: str
    joints: list                 # model joint names
    F: list                      # fixed transforms before each joint (4x4)
    F_tool: np.ndarray
    ranges: list                 # model ranges (rad)
    windows: list                # pose-design windows (rad)
    masses: list                 # per body: (mass kg, com (3,) in the frame after joint i)
    controller: list             # controller joint names (same order)
    sign: list                   # q_model = sign * J + offset  (J and offset in deg)
    offset_deg: list
    parallel_pairs: list = field(default_factory=list)   # consecutive joints with parallel axes (link bending)

    # ------------------------------------------------------------------ kinematics
    def frames(self, q, F=None, F_tool=None, link_post=None):
        """World transforms after each joint's motion, and the tool (output) frame.

        link_post: dict i -> 4x4 applied after joint i's motion (link deformations)."""
        F = self.F if F is None else F
        F_tool = self.F_tool if F_tool is None else F_tool
        t = np.eye(4)
        out = []
        for i, (fi, qi) in enumerate(zip(F, q)):
            t = t @ fi @ geom.rot_z(qi)
            if link_post and i in link_post:
                t = t @ link_post[i]
            out.append(t)
        return out, t @ F_tool

    def tool(self, q, **kw):
        return self.frames(q, **kw)[1]

    def joint_axes(self, q, F=None):
        """World (axis, point) of each joint at q."""
        F = self.F if F is None else F
        t = np.eye(4)
        axes = []
        for fi, qi in zip(F, q):
            t = t @ fi
            axes.append((t[:3, 2].copy(), t[:3, 3].copy()))
            t = t @ geom.rot_z(qi)
        return axes

    def potential(self, q, masses=None, payload=0.0, F=None, F_tool=None):
        """Gravity potential (N mm) of the bodies and the payload (at the tool frame origin);
        gravity along -z of the base."""
        masses = self.masses if masses is None else masses
        fr, tool = self.frames(q, F=F, F_tool=F_tool)
        v = 0.0
        for t, (m, c) in zip(fr, masses):
            v += m * G * (t[:3, :3] @ c + t[:3, 3])[2]
        v += payload * G * tool[2, 3]
        return v

    def gravity_torques(self, q, masses=None, payload=0.0, F=None, F_tool=None, h=1e-6):
        """tau = -dV/dq by central differences (N mm): the torque gravity applies on each joint."""
        q = np.asarray(q, dtype=float)
        tau = np.zeros(len(q))
        for j in range(len(q)):
            dq = np.zeros(len(q))
            dq[j] = h
            tau[j] = -(self.potential(q + dq, masses, payload, F, F_tool)
                       - self.potential(q - dq, masses, payload, F, F_tool)) / (2 * h)
        return tau

    def base_moment(self, q, masses=None, payload=0.0, F=None, F_tool=None):
        """Moment (N mm) of the moving bodies' weight and the payload about the base origin."""
        masses = self.masses if masses is None else masses
        fr, tool = self.frames(q, F=F, F_tool=F_tool)
        g = np.array([0.0, 0.0, -G])
        m = np.zeros(3)
        for t, (mass, c) in zip(fr, masses):
            m += np.cross(t[:3, :3] @ c + t[:3, 3], mass * g)
        m += np.cross(tool[:3, 3], payload * g)
        return m

    def to_controller(self, q):
        """Controller joints (deg) from model joints (rad)."""
        return [(np.degrees(qi) - o) / s for qi, s, o in zip(q, self.sign, self.offset_deg)]

    def com_world(self, q):
        fr, _ = self.frames(q)
        return [t[:3, :3] @ c + t[:3, 3] for t, (m, c) in zip(fr, self.masses)]


# ---------------------------------------------------------------------- KUKA-like 6R
# modified DH rows: alpha_{i-1} (deg), a_{i-1} (mm), theta_i (deg), d_i (mm), min, max (deg)
KR_ROWS = [
    (0.0, 0.0, 0.0, 675.0, -170.0, 170.0),
    (-90.0, 350.0, -90.0, 0.0, -50.0, 85.0),
    (0.0, 1150.0, 0.0, 0.0, -120.0, 65.0),
    (-90.0, -41.0, 0.0, 1200.0, -185.0, 185.0),
    (90.0, 0.0, 0.0, 0.0, -120.0, 120.0),
    (-90.0, 0.0, 0.0, 0.0, -350.0, 350.0),
]
KR_TOOL = 215.0
# bodies moved by each joint: mass (kg), centre of mass in the frame after that joint (mm)
KR_MASSES = [
    (318.0, np.array([-90.0, 25.0, -250.0])),     # rotating column (frame 1 is 675 mm up)
    (168.0, np.array([560.0, 0.0, -95.0])),       # link arm, along x2 (upward at home)
    (176.0, np.array([-60.0, -30.0, 0.0])),       # arm with the wrist motors behind the elbow
    (41.0, np.array([0.0, 0.0, -260.0])),         # in-line wrist housing (frame 4 at the wrist centre)
    (18.0, np.array([0.0, -35.0, 0.0])),
    (5.0, np.array([0.0, 0.0, 170.0])),           # flange and reflector fixture
]


def kr_like() -> Arm:
    F = []
    for al, a, th, d, lo, hi in KR_ROWS:
        F.append(geom.rot_x(np.radians(al)) @ geom.trans(a, 0, 0) @ geom.rot_z(np.radians(th))
                 @ geom.trans(0, 0, d))
    ranges = [(np.radians(r[4]), np.radians(r[5])) for r in KR_ROWS]
    windows = [(-1.92, 1.92), (-0.6, 1.4), (-1.65, 0.95), (-2.6, 2.6), (-1.75, 1.75), (-2.95, 2.95)]
    return Arm("kr_like", [str(i) for i in range(1, 7)], F, geom.trans(0, 0, KR_TOOL), ranges, windows,
               [(m, c.copy()) for m, c in KR_MASSES], [f"A{i}" for i in range(1, 7)],
               sign=[1, 1, 1, -1, 1, -1], offset_deg=[0.0, 90.0, -90.0, 0.0, 0.0, 0.0],
               parallel_pairs=[(1, 2)])


def kr_dh_yaml() -> str:
    lines = ["format: hyperstat-dh", "version: 1", "name: kr_like",
             "convention: modified-dh                # Craig: T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i + q_i) Tz(d_i)",
             "units: {length: mm, angle: deg}",
             f"tool: {{origin: [0, 0, {KR_TOOL:g}], rpy: [0, 0, 0]}}",
             "joints:"]
    for i, (al, a, th, d, lo, hi) in enumerate(KR_ROWS, start=1):
        lines.append(f"  - {{name: \"{i}\", type: R, a: {a:g}, alpha: {al:g}, d: {d:g}, theta: {th:g}, "
                     f"min: {lo:g}, max: {hi:g}}}")
    arm = kr_like()
    lines += ["joint_map:                              # q_model = sum(coefficient * J) / ratio + offset",
              "  units: {angle: deg}", "  joints:"]
    for j, c, s, o in zip(arm.joints, arm.controller, arm.sign, arm.offset_deg):
        entry = f"{c}: {s}" + (f", offset: {o:g}" if o else "")
        lines.append(f"    \"{j}\": {{{entry}}}")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------- LBR-like 7-joint arm
# URDF joints: origin xyz (mm), rpy (rad), axis z; limits (rad)
LBR_JOINTS = [
    ("lbr_a1", (0.0, 0.0, 160.0), (0.0, 0.0, 0.0), (-2.96, 2.96)),
    ("lbr_a2", (0.0, 0.0, 200.0), (np.pi / 2, 0.0, np.pi), (-2.09, 2.09)),
    ("lbr_a3", (0.0, 205.0, 0.0), (np.pi / 2, 0.0, np.pi), (-2.96, 2.96)),
    ("lbr_a4", (0.0, 0.0, 215.0), (np.pi / 2, 0.0, 0.0), (-2.09, 2.09)),
    ("lbr_a5", (0.0, 185.0, 0.0), (-np.pi / 2, np.pi, 0.0), (-2.96, 2.96)),
    ("lbr_a6", (0.0, 0.0, 215.0), (np.pi / 2, 0.0, 0.0), (-2.09, 2.09)),
    ("lbr_a7", (0.0, 81.0, 0.0), (-np.pi / 2, np.pi, 0.0), (-3.05, 3.05)),
]
LBR_TOOL = (0.0, 0.0, 126.0)   # flange + 6-D probe adapter
# link masses (kg) and centres of mass (mm, in the link frame after the joint)
LBR_MASSES = [
    (4.0, np.array([0.0, -30.0, 120.0])),
    (4.0, np.array([0.0, 42.0, 20.0])),
    (3.0, np.array([0.0, 30.0, 130.0])),
    (2.7, np.array([0.0, 67.0, 34.0])),
    (1.7, np.array([0.0, 21.0, 76.0])),
    (1.8, np.array([0.0, 2.0, 4.0])),
    (1.1, np.array([0.0, 0.0, 75.0])),       # flange, probe adapter and 6-D probe
]


def lbr_like() -> Arm:
    F = [geom.trans(*xyz) @ geom.hom(geom.rpy_matrix(*rpy)) for _, xyz, rpy, _ in LBR_JOINTS]
    ranges = [lim for *_, lim in LBR_JOINTS]
    windows = [(-2.1, 2.1), (-1.3, 1.3), (-2.2, 2.2), (-1.9, 1.9), (-2.5, 2.5), (-1.8, 1.8), (-2.8, 2.8)]
    names = [n for n, *_ in LBR_JOINTS]
    return Arm("lbr_like", names, F, geom.trans(*LBR_TOOL), ranges, windows,
               [(m, c.copy()) for m, c in LBR_MASSES], names,
               sign=[1] * 7, offset_deg=[0.0] * 7)


def lbr_urdf() -> str:
    def f(v):
        return " ".join(f"{x:.12g}" for x in v)

    out = ['<?xml version="1.0"?>', '<robot name="lbr_like">', '  <link name="lbr_base"/>']
    parent = "lbr_base"
    for k, ((name, xyz, rpy, lim), (m, c)) in enumerate(zip(LBR_JOINTS, LBR_MASSES), start=1):
        link = f"lbr_link{k}"
        out += [f'  <link name="{link}">', "    <inertial>",
                f'      <origin xyz="{f(np.asarray(c) / 1000.0)}" rpy="0 0 0"/>',
                f'      <mass value="{m:g}"/>',
                '      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.01"/>',
                "    </inertial>", "  </link>",
                f'  <joint name="{name}" type="revolute">', f'    <parent link="{parent}"/>',
                f'    <child link="{link}"/>',
                f'    <origin xyz="{f(np.asarray(xyz) / 1000.0)}" rpy="{f(rpy)}"/>',
                '    <axis xyz="0 0 1"/>',
                f'    <limit lower="{lim[0]:g}" upper="{lim[1]:g}" effort="200" velocity="1.7"/>',
                "  </joint>"]
        parent = link
    out += ['  <link name="lbr_tool"/>', '  <joint name="lbr_tool_fixed" type="fixed">',
            f'    <parent link="{parent}"/>', '    <child link="lbr_tool"/>',
            f'    <origin xyz="{f(np.asarray(LBR_TOOL) / 1000.0)}" rpy="0 0 0"/>', "  </joint>",
            "</robot>"]
    return "\n".join(out) + "\n"
