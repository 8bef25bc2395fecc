"""A LinuxCNC kinematics component (C, built with ``halcompile``) for any mechanism of a controller file.

Units: lengths in mm; angles in degrees on LinuxCNC's side (its ``ANGULAR_UNITS``), rad inside.

The generated component carries the identified geometry as constants: the matrix
``D(xi)`` of every element (paper 1, eq. 2, with the identified defects), the joint
types, the chains in evaluation order and the loop closures (eqs. 7, 9).  Its C code
evaluates the same product of ``D`` and ``M`` matrices as
:class:`hyperstat.solver.kinematics.closure.Kinematics`, written again in C (no code is
shared), and solves:

* **inverse kinematics** (world -> joints): all joint variables by Gauss-Newton on the
  closure residuals plus the output constraints, from the previous solution (the
  previous servo cycle);
* **forward kinematics** (joints -> world): the passive joints by Gauss-Newton on the
  closure residuals from the previous pose, as LinuxCNC's own parallel-kinematics
  modules (``genhexkins``) do, then the output pose.

Jacobians are the unit screws of the joints (paper 2, eq. 7).  A mechanism with no
loop (a serial robot) needs no iteration for its forward model.

World coordinates (``[TRAJ] COORDINATES``), by the number of actuated joints:

* 6: ``X Y Z A B C``, the output frame's origin and its orientation
  ``R = Rz(C) Ry(B) Rx(A)``;
* 5: ``X Y Z A B``, the output frame's origin and its z axis
  ``w = Ry(B) Rx(A) e_z = (cos A sin B, -sin A, cos A cos B)`` (a five-axis machine: the
  rotation about the tool axis is not controlled);
* 3: ``X Y Z``, the output frame's origin.

LinuxCNC joints are the actuated joints in the model's order; a revolute joint is an
``ANGULAR`` LinuxCNC joint in degrees, a prismatic joint a ``LINEAR`` one in mm.
"""

from __future__ import annotations

import math
import re

import numpy as np

from hyperstat.solver.errors import DataError
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Joint

__all__ = ["world_layout", "world_of", "kins_component", "component_name", "sample_world", "inverse_conditioning"]

_LETTERS = "ABC"
#: the joint limits are widened by this much (mm, or degrees for a revolute joint) in the INI and in the
#: component's range check: a home on a limit (the SCARA's quill) is not refused for round-off
LIMIT_MARGIN = 1e-6


def world_layout(mechanism) -> dict:
    """How LinuxCNC's world coordinates map onto the mechanism.

    Returns
    -------
    dict
        ``coordinates`` (e.g. ``"XYZBC"``), ``mode`` (``"xyz"``, ``"pose"`` or ``"tcp"``) and
        ``wrist``: (joint index, letter) of the rotary axes commanded directly in
        ``"tcp"`` mode.

    Raises
    ------
    DataError
        For a mechanism with no world-coordinate convention here.
    """
    m = mechanism
    act = [int(i) for i in m.actuated]
    n = len(act)
    if n == 3:
        return {"coordinates": "XYZ", "mode": "xyz", "wrist": []}
    if n == 6:
        return {"coordinates": "XYZABC", "mode": "pose", "wrist": []}
    if n in (4, 5):
        in_loop = set()
        for cl in m.closures:
            in_loop.update(cl.path)
            in_loop.update(cl.reference_path)
        path = [e for e in m.path_to(m.output) if isinstance(m.chains[e[0]].elements[e[1]], Joint)]
        trailing = path[len(path) - (n - 3):]
        els = [m.chains[c].elements[e] for c, e in trailing]
        if all(el.type == "R" and el.role == "actuated" and key not in in_loop for el, key in zip(els, trailing)):
            kin = Kinematics(m)
            frames = kin.evaluate(m.home[None, :], jacobians=False).element_frames
            wrist = []
            for el, key in zip(els, trailing):
                axis = frames[key][0, :3, 2]
                wrist.append((m.joint_index[el.name], _LETTERS[int(np.argmax(np.abs(axis)))]))
            letters = [w[1] for w in wrist]
            if len(set(letters)) == len(letters):
                wrist.sort(key=lambda w: w[1])
                return {"coordinates": "XYZ" + "".join(letters and sorted(letters)), "mode": "tcp", "wrist": wrist}
    raise DataError(f"'{m.name}' has {n} actuated joint{'' if n == 1 else 's'} and no world-coordinate convention in the LinuxCNC export "
                    f"(3: X Y Z; 6: X Y Z A B C; 4 or 5: X Y Z plus the last revolute joints of the output path, "
                    f"outside every loop, as rotary axes).")


