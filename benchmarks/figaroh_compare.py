"""hyperstat and FIGAROH side by side on the same simulated serial-robot campaigns (issue 21, item 5).

Units: lengths in mm (errors printed in um), angles in rad (printed in urad), time in s of CPU.

The campaigns come from the FANUC-like generator of the tests
(:mod:`tests.solver.calibration.fanuc_like`): its own standard-DH forward kinematics on a
*true* table (the nominal one perturbed by up to 0.5 mm / 1 mrad per entry), a tool frame
error, a laser tracker 3.5 m away, up to three SMRs on the tool.  Neither tool shares that
code.  Each tool gets the same poses, the same noisy measurements and only what its documented
workflow takes:

* hyperstat: the DH table with its joint map (``hyperstat-dh`` YAML) -> ``import_robot`` ->
  ``analyze`` -> ``read_measurements`` (controller joints in deg, positions in m, no target
  prior) -> ``identify`` (defaults of ``hyperstat identify``: ``--select-size auto``);
* FIGAROH (PyPI ``figaroh``, on pinocchio): a URDF of the nominal table written here (metres,
  one revolute joint per row, the last row's static part as a fixed ``tool`` link) and a unified
  config YAML (``tasks.calibration``: ``calibration_level: full_params``, base frame
  ``universe``, tool frame ``tool``, one marker per SMR, ``measurable_dof`` xyz or xyz+rpy),
  the CSV layout of ``PoseObservations.from_csv`` (``x1, y1, z1, [phix1 ...,] <joint names>``,
  m and rad, model joint angles: FIGAROH has no joint map); ``BaseCalibration`` with unknown
  base and tip frames (``known_baseframe = known_tipframe = False``, as its UR10 example),
  ``initialize()`` (structural QR selection, then the frame-absorbed parameters dropped on the
  data), ``solve()`` (scipy ``least_squares`` LM with outlier exclusion, defaults).  Its cost is
  the documented ``_compute_logmap_residuals(position_frame="world")`` weighted by
  ``apply_measurement_weighting`` with the campaign's noise (1/sigma for positions and
  orientations): the same weights as hyperstat's.

Compared, per campaign and seed:

* ``truth err``: RMS over 200 fresh random configurations of the noise-free prediction error of
  each SMR position in the tracker frame (identified geometry + tracker + target offsets against
  the true ones): how well the geometry was identified, free of measurement noise;
* ``val RMS``: RMS of the 3-D residual norms on 30 held-out noisy poses (what a user sees);
* ``noise``: the 3-D noise RMS of the campaign (the floor of ``val RMS``);
* ``params``: parameters identified (geometry + tracker frame + targets: hyperstat's rank,
  FIGAROH's ``param_name`` after its selection);
* ``CPU s``: ``time.process_time()`` of the whole identification from the files (hyperstat:
  import, stationarity analysis, reading, identification; FIGAROH: URDF load, config,
  ``initialize``, ``solve``), in one process, BLAS limited to one thread for both tools
  (``identify`` does so itself; a 2-thread OpenBLAS on these small matrices burns CPU spinning).

Run: ``.venv/bin/python benchmarks/figaroh_compare.py [--seeds 3] [--markdown out/figaroh.md]`` after
``make bench`` (the ``bench`` extra installs ``figaroh``).  ``docs/identification.md`` quotes its output.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import math
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
warnings.simplefilter("ignore")

from scipy.spatial.transform import Rotation  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from tests.solver.calibration.fanuc_like import (  # noqa: E402
    DH_YAML, LIMITS_DEG, NOMINAL, TARGETS, Campaign, dh_matrix, quaternion)

NOISE_MM = 0.02      # 1-sigma per axis, mm (constant: FIGAROH weights every point alike)
NOISE_RAD = 5e-5     # 1-sigma per axis of the 6-D orientation, rad
N_VAL, N_FRESH = 30, 200
CAMPAIGNS = [  # name, identification poses, targets, 6-D
    ("1 target", 50, ("SMR1",), False),
    ("3 targets", 50, ("SMR1", "SMR2", "SMR3"), False),
    ("6-D (1 target)", 40, ("SMR1",), True),
]
JOINTS = [f"joint_{i}" for i in range(1, 7)]


# ---------------------------------------------------------------------- the campaign, for both tools
def true_pose(c: Campaign, q: np.ndarray, target: str) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free position (mm) and orientation of a target frame in the tracker frame."""
    f = c.flange(q)
    world = f[:3, :3] @ c.targets[target] + f[:3, 3]
    return c.tracker_r.T @ (world - c.tracker_t), c.tracker_r.T @ f[:3, :3] @ c.target_rot[target]


