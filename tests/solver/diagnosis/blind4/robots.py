"""The robot families of the sixth blind generator and their input files (units in each file).

Serial arms are written as a user would (DH tables, a URDF) and imported by `hyperstat
import-robot`; the parallel machines are the bundled templates' model files (`hyperstat build
TEMPLATE --model`), to which a declared moving mass is added.  A second forward kinematics, straight
from the DH table or the URDF (not through the model file), checks the import (self-check).
"""
from __future__ import annotations

import json
import os
import subprocess

import numpy as np

from .kinematics import ModelKinematics, rot_x, rot_y, rot_z, transform

DEG = np.pi / 180.0

# ------------------------------------------------------------------------------------------------
# PAL5: palletiser-like 5-axis arm, standard DH in metres and degrees, with a joint map
# (the controller's J3 is the forearm angle to the horizontal: q3 = J3 - J2; J4 mastered 0.5 deg
# off; J5 counted the other way).  Link masses declared in the model file (medium class).
PAL5_DH = [  # name, a[m], alpha[deg], d[m], theta[deg], min[deg], max[deg]
    ("1", 0.35, -90.0, 0.80, 0.0, -185.0, 185.0),
    ("2", 1.15, 0.0, 0.0, -90.0, -40.0, 75.0),
    ("3", 1.30, 0.0, 0.0, 0.0, -60.0, 60.0),
    ("4", 0.22, 90.0, 0.0, 0.0, -120.0, 120.0),
    ("5", 0.0, 0.0, 0.20, 0.0, -350.0, 350.0),
]
PAL5_MAP = {  # model joint -> ({controller joint: coefficient}, offset deg)
    "1": ({"J1": 1.0}, 0.0),
    "2": ({"J2": 1.0}, 0.0),
    "3": ({"J3": 1.0, "J2": -1.0}, 0.0),
    "4": ({"J4": 1.0}, 0.5),
    "5": ({"J5": -1.0}, 0.0),
}
PAL5_MASSES = {"1": 210.0, "2": 95.0, "3": 62.0, "4": 18.0, "5": 6.0}  # kg, bodies moved by each joint

# OW6: 6R with a non-spherical wrist (d5 = 110 mm), standard DH in mm and degrees, no joint map,
# no masses declared (the gravity effects cannot be sized).
OW6_DH = [
    ("1", 150.0, -90.0, 450.0, 0.0, -185.0, 185.0),
    ("2", 610.0, 0.0, 0.0, -90.0, -85.0, 75.0),
    ("3", 20.0, -90.0, 0.0, 0.0, -110.0, 60.0),
    ("4", 0.0, 90.0, 660.0, 0.0, -190.0, 190.0),
    ("5", 0.0, -90.0, 110.0, 0.0, -120.0, 120.0),
    ("6", 0.0, 0.0, 95.0, 0.0, -355.0, 355.0),
]

# XA6: a light 6R cobot of another maker's proportions (xArm6-like), as a URDF in metres with
# <inertial> on every moving link (light class, 8.4 kg of links).
XA6_JOINTS = [  # name, xyz (m), rpy (rad), lower, upper (rad)
    ("joint1", (0.0, 0.0, 0.267), (0.0, 0.0, 0.0), -6.2, 6.2),
    ("joint2", (0.0, 0.0, 0.0), (-np.pi / 2, 0.0, 0.0), -2.0, 2.0),
    ("joint3", (0.0535, -0.2845, 0.0), (0.0, 0.0, 0.0), -3.8, 0.18),
    ("joint4", (0.0775, 0.3425, 0.0), (-np.pi / 2, 0.0, 0.0), -6.2, 6.2),
    ("joint5", (0.0, 0.0, 0.0), (np.pi / 2, 0.0, 0.0), -1.69, 3.14),
    ("joint6", (0.076, 0.097, 0.0), (-np.pi / 2, 0.0, 0.0), -6.2, 6.2),
]
XA6_INERTIALS = [  # link, mass kg, com xyz (m) in the link frame
    ("link1", 2.16, (0.0, 0.025, -0.022)),
    ("link2", 1.71, (0.036, -0.21, 0.02)),
    ("link3", 1.38, (0.068, 0.10, 0.016)),
    ("link4", 1.70, (0.0, -0.02, -0.05)),
    ("link5", 1.13, (0.06, 0.035, 0.0)),
    ("link6", 0.17, (0.0, 0.0, -0.01)),
]


def dh_yaml(name, rows, length_unit, joint_map=None, scale=1.0):
    lines = ["format: hyperstat-dh", "version: 1", f"name: {name}", "convention: dh",
             f"units: {{length: {length_unit}, angle: deg}}",
             "tool: {origin: [0, 0, 0], rpy: [0, 0, 0]}", "joints:"]
    for n, a, al, d, th, lo, hi in rows:
        lines.append(f'  - {{name: "{n}", type: R, a: {a}, alpha: {al}, d: {d}, theta: {th}, min: {lo}, max: {hi}}}')
    if joint_map:
        lines += ["joint_map:", "  units: {angle: deg}", "  joints:"]
        for n, (coef, off) in joint_map.items():
            items = ", ".join(f"{k}: {v:g}" for k, v in coef.items())
            if off:
                items += f", offset: {off:g}"
            lines.append(f'    "{n}": {{{items}}}')
    return "\n".join(lines) + "\n"