def world_of(q: np.ndarray, pose: np.ndarray, layout: dict) -> np.ndarray:
    """World coordinates (mm, degrees) of configurations ``q`` (K, n_q) with output poses (K, 4, 4).

    The same formulas as the component: the output origin, then ``Rz(C) Ry(B) Rx(A)``
    angles (``pose`` mode) or the wrist joint values (``tcp`` mode), in degrees.

    Examples
    --------
    >>> import numpy as np
    >>> rz = np.eye(4)[None].copy()
    >>> rz[0, :2, :2] = [[0.0, -1.0], [1.0, 0.0]]  # 90 degrees about z
    >>> rz[0, :3, 3] = [1.0, 2.0, 3.0]
    >>> world_of(np.zeros((1, 6)), rz, {"mode": "pose", "wrist": []}).round(9) + 0.0
    array([[ 1.,  2.,  3.,  0.,  0., 90.]])
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    pose = np.asarray(pose, dtype=float).reshape(-1, 4, 4)
    cols = [pose[:, 0, 3], pose[:, 1, 3], pose[:, 2, 3]]
    r = pose[:, :3, :3]
    if layout["mode"] == "pose":
        b = np.arctan2(-r[:, 2, 0], np.hypot(r[:, 0, 0], r[:, 1, 0]))
        a = np.arctan2(r[:, 2, 1], r[:, 2, 2])
        c = np.arctan2(r[:, 1, 0], r[:, 0, 0])
        cols += [np.degrees(a), np.degrees(b), np.degrees(c)]
    elif layout["mode"] == "tcp":
        cols += [np.degrees(q[:, j]) for j, _ in layout["wrist"]]
    return np.stack(cols, axis=1)


def sample_world(mechanism, xi: np.ndarray | None, layout: dict, count: int = 200, seed: int = 0) -> np.ndarray:
    """World coordinates (mm, degrees) of ``count`` random actuated configurations in the joint ranges.

    Configurations that do not assemble are left out.  Used for the axis limits of the
    simulation configuration.
    """
    kin = Kinematics(mechanism)
    act = mechanism.actuated
    lo, hi = mechanism.ranges[act].T
    qa = lo + (hi - lo) * np.random.default_rng(seed).random((count, len(act)))
    res = kin.solve(qa, xi)
    q = res.q[res.converged]
    return world_of(q, kin.evaluate(q, xi, jacobians=False).output_pose, layout)


def inverse_conditioning(mechanism, xi: np.ndarray | None, q: np.ndarray) -> float:
    """Smallest over largest singular value of the component's inverse-kinematics Jacobian at ``q``.

    The rows are those the component's Newton iterates on (closure residuals, rotations
    times the length scale, and the output constraints of :func:`world_layout`), the
    columns its unknowns (every joint but the wrist joints of ``tcp`` mode).  Zero at a
    singularity, where Newton has no direction to leave by (the SCARA template's home, arm
    stretched); about 1e-4 at the Tripteor X7's and the hexapod's homes.
    """
    layout = world_layout(mechanism)
    kin = Kinematics(mechanism)
    st = kin.evaluate(np.asarray(q, dtype=float)[None, :], xi, jacobians=True)
    lc = kin.length_scale
    rows = []
    if len(mechanism.closures):
        c = st.closure_q[0].copy()
        for k in range(len(mechanism.closures)):
            c[6 * k:6 * k + 3] *= lc
        rows.append(c)
    out = st.output_q[0].copy()
    out[:3] *= lc
    rows.append(out if layout["mode"] == "pose" else out[3:])
    wrist = {w[0] for w in layout["wrist"]}
    cols = [j for j in range(len(mechanism.joints)) if j not in wrist]
    s = np.linalg.svd(np.vstack(rows)[:, cols], compute_uv=False)
    return float(s[-1] / s[0]) if s[0] > 0 else 0.0


def component_name(mechanism_name: str, digest: str = "") -> str:
    """A HAL component name from a mechanism name (letters, digits, underscores; ends in ``kins``)."""
    base = re.sub(r"[^a-z0-9_]", "_", mechanism_name.lower()).strip("_") or "mechanism"
    return f"hs_{base}{'_' + digest[:8] if digest else ''}_kins"


def _c_array(values, fmt: str = "{:.17g}") -> str:
    return "{" + ", ".join(fmt.format(v) for v in values) + "}"


def kins_component(mechanism, xi: np.ndarray | None = None, name: str | None = None,
                   tolerance: float = 1e-12, max_iterations: int = 50, home: np.ndarray | None = None) -> str:
    """Source of a ``halcompile`` component (``.comp``) with the geometry ``xi`` baked in.

    Parameters
    ----------
    mechanism : Mechanism
        The model (nominal geometry and topology).
    xi : ndarray, optional
        Defects (rad / mm), e.g. the identified ones of a controller file; nominal if omitted.
    name : str, optional
        Component name (default from the mechanism name).
    tolerance : float
        Newton stops when the largest step is below ``tolerance`` times the length scale
        (mm; rad times the length scale).
    max_iterations : int
        Newton iterations before the component reports failure to LinuxCNC.
    home : ndarray, (n_q,), optional
        Assembled configuration (every joint) where the machine homes and Newton first
        starts (default: the model's home).  A home on a singularity (a SCARA with its arm
        stretched) leaves Newton nowhere to go: choose one away from it.

    Returns
    -------
    str
        The ``.comp`` text.
    """
    layout = world_layout(mechanism)
    name = name or component_name(mechanism.name)
    q_home = mechanism.home if home is None else np.asarray(home, dtype=float).reshape(-1)
    kin = Kinematics(mechanism)
    mats = kin.element_matrices(xi)
    m = mechanism
    order = m.topology["order"]
    frames = [m.base]
    for ci in order:
        if m.chains[ci].end not in frames:
            frames.append(m.chains[ci].end)
    closure_of = {cl.chain: k for k, cl in enumerate(m.closures)}
    el_d, el_joint, el_rot = [], [], []
    ch_first, ch_count, ch_start, ch_end, ch_close = [], [], [], [], []
    for ci in order:
        chain = m.chains[ci]
        ch_first.append(len(el_d))
        ch_count.append(len(chain.elements))
        ch_start.append(frames.index(chain.start))
        ch_close.append(closure_of.get(ci, -1))
        ch_end.append(frames.index(chain.end))
        for ei, el in enumerate(chain.elements):
            el_d.append(mats[(ci, ei)].reshape(-1))
            if isinstance(el, Joint):
                el_joint.append(m.joint_index[el.name])
                el_rot.append(1 if el.type == "R" else 0)
            else:
                el_joint.append(-1)
                el_rot.append(0)
    n_q, n_cl = len(m.joints), len(m.closures)
    joint_key = {}
    for ci, chain in enumerate(m.chains):
        for ei, el in enumerate(chain.elements):
            if isinstance(el, Joint):
                joint_key[(ci, ei)] = m.joint_index[el.name]
    cl_sign = np.zeros((max(n_cl, 1), n_q))
    cl_frame = []
    for k, cl in enumerate(m.closures):
        for e in cl.path:
            if e in joint_key:
                cl_sign[k, joint_key[e]] += 1.0
        for e in cl.reference_path:
            if e in joint_key:
                cl_sign[k, joint_key[e]] -= 1.0
        cl_frame.append(frames.index(cl.frame))
    out_member = np.zeros(n_q)
    for e in m.path_to(m.output):
        if e in joint_key:
            out_member[joint_key[e]] = 1.0
    act = [int(i) for i in m.actuated]
    act_rot = [1 if m.joints[i].type == "R" else 0 for i in act]
    margin = [math.radians(LIMIT_MARGIN) if r else LIMIT_MARGIN for r in act_rot]
    act_lo = [m.joints[i].range[0] - e for i, e in zip(act, margin)]
    act_hi = [m.joints[i].range[1] + e for i, e in zip(act, margin)]
    n_out = 6 if layout["mode"] == "pose" else 3
    mode = {"xyz": 0, "tcp": 1, "pose": 2}[layout["mode"]]
    wrist = layout["wrist"] or [(0, "A")]
    lc = kin.length_scale
    # what is left of the closure residual on this geometry (an identified hyperstatic machine keeps some, in
    # directions no joint motion changes): a solve ending above ten times it found a false minimum
    res_max = 1e-9 * max(1.0, lc)
    if n_cl:
        act_idx = m.actuated
        lo, hi = m.ranges[act_idx].T
        qa = lo + (hi - lo) * (0.1 + 0.8 * np.random.default_rng(0).random((50, len(act_idx))))
        res = kin.solve(qa, xi)
        if res.converged.any():
            res_max = max(res_max, 10.0 * float(res.residual[res.converged].max()))
    lines = [
        f'component {name} "hyperstat kinematics of {m.name} (identified geometry; mm, degrees)";',
        'pin out bit dummy = 0 "unused (halcompile needs a pin; the kinematics functions have none)";',
        "option period no;",
        "function _;",
        'license "GPL";',
        'author "hyperstat (generated)";',
        ";;",
        "/* Generated by hyperstat: do not edit. Units: mm, rad inside; LinuxCNC angles in degrees. */",
        '#include "kinematics.h"',
        "#include <rtapi_math.h>",
        f"#define NQ {n_q}",
        f"#define NEL {len(el_d)}",
        f"#define NCH {len(order)}",
        f"#define NFR {len(frames)}",
        f"#define NCL {n_cl}",
        f"#define NACT {len(act)}",
        f"#define NOUT {n_out}",
        f"#define MODE {mode}",
        f"#define LSCALE {lc:.17g}",
        f"#define TOL {tolerance * max(1.0, lc):.17g}",
        f"#define MAXIT {int(max_iterations)}",
        f"#define RES_MAX {res_max:.17g}",
        "static const double EL_D[NEL][16] = {" + ",\n  ".join(_c_array(d) for d in el_d) + "};",
        f"static const int EL_JOINT[NEL] = {_c_array(el_joint, '{:d}')};",
        f"static const int EL_ROT[NEL] = {_c_array(el_rot, '{:d}')};",
        f"static const int CH_FIRST[NCH] = {_c_array(ch_first, '{:d}')};",
        f"static const int CH_COUNT[NCH] = {_c_array(ch_count, '{:d}')};",
        f"static const int CH_START[NCH] = {_c_array(ch_start, '{:d}')};",
        f"static const int CH_END[NCH] = {_c_array(ch_end, '{:d}')};",
        f"static const int CH_CLOSE[NCH] = {_c_array(ch_close, '{:d}')};",
        f"static const int CL_FRAME[NCL > 0 ? NCL : 1] = {_c_array(cl_frame or [0], '{:d}')};",
        "static const double CL_SIGN[NCL > 0 ? NCL : 1][NQ] = {"
        + ", ".join(_c_array(row, "{:.1f}") for row in cl_sign) + "};",
        f"static const double OUT_MEMBER[NQ] = {_c_array(out_member, '{:.1f}')};",
        f"static const int OUT_FRAME = {frames.index(m.output)};",
        f"static const int ACT[NACT] = {_c_array(act, '{:d}')};",
        f"static const int ACT_ROT[NACT] = {_c_array(act_rot, '{:d}')};",
        "/* actuated joint ranges (rad / mm), widened like the INI joint limits (1e-6 degree or mm): an inverse",
        "   solution outside them is refused, so that LinuxCNC stops at a limit, not past it */",
        f"static const double ACT_LO[NACT] = {_c_array(act_lo)};",
        f"static const double ACT_HI[NACT] = {_c_array(act_hi)};",
        f"static const int JOINT_ROT[NQ] = {_c_array([1 if j.type == 'R' else 0 for j in m.joints], '{:d}')};",
        f"#define NW {len(layout['wrist'])}",
        "#if MODE == 1",
        f"static const int WRIST[{len(wrist)}] = {_c_array([w[0] for w in wrist], '{:d}')};",
        f"static const int WRIST_FIELD[{len(wrist)}] = {_c_array(['ABC'.index(w[1]) for w in wrist], '{:d}')};",
        "#endif",
        f"static const double Q_HOME[NQ] = {_c_array(q_home)};",
        f"static double q_prev[NQ] = {_c_array(q_home)};",
        _C_BODY,
    ]
    return "\n".join(lines) + "\n"


_C_BODY = r"""
#define NROW (6 * NCL + NOUT)
#define DEG (M_PI / 180.0)