def simulate(c: Campaign, q: np.ndarray, targets: tuple, six_d: bool, noise: bool = True) -> dict:
    """Measured positions (K, T, 3) mm and orientations (K, T, 3, 3) of every pose and target."""
    pos = np.empty((len(q), len(targets), 3))
    rot = np.empty((len(q), len(targets), 3, 3))
    for k, qk in enumerate(q):
        for t, name in enumerate(targets):
            p, r = true_pose(c, qk, name)
            if noise:
                p = p + c.rng.normal(0.0, NOISE_MM, 3)
                if six_d:
                    r = Rotation.from_rotvec(c.rng.normal(0.0, NOISE_RAD, 3)).as_matrix() @ r
            pos[k, t], rot[k, t] = p, r
    return {"q": q, "pos": pos, "rot": rot, "targets": targets, "six_d": six_d}


def hyperstat_csv(c: Campaign, m: dict, prefix: str) -> str:
    """hyperstat measurement file: FANUC controller joints (deg) and the joint map, positions in m."""
    lines = ["# hyperstat measurements, version 1", "# mechanism: fanuc_like", f"# noise: {NOISE_MM} mm + 0 mm/m"]
    if m["six_d"]:
        lines.append(f"# orientation noise: {NOISE_RAD * 1e3} mrad")
    cols = ["pose"] + [f"J{i}[deg]" for i in range(1, 7)]
    for name in m["targets"]:
        sfx = f"_{name}" if len(m["targets"]) > 1 else ""
        cols += [f"{a}{sfx}[m]" for a in "xyz"]
        if m["six_d"]:
            cols += [f"quat_{a}{sfx}" for a in "wxyz"]
    lines.append(",".join(cols))
    for k, qk in enumerate(m["q"]):
        row = [f"{prefix}{k + 1}"] + [repr(float(v)) for v in c.controller(qk)]
        for t in range(len(m["targets"])):
            row += [f"{v / 1000.0:.12f}" for v in m["pos"][k, t]]
            if m["six_d"]:
                row += [repr(float(v)) for v in quaternion(m["rot"][k, t])]
        lines.append(",".join(row))
    return "\n".join(lines) + "\n"


def figaroh_csv(m: dict) -> str:
    """FIGAROH's layout: x1, y1, z1[, phix1, phiy1, phiz1], x2 ..., then the joints (m, rad, model joints)."""
    cols = []
    for t in range(len(m["targets"])):
        cols += [f"{a}{t + 1}" for a in ("x", "y", "z")]
        if m["six_d"]:
            cols += [f"{a}{t + 1}" for a in ("phix", "phiy", "phiz")]
    lines = [",".join(cols + JOINTS)]
    for k, qk in enumerate(m["q"]):
        row = []
        for t in range(len(m["targets"])):
            row += [repr(float(v / 1000.0)) for v in m["pos"][k, t]]
            if m["six_d"]:  # roll-pitch-yaw, R = Rz(yaw) Ry(pitch) Rx(roll)
                row += [repr(float(v)) for v in Rotation.from_matrix(m["rot"][k, t]).as_euler("xyz")]
        lines.append(",".join(row + [repr(float(v)) for v in qk]))
    return "\n".join(lines) + "\n"


def nominal_urdf() -> str:
    """URDF (m, rad) of the nominal DH table: joint i's origin is the previous row's static part
    ``Tz(d) Tx(a) Rx(alpha)`` followed by ``Rz(theta_i)``; the last row's static part is the tool."""

    def origin(t: np.ndarray) -> str:
        rpy = Rotation.from_matrix(t[:3, :3]).as_euler("xyz")
        return (f'<origin xyz="{" ".join(repr(float(v) / 1000.0) for v in t[:3, 3])}" '
                f'rpy="{" ".join(repr(float(v)) for v in rpy)}"/>')

    lo, hi = np.radians(np.array(LIMITS_DEG, float)).T
    out = ['<?xml version="1.0"?>', '<robot name="fanuc_like">', '  <link name="base_link"/>']
    static = np.eye(4)
    parent = "base_link"
    for i, (a, al, d, th) in enumerate(NOMINAL):
        t = static @ dh_matrix(math.radians(th), 0.0, 0.0, 0.0)
        child = f"link_{i + 1}"
        out += [f'  <link name="{child}"/>',
                f'  <joint name="{JOINTS[i]}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
                f'{origin(t)}<axis xyz="0 0 1"/><limit lower="{lo[i]}" upper="{hi[i]}" effort="1" velocity="1"/></joint>']
        static = dh_matrix(0.0, d, a, math.radians(al))
        parent = child
    out += ['  <link name="tool"/>',
            f'  <joint name="tool_joint" type="fixed"><parent link="{parent}"/><child link="tool"/>{origin(static)}</joint>',
            "</robot>"]
    return "\n".join(out) + "\n"