def dh_forward(rows, q_rad, length_scale=1.0):
    """Second method: standard DH, T_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i) (mm)."""
    t = np.eye(4)
    for (n, a, al, d, th, lo, hi), q in zip(rows, q_rad):
        t = t @ transform(rot_z(th * DEG + q)) @ transform(None, [0, 0, d * length_scale]) \
            @ transform(None, [a * length_scale, 0, 0]) @ transform(rot_x(al * DEG))
    return t


def rpy_matrix(rpy):
    r, p, y = rpy
    return rot_z(y) @ rot_y(p) @ rot_x(r)


def urdf_text():
    out = ['<?xml version="1.0"?>', '<robot name="xa6">', '  <link name="link_base"/>']
    for link, m, c in XA6_INERTIALS:
        out.append(f'  <link name="{link}"><inertial><origin xyz="{c[0]} {c[1]} {c[2]}" rpy="0 0 0"/>'
                   f'<mass value="{m}"/><inertia ixx="0.005" ixy="0" ixz="0" iyy="0.005" iyz="0" izz="0.005"/></inertial></link>')
    parent = "link_base"
    for (n, xyz, rpy, lo, hi), (link, _, _) in zip(XA6_JOINTS, XA6_INERTIALS):
        out.append(f'  <joint name="{n}" type="revolute"><parent link="{parent}"/><child link="{link}"/>'
                   f'<origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}" rpy="{rpy[0]} {rpy[1]} {rpy[2]}"/>'
                   f'<axis xyz="0 0 1"/><limit lower="{lo}" upper="{hi}" effort="50" velocity="3"/></joint>')
        parent = link
    out.append("</robot>")
    return "\n".join(out) + "\n"


def urdf_forward(q):
    """Second method: the URDF's own origins (mm), link6 frame."""
    t = np.eye(4)
    for (n, xyz, rpy, lo, hi), qj in zip(XA6_JOINTS, q):
        t = t @ transform(rpy_matrix(rpy), np.array(xyz) * 1000.0) @ transform(rot_z(qj))
    return t


def run(cmd, cwd=None):
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {p.stderr.strip()[-800:]}")
    return p.stdout


def _add_serial_masses(model_path, masses_kg):
    """Declare each joint's body: its mass at the middle of the segment from its joint to the next
    (home configuration, base frame, mm), 40 mm off the axis line."""
    with open(model_path) as f:
        model = json.load(f)
    kin = ModelKinematics(model)
    fk = kin.forward(kin.home)
    names = kin.actuated
    org = [fk["L"][kin.elem_by_name[n]][:3, 3] for n in names]
    tool, _ = kin.frame_of(fk, kin.output)
    org.append(tool[:3, 3])
    decl = {}
    for i, n in enumerate(names):
        c = 0.5 * (org[i] + org[i + 1]) + np.array([0.0, 0.0, 40.0])
        decl[n] = {"mass": float(masses_kg[n]), "com": [round(float(v), 3) for v in c]}
    model.setdefault("metadata", {})["masses"] = decl
    with open(model_path, "w") as f:
        json.dump(model, f, indent=1)


def prepare_models(hyperstat, repo_root, out_dir):
    """Write every family's model file into out_dir; return {family: model path}."""
    os.makedirs(out_dir, exist_ok=True)
    paths = {}
    # PAL5
    p = os.path.join(out_dir, "pal5.dh.yaml")
    with open(p, "w") as f:
        f.write(dh_yaml("pal5", PAL5_DH, "m", PAL5_MAP))
    m = os.path.join(out_dir, "pal5.skel.json")
    run([hyperstat, "import-robot", p, "--out", m, "--quiet"])
    _add_serial_masses(m, PAL5_MASSES)
    paths["pal5"] = m
    # OW6
    p = os.path.join(out_dir, "ow6.dh.yaml")
    with open(p, "w") as f:
        f.write(dh_yaml("ow6", OW6_DH, "mm"))
    m = os.path.join(out_dir, "ow6.skel.json")
    run([hyperstat, "import-robot", p, "--out", m, "--quiet"])
    paths["ow6"] = m
    # XA6
    p = os.path.join(out_dir, "xa6.urdf")
    with open(p, "w") as f:
        f.write(urdf_text())
    m = os.path.join(out_dir, "xa6.skel.json")
    run([hyperstat, "import-robot", p, "--out", m, "--tip", "link6", "--quiet"])
    paths["xa6"] = m
    # parallel machines
    for fam, tpl, mass, lead in (("tx7", "tripteor_x7.py", 120.0, None), ("hexa", "hexapod.py", 60.0, 5.0)):
        m = os.path.join(out_dir, f"{fam}.skel.json")
        run([hyperstat, "build", os.path.join(repo_root, "templates", tpl), "--model", m, "--quiet"])
        with open(m) as f:
            model = json.load(f)
        model.setdefault("metadata", {})["moving_mass"] = mass
        if lead is not None:
            model["metadata"]["screw_lead"] = lead
        with open(m, "w") as f:
            json.dump(model, f, indent=1)
        paths[fam] = m
    return paths


def serial_masses(kin: ModelKinematics):
    """(joint name, mass, com in that joint's moving frame at home) from metadata.masses."""
    decl = kin.model.get("metadata", {}).get("masses") or {}
    if not decl:
        return []
    fk = kin.forward(kin.home)
    out = []
    for n, v in decl.items():
        if isinstance(v, dict) and "mass" in v:
            t = fk["P"][kin.elem_by_name[n]]
            c = np.linalg.solve(t, np.append(np.array(v["com"], float), 1.0))[:3]
            out.append((n, float(v["mass"]), c))
    return out