FUNCTION(_) { }

/* c = a b (4x4 row-major) */
static void mul44(const double *a, const double *b, double *c)
{
    int i, j, k;
    for (i = 0; i < 4; i++)
        for (j = 0; j < 4; j++) {
            double s = 0.0;
            for (k = 0; k < 4; k++) s += a[4 * i + k] * b[4 * k + j];
            c[4 * i + j] = s;
        }
}

/* frame <- frame M(q): rotation about the local z axis, or translation along it (paper 1, eq. 5) */
static void motion(double *f, int rot, double q)
{
    int i;
    if (rot) {
        double c = cos(q), s = sin(q);
        for (i = 0; i < 3; i++) {
            double x = f[4 * i], y = f[4 * i + 1];
            f[4 * i] = c * x + s * y;
            f[4 * i + 1] = c * y - s * x;
        }
    } else {
        for (i = 0; i < 3; i++) f[4 * i + 3] += q * f[4 * i + 2];
    }
}

struct walk {
    double fr[NFR][16];                 /* frames defined by their chains */
    double ce[NCL > 0 ? NCL : 1][16];   /* frames reached by closing chains */
    double zj[NQ][3], pj[NQ][3];        /* joint axis and origin (base frame) */
};

/* element-by-element product of D and M matrices (paper 1, eq. 2) */
static void walk(const double *q, struct walk *w)
{
    int c, e, i;
    for (i = 0; i < 16; i++) w->fr[0][i] = (i % 5 == 0) ? 1.0 : 0.0;
    for (c = 0; c < NCH; c++) {
        double t[16], l[16];
        for (i = 0; i < 16; i++) t[i] = w->fr[CH_START[c]][i];
        for (e = CH_FIRST[c]; e < CH_FIRST[c] + CH_COUNT[c]; e++) {
            mul44(t, EL_D[e], l);
            if (EL_JOINT[e] >= 0) {
                int j = EL_JOINT[e];
                for (i = 0; i < 3; i++) { w->zj[j][i] = l[4 * i + 2]; w->pj[j][i] = l[4 * i + 3]; }
                motion(l, EL_ROT[e], q[j]);
            }
            for (i = 0; i < 16; i++) t[i] = l[i];
        }
        if (CH_CLOSE[c] >= 0) for (i = 0; i < 16; i++) w->ce[CH_CLOSE[c]][i] = t[i];
        else for (i = 0; i < 16; i++) w->fr[CH_END[c]][i] = t[i];
    }
}