def figaroh_config(n_markers: int, six_d: bool, data: Path, n: int) -> str:
    dof = "[true, true, true, true, true, true]" if six_d else "[true, true, true, false, false, false]"
    markers = "".join(f"""
        - name: "marker{k + 1}"
          reference_joint: "joint_6"
          measurable_dof: {dof}
          sensor_type: "tracker\"""" for k in range(n_markers))
    return f"""robot:
  name: "fanuc_like"
  properties:
    joints:
      active_joints: {JOINTS}
tasks:
  calibration:
    enabled: true
    parameters:
      calibration_level: "full_params"
      include_non_geometric: false
    kinematics:
      base_frame: "universe"
      tool_frame: "tool"
    measurements:
      markers:{markers}
      poses:
        base_pose: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        tool_pose: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    data:
      source_file: "{data}"
      number_of_samples: {n}
"""


# ---------------------------------------------------------------------- the two tools
def run_hyperstat(tmp: Path, c: Campaign, ident: dict, val: dict, fresh: dict) -> dict:
    from hyperstat.solver.analysis.stationarity import analyze
    from hyperstat.solver.calibration.identify import identify
    from hyperstat.solver.calibration.measurements import read_measurements
    from hyperstat.solver.kinematics.robot_import import import_robot

    (tmp / "fanuc_like.dh.yaml").write_text(DH_YAML)
    (tmp / "id.csv").write_text(hyperstat_csv(c, ident, "P"))
    (tmp / "val.csv").write_text(hyperstat_csv(c, val, "V"))
    (tmp / "fresh.csv").write_text(hyperstat_csv(c, fresh, "F"))
    t0 = time.process_time()
    mech = import_robot(tmp / "fanuc_like.dh.yaml")
    analysis = analyze(mech, n_configurations=24, seed=0)
    data, vdata = read_measurements(tmp / "id.csv", mech), read_measurements(tmp / "val.csv", mech)
    res = identify(mech, analysis, data, vdata, select_size="auto")
    cpu = time.process_time() - t0
    fdata = read_measurements(tmp / "fresh.csv", mech)
    pred = res.model.predict(res.theta, fdata)
    truth_err = np.linalg.norm(pred.position - fdata.position, axis=1)
    vpred = res.model.predict(res.theta, vdata).position
    out = {"truth": rms(truth_err), "val": rms(np.linalg.norm(vpred - vdata.position, axis=1)),
           "params": res.rank, "unknowns": res.n_unknowns, "cpu": cpu, "sigma": res.sigma,
           "reported_val": res.validation["rms"]}
    if ident["six_d"]:
        out["truth_rot"] = rms(rotation_angle(pred.rotation, Rotation.from_rotvec(fdata.rotation).as_matrix()))
    return out