/* rotation vector of R = A B^T (rows of 4x4 frames) */
static void rot_log(const double *a, const double *b, double *v)
{
    double r[3][3], tr, ang, s, k;
    int i, j, n;
    for (i = 0; i < 3; i++)
        for (j = 0; j < 3; j++) {
            r[i][j] = 0.0;
            for (n = 0; n < 3; n++) r[i][j] += a[4 * i + n] * b[4 * j + n];
        }
    tr = r[0][0] + r[1][1] + r[2][2];
    s = 0.5 * (tr - 1.0);
    if (s > 1.0) s = 1.0;
    if (s < -1.0) s = -1.0;
    ang = acos(s);
    k = (ang < 1e-8) ? 0.5 + ang * ang / 12.0 : 0.5 * ang / sin(ang);
    v[0] = k * (r[2][1] - r[1][2]);
    v[1] = k * (r[0][2] - r[2][0]);
    v[2] = k * (r[1][0] - r[0][1]);
}

/* twist of joint j: angular part om, velocity of the point x */
static void twist(const struct walk *w, int j, const double *x, double *om, double *vel)
{
    const double *z = w->zj[j], *p = w->pj[j];
    if (JOINT_ROT[j]) {
        double d[3] = {x[0] - p[0], x[1] - p[1], x[2] - p[2]};
        om[0] = z[0]; om[1] = z[1]; om[2] = z[2];
        vel[0] = z[1] * d[2] - z[2] * d[1];
        vel[1] = z[2] * d[0] - z[0] * d[2];
        vel[2] = z[0] * d[1] - z[1] * d[0];
    } else {
        om[0] = om[1] = om[2] = 0.0;
        vel[0] = z[0]; vel[1] = z[1]; vel[2] = z[2];
    }
}

/* closure residuals (rotation rows scaled by LSCALE) and their Jacobian in all joints */
static void closure_rows(const struct walk *w, double r[][1], double jac[][NQ], int row0)
{
    int k, j, i;
    for (k = 0; k < NCL; k++) {
        const double *fc = w->ce[k], *fr = w->fr[CL_FRAME[k]];
        double v[3], x[3] = {fc[3], fc[7], fc[11]};
        rot_log(fc, fr, v);
        for (i = 0; i < 3; i++) {
            r[row0 + 6 * k + i][0] = LSCALE * v[i];
            r[row0 + 6 * k + 3 + i][0] = fc[4 * i + 3] - fr[4 * i + 3];
        }
        for (j = 0; j < NQ; j++) {
            double om[3], vel[3], s = CL_SIGN[k][j];
            twist(w, j, x, om, vel);
            for (i = 0; i < 3; i++) {
                jac[row0 + 6 * k + i][j] = s * LSCALE * om[i];
                jac[row0 + 6 * k + 3 + i][j] = s * vel[i];
            }
        }
    }
}

/* largest closure residual (rotations times LSCALE, mm) */
static double closure_residual(const struct walk *w)
{
    double m = 0.0, v[3];
    int k, i;
    for (k = 0; k < NCL; k++) {
        const double *fc = w->ce[k], *fr = w->fr[CL_FRAME[k]];
        rot_log(fc, fr, v);
        for (i = 0; i < 3; i++) {
            if (fabs(LSCALE * v[i]) > m) m = fabs(LSCALE * v[i]);
            if (fabs(fc[4 * i + 3] - fr[4 * i + 3]) > m) m = fabs(fc[4 * i + 3] - fr[4 * i + 3]);
        }
    }
    return m;
}