def run_figaroh(tmp: Path, ident: dict, val: dict, fresh: dict) -> dict:
    import pinocchio as pin
    from figaroh.calibration.base_calibration import BaseCalibration
    from figaroh.calibration.calibration_tools import calc_updated_fkm
    from figaroh.tools.load_robot import load_robot

    class TrackerCalibration(BaseCalibration):
        """FIGAROH's documented subclass: world-frame log-map residuals, unit-aware weights."""

        def cost_function(self, var):
            est = calc_updated_fkm(self.model, self.data, var, self.q_measured, self.calib_config)
            res = self._compute_logmap_residuals(self.PEE_measured, est, position_frame="world")
            return self.apply_measurement_weighting(res)

    urdf, cfg = tmp / "fanuc_like.urdf", tmp / "figaroh.yaml"
    data = tmp / "figaroh_id.csv"
    urdf.write_text(nominal_urdf())
    data.write_text(figaroh_csv(ident))
    n_markers = len(ident["targets"])
    cfg.write_text(figaroh_config(n_markers, ident["six_d"], data, len(ident["q"])))
    logging.disable(logging.CRITICAL)
    t0 = time.process_time()
    with contextlib.redirect_stdout(io.StringIO()):
        robot = load_robot(str(urdf), load_by_urdf=True)
        cal = TrackerCalibration(robot, str(cfg))
        cal.calib_config["known_baseframe"] = False
        cal.calib_config["known_tipframe"] = False
        cal.calib_config["measurement_std"] = {"position": NOISE_MM / 1000.0, "orientation": NOISE_RAD}
        cal.initialize()
        result = cal.solve(enable_logging=False)
    cpu = time.process_time() - t0
    logging.disable(logging.NOTSET)
    names = list(cal.calib_config["param_name"])

    def predict(m: dict) -> tuple[np.ndarray, np.ndarray | None]:
        conf = dict(cal.calib_config, NbSample=len(m["q"]))
        flat = calc_updated_fkm(cal.model, cal.data, result.x, np.asarray(m["q"]), conf)
        ndof = 6 if m["six_d"] else 3
        arr = flat.reshape(n_markers, ndof, len(m["q"]))
        pos = np.transpose(arr[:, :3], (2, 0, 1)) * 1000.0  # (K, T, 3) mm
        rot = None
        if m["six_d"]:
            rot = np.array([[pin.rpy.rpyToMatrix(arr[t, 3:, k]) for t in range(n_markers)] for k in range(len(m["q"]))])
        return pos, rot

    fpos, frot = predict(fresh)
    vpos, _ = predict(val)
    out = {"truth": rms(np.linalg.norm(fpos - fresh["pos"], axis=2).ravel()),
           "val": rms(np.linalg.norm(vpos - val["pos"], axis=2).ravel()),
           "params": len(names), "cpu": cpu, "success": bool(result.success),
           "dropped": list(cal.calib_config.get("absorbed_param_name", []))}
    if ident["six_d"]:
        out["truth_rot"] = rms(rotation_angle(frot[:, 0], fresh["rot"][:, 0]))
    return out


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def rotation_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (rad) of ``a b^T`` per pose."""
    return Rotation.from_matrix(np.einsum("kij,klj->kil", a, b)).magnitude()


# ---------------------------------------------------------------------- main
def main(argv: list | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=3, help="seeds per campaign (default 3)")
    p.add_argument("--markdown", help="also write the table to this file")
    args = p.parse_args(argv)
    import figaroh
    import pinocchio

    from hyperstat.solver.calibration.identify import identify  # noqa: F401  (import time outside the timing)

    fig_version = getattr(figaroh, "__version__", None)
    if fig_version is None:
        from importlib.metadata import version
        fig_version = version("figaroh")
    head = [f"FIGAROH {fig_version}, pinocchio {pinocchio.__version__}; noise {NOISE_MM * 1000:.0f} um per axis"
            f" (3-D RMS {NOISE_MM * 1000 * math.sqrt(3):.1f} um), 6-D orientation {NOISE_RAD * 1e6:.0f} urad per axis;"
            f" {N_VAL} validation poses, {N_FRESH} fresh noise-free configurations; CPU time (process_time, one BLAS thread).", "",
            "| campaign | seed | tool | truth err RMS (um) | val RMS (um) | params | CPU (s) | note |",
            "|---|---|---|---|---|---|---|---|"]
    print("\n".join(head), flush=True)
    rows = list(head)
    for name, n_id, targets, six_d in CAMPAIGNS:
        for seed in range(args.seeds):
            c = Campaign(100 + seed)
            ident = simulate(c, c.poses(n_id), targets, six_d)
            val = simulate(c, c.poses(N_VAL), targets, six_d)
            fresh = simulate(c, c.poses(N_FRESH), targets, six_d, noise=False)
            with tempfile.TemporaryDirectory() as d, threadpool_limits(limits=1, user_api="blas"):
                h = run_hyperstat(Path(d), c, ident, val, fresh)
            with tempfile.TemporaryDirectory() as d, threadpool_limits(limits=1, user_api="blas"):
                try:
                    f = run_figaroh(Path(d), ident, val, fresh)
                except Exception as exc:  # reported in the table, never hidden
                    f = {"error": f"{type(exc).__name__}: {str(exc).splitlines()[0][:120]}"}
            floor = NOISE_MM * 1000 * math.sqrt(3)
            for tool, r in (("hyperstat", h), ("FIGAROH", f)):
                if "error" in r:
                    line = f"| {name} | {seed} | {tool} | - | - | - | - | failed: {r['error']} |"
                else:
                    note = []
                    if "truth_rot" in r:
                        note.append(f"orientation truth err {r['truth_rot'] * 1e6:.1f} urad")
                    if tool == "hyperstat":
                        note.append(f"{r['params']} of {r['unknowns']} unknowns, sigma {r['sigma']:.2f}")
                        # our own residuals (mm) and those identify() reports agree (a consistency check)
                        assert abs(r["reported_val"] - r["val"]) < 1e-6, (r["reported_val"], r["val"])
                    else:
                        if not r["success"]:
                            note.append("LM did not report success")
                        if r["dropped"]:
                            note.append(f"dropped on the data: {len(r['dropped'])}")
                    line = (f"| {name} | {seed} | {tool} | {r['truth'] * 1000:.1f} | {r['val'] * 1000:.1f}"
                            f" (floor {floor:.1f}) | {r['params']} | {r['cpu']:.2f} | {'; '.join(note)} |")
                print(line, flush=True)
                rows.append(line)
    if args.markdown:
        Path(args.markdown).parent.mkdir(parents=True, exist_ok=True)
        Path(args.markdown).write_text("\n".join(rows) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