/* solve (J^T J + damping) dx = -J^T r over the unknown joints (mask), Gaussian elimination */
static int gn_step(double r[][1], double jac[][NQ], int nrow, const int *mask, double *dx)
{
    static double a[NQ][NQ + 1];  /* static: kept off the realtime thread's stack */
    double big = 0.0;
    int idx[NQ], n = 0, i, j, k;
    for (j = 0; j < NQ; j++) if (mask[j]) idx[n++] = j;
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) {
            double s = 0.0;
            for (k = 0; k < nrow; k++) s += jac[k][idx[i]] * jac[k][idx[j]];
            a[i][j] = s;
        }
        {
            double s = 0.0;
            for (k = 0; k < nrow; k++) s += jac[k][idx[i]] * r[k][0];
            a[i][n] = -s;
        }
        if (a[i][i] > big) big = a[i][i];
    }
    for (i = 0; i < n; i++) a[i][i] += 1e-14 * (big > 0 ? big : 1.0);
    for (i = 0; i < n; i++) {
        int p = i;
        for (k = i + 1; k < n; k++) if (fabs(a[k][i]) > fabs(a[p][i])) p = k;
        if (a[p][i] == 0.0) return -1;
        if (p != i) for (j = 0; j <= n; j++) { double t = a[i][j]; a[i][j] = a[p][j]; a[p][j] = t; }
        for (k = i + 1; k < n; k++) {
            double f = a[k][i] / a[i][i];
            for (j = i; j <= n; j++) a[k][j] -= f * a[i][j];
        }
    }
    for (i = n - 1; i >= 0; i--) {
        double s = a[i][n];
        for (j = i + 1; j < n; j++) s -= a[i][j] * dx[idx[j]];
        dx[idx[i]] = s / a[i][i];
    }
    for (j = 0; j < NQ; j++) if (!mask[j]) dx[j] = 0.0;
    return 0;
}

/* output constraints: world target -> rows */
static void output_rows(const struct walk *w, const double *target_pos, const double *target_rot,
                        double r[][1], double jac[][NQ], int row0)
{
    const double *f = w->fr[OUT_FRAME];
    double x[3] = {f[3], f[7], f[11]};
    int i, j;
    for (i = 0; i < 3; i++) r[row0 + i][0] = x[i] - target_pos[i];
#if MODE == 2
    {
        double v[3];
        rot_log(f, target_rot, v);
        for (i = 0; i < 3; i++) r[row0 + 3 + i][0] = LSCALE * v[i];
    }
#endif
    for (j = 0; j < NQ; j++) {
        double om[3], vel[3], s = OUT_MEMBER[j];
        twist(w, j, x, om, vel);
        for (i = 0; i < 3; i++) jac[row0 + i][j] = s * vel[i];
#if MODE == 2
        for (i = 0; i < 3; i++) jac[row0 + 3 + i][j] = s * LSCALE * om[i];
#endif
    }
}

/* target rotation from world angles (degrees): Rz(C) Ry(B) Rx(A) (4x4 row-major, rotation part) */
static void world_rotation(const EmcPose *pos, double *t)
{
    double a = pos->a * DEG, b = pos->b * DEG, c = 0.0;
    double ca, sa, cb, sb, cc, sc;
    int i;
#if MODE == 2
    c = pos->c * DEG;
#endif
    ca = cos(a); sa = sin(a); cb = cos(b); sb = sin(b); cc = cos(c); sc = sin(c);
    for (i = 0; i < 16; i++) t[i] = 0.0;
    t[0] = cc * cb; t[1] = cc * sb * sa - sc * ca; t[2] = cc * sb * ca + sc * sa;
    t[4] = sc * cb; t[5] = sc * sb * sa + cc * ca; t[6] = sc * sb * ca - cc * sa;
    t[8] = -sb;     t[9] = cb * sa;                t[10] = cb * ca;
    t[15] = 1.0;
}

static void pose_to_world(const double *f, const double *q, EmcPose *pos)
{
    double ang[3] = {0.0, 0.0, 0.0};
    int i;
    pos->tran.x = f[3]; pos->tran.y = f[7]; pos->tran.z = f[11];
    pos->u = pos->v = pos->w = 0.0;
#if MODE == 2
    ang[1] = atan2(-f[8], sqrt(f[0] * f[0] + f[4] * f[4])) / DEG;
    ang[0] = atan2(f[9], f[10]) / DEG;
    ang[2] = atan2(f[4], f[0]) / DEG;
#elif MODE == 1
    for (i = 0; i < NW; i++) ang[WRIST_FIELD[i]] = q[WRIST[i]] / DEG;
#endif
    (void)i; (void)q;
    pos->a = ang[0]; pos->b = ang[1]; pos->c = ang[2];
}

/* limit a Newton step to 0.5 rad per revolute joint and LSCALE / 4 per prismatic joint */
static void cap_step(double *dx)
{
    double s = 1.0;
    int j;
    for (j = 0; j < NQ; j++) {
        double lim = JOINT_ROT[j] ? 0.5 : 0.25 * LSCALE;
        if (fabs(dx[j]) * s > lim) s = lim / fabs(dx[j]);
    }
    if (s < 1.0) for (j = 0; j < NQ; j++) dx[j] *= s;
}

static double max_abs(const double *v, int n)
{
    double m = 0.0;
    int i;
    for (i = 0; i < n; i++) if (fabs(v[i]) > m) m = fabs(v[i]);
    return m;
}

int kinematicsForward(const double *joints, EmcPose *pos, const KINEMATICS_FORWARD_FLAGS *fflags,
                      KINEMATICS_INVERSE_FLAGS *iflags)
{
    static struct walk w;
    static double r[6 * NCL + 1][1], jac[6 * NCL + 1][NQ];
    double q[NQ], dx[NQ];
    int mask[NQ], i;
#if NCL > 0
    int it, start;
#endif
    (void)fflags; (void)iflags; (void)r; (void)jac; (void)dx; (void)mask;
    for (i = 0; i < NQ; i++) { q[i] = q_prev[i]; mask[i] = 1; }
    for (i = 0; i < NACT; i++) {
        q[ACT[i]] = ACT_ROT[i] ? joints[i] * DEG : joints[i];
        mask[ACT[i]] = 0;
    }
    walk(q, &w);
#if NCL > 0
    for (start = 0; start < 2; start++) {  /* from the previous pose, else from home */
        if (start) {
            for (i = 0; i < NQ; i++) if (mask[i]) q[i] = Q_HOME[i];
            walk(q, &w);
        }
        for (it = 1; it <= MAXIT; it++) {
            closure_rows(&w, r, jac, 0);
            if (gn_step(r, jac, 6 * NCL, mask, dx)) return -1;
            cap_step(dx);
            for (i = 0; i < NQ; i++) q[i] += dx[i];
            walk(q, &w);
            if (max_abs(dx, NQ) < TOL) break;
        }
        if (it <= MAXIT && closure_residual(&w) <= RES_MAX) break;  /* converged to a true solution */
    }
    if (start == 2) return -1;
#endif
    for (i = 0; i < NQ; i++) q_prev[i] = q[i];
    pose_to_world(w.fr[OUT_FRAME], q, pos);
    return 0;
}

/* Newton on all joints from q (updated); 0 when converged */
static int inverse_from(double *q, const EmcPose *pos)
{
    static struct walk w;
    static double r[NROW][1], jac[NROW][NQ];
    double dx[NQ], tp[3], tr[16];
    int mask[NQ], i, it;
    tp[0] = pos->tran.x; tp[1] = pos->tran.y; tp[2] = pos->tran.z;
    world_rotation(pos, tr);
    for (i = 0; i < NQ; i++) mask[i] = 1;
#if MODE == 1
    {   /* the wrist joints are world coordinates (rotary axes commanded directly) */
        double ang[3] = {pos->a, pos->b, pos->c};
        for (i = 0; i < NW; i++) { q[WRIST[i]] = ang[WRIST_FIELD[i]] * DEG; mask[WRIST[i]] = 0; }
    }
#endif
    walk(q, &w);
    for (it = 1; it <= MAXIT; it++) {
        closure_rows(&w, r, jac, 0);
        output_rows(&w, tp, tr, r, jac, 6 * NCL);
        if (gn_step(r, jac, NROW, mask, dx)) return -1;
        cap_step(dx);
        for (i = 0; i < NQ; i++) q[i] += dx[i];
        walk(q, &w);
        if (max_abs(dx, NQ) < TOL) return closure_residual(&w) <= RES_MAX ? 0 : -1;
    }
    return -1;
}

int kinematicsInverse(const EmcPose *pos, double *joints, const KINEMATICS_INVERSE_FLAGS *iflags,
                      KINEMATICS_FORWARD_FLAGS *fflags)
{
    double q[NQ];
    int i;
    (void)iflags; (void)fflags;
    for (i = 0; i < NQ; i++) q[i] = q_prev[i];
    if (inverse_from(q, pos)) {  /* from the previous solution, else from home */
        for (i = 0; i < NQ; i++) q[i] = Q_HOME[i];
        if (inverse_from(q, pos)) return -1;
    }
    for (i = 0; i < NACT; i++)  /* a pose that needs a joint beyond its range: refused (LinuxCNC stops the move) */
        if (q[ACT[i]] < ACT_LO[i] || q[ACT[i]] > ACT_HI[i]) return -1;
    for (i = 0; i < NQ; i++) q_prev[i] = q[i];
    for (i = 0; i < NACT; i++) joints[i] = ACT_ROT[i] ? q[ACT[i]] / DEG : q[ACT[i]];
    return 0;
}

int kinematicsHome(EmcPose *world, double *joint, KINEMATICS_FORWARD_FLAGS *fflags,
                   KINEMATICS_INVERSE_FLAGS *iflags)
{
    *fflags = 0;
    *iflags = 0;
    return kinematicsForward(joint, world, fflags, iflags);
}

KINEMATICS_TYPE kinematicsType(void) { return KINEMATICS_BOTH; }

KINS_NOT_SWITCHABLE
EXPORT_SYMBOL(kinematicsType);
EXPORT_SYMBOL(kinematicsForward);
EXPORT_SYMBOL(kinematicsInverse);
EXPORT_SYMBOL(kinematicsHome);
"""
