"""Self-checks of the blind generator (never against hyperstat's diagnosis).

    python -m tests.solver.diagnosis.blind.selfcheck --hyperstat PATH/TO/hyperstat [--seeds 3] [--out selfcheck.md]

1. Forward kinematics against hyperstat's nominal model, as a black box (``import-robot`` of
   our URDF, then ``identify`` on our files): exact measurements of the nominal machine must
   be reproduced by hyperstat's *nominal* model with only the tracker frame and the reflector
   offsets fitted (RMS < 0.1 um); exact measurements of a machine with our placement errors
   must be reproduced by the calibrated model (RMS < 1 um: the errors lie in hyperstat's
   parameter space, so a "none" campaign has nothing unmodelled); with noise, sigma near 1
   and the validation RMS near the noise.  Also for 3 reflectors with lengths in m, angles in
   deg and every metadata column (the file is read as intended), and for the URDF without
   masses.  When the model file carries ``metadata.masses`` they are compared with ours.
2. Our physics by a second method: gravity torques from the potential-energy derivative
   against the cross-product formula ``z_j . ((c_b - o_j) x m_b g)``; the beam and pedestal
   closed forms against a numerical integration of the Euler-Bernoulli equations
   (``dtheta/ds = M(s)/EI``, ``dw/ds = theta x e``).
3. Effect sizes: per case and arm, the effect's RMS contribution at the reflectors and what
   our own rigid calibration leaves of it on the validation poses (``rigid.visibility``).
4. Noise: (measured - exact) / header sigma, pooled per noise factor: its standard deviation
   must be the case's factor (1 as stated, 1.5 / 1.7 / 2 understated), and hyperstat's
   ``noise_rms`` must equal ours on the identification points.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess

import tempfile
import time

import numpy as np

from . import effects as fx
from .cases import CASES
from .generator import build, noise_rms, write
from .kinematics import GVEC, Geometry, com_positions, frames, get_arm, gravity_torques, mass_vector
from .rigid import visibility


def _run(cmd, timeout=600):
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr


def identify(hyperstat, outdir, files, skel):
    out = os.path.join(outdir, "id.json")
    rc, so, se = _run([hyperstat, "identify", skel, files["data"], "--validation", files["validation"], "--json", out, "--quiet"])
    if rc != 0 or not os.path.exists(out):
        return {"error": (se or so).strip()[-400:], "rc": rc}
    with open(out) as f:
        return json.load(f)


def check_fk(hyperstat, work, lines):
    lines.append("## 1. Forward kinematics against hyperstat's nominal model (black box: import-robot + identify)\n")
    lines.append("| arm | URDF | campaign | geometric errors | noise | hyperstat fit | RMS ident (um) | RMS valid (um) | noise RMS (um, hyperstat / ours) | sigma | pass |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|")
    ok_all = True
    runs = [
        ("none", "ind6", False, False, "nominal"), ("none", "ind6", True, False, "calibrated"),
        ("none", "ind6", True, True, "calibrated"),
        ("none", "cobot6", False, False, "nominal"), ("none", "cobot6", True, False, "calibrated"),
        ("none", "cobot6", True, True, "calibrated"),
        ("none-3smr-meta", "ind6", False, False, "nominal"), ("none-3smr-meta", "ind6", True, False, "calibrated"),
        ("none-3smr-meta", "cobot6", True, False, "calibrated"), ("none-3smr-meta", "cobot6", True, True, "calibrated"),
        ("none-nomass", "ind6", False, False, "nominal"), ("none-nomass", "cobot6", True, True, "calibrated"),
    ]
    skels = {}
    for case, arm, geo, noise, which in runs:
        d = os.path.join(work, f"fk_{case}_{arm}_{int(geo)}{int(noise)}")
        c = build(case, arm, 0, geometry_errors=geo, noise=noise)
        files = write(c, d, analysis=False)
        key = (arm, c.case.masses)
        skel = os.path.join(work, f"{arm}{'' if c.case.masses else '_nomass'}.skel.json")
        if key not in skels:
            rc, so, se = _run([hyperstat, "import-robot", files["urdf"], "--out", skel, "--quiet"])
            if rc != 0:
                lines.append(f"| {arm} | import-robot failed: {se.strip()[-200:]} |")
                ok_all = False
                continue
            skels[key] = skel
        res = identify(hyperstat, d, files, skel)
        if "error" in res:
            lines.append(f"| {arm} | {'masses' if c.case.masses else 'no masses'} | {case} | {geo} | {noise} | identify failed (rc {res['rc']}): {res['error']} | | | | | no |")
            ok_all = False
            continue
        stats = res["nominal"] if which == "nominal" else res
        # hyperstat reports mm; everything below in um
        rid, rva = stats["identification"]["rms"] * 1e3, stats["validation"]["rms"] * 1e3
        ours = noise_rms(c.sigma_header, np.flatnonzero(~c.is_val)) * 1e6
        hs_noise = (res.get("noise_rms") or float("nan")) * 1e3
        sigma = stats.get("sigma", float("nan"))
        if not noise:
            good = rid < (0.1 if which == "nominal" else 1.0) and rva < (0.1 if which == "nominal" else 2.0)
        else:
            ours_val = noise_rms(c.sigma_header, np.flatnonzero(c.is_val)) * 1e6
            good = 0.85 <= sigma <= 1.15 and rva / ours_val < 1.3
        good = good and abs(hs_noise - ours) < 0.01 * ours
        ok_all &= good
        lines.append(f"| {arm} | {'masses' if c.case.masses else 'no masses'} | {case} | {geo} | {noise} | {which} | "
                     f"{rid:.4g} | {rva:.4g} | {hs_noise:.2f} / {ours:.2f} | {sigma:.3g} | {'yes' if good else 'NO'} |")
    lines.append("")
    lines.append("Pass: exact data, nominal machine: the nominal model's RMS < 0.1 um; exact data with placement "
                 "errors: the calibrated RMS < 1 um (validation < 2 um); noisy data: sigma in [0.85, 1.15] and "
                 "validation RMS < 1.3x the noise; hyperstat's noise RMS equal to ours within 1 %.\n")
    # masses in the model file
    lines.append("### Link masses in hyperstat's model file\n")
    for (arm, masses), skel in skels.items():
        with open(skel) as f:
            model = json.load(f)
        md = model.get("metadata", {}).get("masses")
        if not masses:
            lines.append(f"* {arm} without `<inertial>`: `metadata.masses` {'absent (as it should be)' if not md else 'PRESENT: ' + json.dumps(md)[:200]}")
            ok_all &= not md
            continue
        if not md:
            lines.append(f"* {arm}: the model file has no `metadata.masses` (this hyperstat does not keep URDF inertials); not compared.")
            continue
        a = get_arm(arm)
        fr = frames(a, Geometry.nominal(a.n), np.zeros((1, a.n)))
        com = com_positions(a, fr)[0] * 1000.0
        worst = 0.0
        txt = []
        for i, jt in enumerate(a.joints):
            e = md.get(jt.name)
            if e is None:
                txt.append(f"{jt.name}: missing")
                worst = float("inf")
                continue
            dm = abs(e["mass"] - a.masses[i])
            dc = float(np.linalg.norm(np.array(e["com"]) - com[i]))
            worst = max(worst, dm, dc)
            txt.append(f"{jt.name}: {e['mass']:g} kg vs {a.masses[i]:g}, com off by {dc:.3g} mm")
        lines.append(f"* {arm}: " + "; ".join(txt))
        ok_all &= worst < 1e-6 * 1e3
    lines.append("")
    return ok_all


def _torques_cross(arm, geom, q, payload):
    fr = frames(arm, geom, q)
    com = com_positions(arm, fr)
    m = mass_vector(arm, payload)
    tau = np.zeros_like(q)
    for j in range(arm.n):
        f = fr[j + 1]                     # frame of link j+1 (after joint j): the axis is its joint's axis
        z = np.einsum("kij,j->ki", f[:, :3, :3], arm.joints[j].axis)
        o = f[:, :3, 3]
        lever = com[:, j:] - o[:, None, :]
        w = m[:, j:, None] * GVEC[None, None, :]
        tau[:, j] = np.einsum("ki,ki->k", z, np.sum(np.cross(lever, w), axis=1))
    return tau


def _beam_ode(ctx, which, n=4000):
    """End deflection and rotation of the beam by integrating the Euler-Bernoulli equations."""
    arm = ctx.arm
    bm = arm.beams[which]
    fr = frames(arm, ctx.geom, ctx.q)
    com = com_positions(arm, fr)
    m = mass_vector(arm, ctx.payload)
    rl = fr[bm.link][:, :3, :3]
    e = np.einsum("kij,j->ki", rl, bm.direction)
    root = np.einsum("kij,j->ki", rl, bm.start) + fr[bm.link][:, :3, 3]
    L = bm.length
    down = slice(bm.link, arm.n + 1)
    wvec = (m[:, bm.link - 1] / L)[:, None] * GVEC[None, :]
    s = (np.arange(n) + 0.5) * L / n
    theta = np.zeros_like(e)
    defl = np.zeros_like(e)
    for x in s:
        p = root + x * e
        # internal moment at the section: everything outboard about p
        mom = np.sum(np.cross(com[:, down] - p[:, None, :], m[:, down, None] * GVEC[None, None, :]), axis=1)
        mom += np.cross(0.5 * (L - x) * e, wvec * (L - x))   # the outboard part of the own weight, at its middle
        mb = mom - np.sum(mom * e, axis=1)[:, None] * e
        theta = theta + mb / bm.EI * (L / n)
        defl = defl + np.cross(theta - mb / bm.EI * (L / n) / 2, e) * (L / n)
    return defl, theta


def check_physics(lines):
    lines.append("## 2. Our physics by a second method\n")
    ok = True
    rng = np.random.default_rng(5)
    for key in ("ind6", "cobot6"):
        arm = get_arm(key)
        box = arm.ranges()
        q = rng.uniform(box[:, 0], box[:, 1], size=(50, arm.n))
        pay = rng.uniform(0, arm.payload_max, 50)
        geom = Geometry.random(rng, arm.n)
        t1 = gravity_torques(arm, geom, q, pay)
        t2 = _torques_cross(arm, geom, q, pay)
        err = float(np.max(np.abs(t1 - t2)))
        scale = float(np.max(np.abs(t2)))
        ok &= err < 1e-6 * scale
        lines.append(f"* {key}: gravity torques, -dV/dq (central differences) vs cross-product formula over 50 poses "
                     f"with payload: max difference {err:.2e} N m (largest torque {scale:.0f} N m)")
        ctx = fx.Context(arm, geom, q, pay, np.full(50, 20.0), np.ones((50, 6)), np.ones(50), 1)
        for which, bm in arm.beams.items():
            ch = fx.beam(ctx, which, bending=1.0)
            d4 = ch.deform[bm.link]
            centre = bm.start + bm.length * bm.direction
            # closed form, back in the world frame
            rl = frames(arm, geom, q)[bm.link][:, :3, :3]
            d_link = d4[:, :3, 3] - centre + np.einsum("kij,j->ki", d4[:, :3, :3], centre)
            rot_link = np.stack([_rotvec(r) for r in d4[:, :3, :3]])
            d_w = np.einsum("kij,kj->ki", rl, d_link)
            r_w = np.einsum("kij,kj->ki", rl, rot_link)
            d_o, r_o = _beam_ode(ctx, which)
            ed = float(np.max(np.linalg.norm(d_w - d_o, axis=1)))
            er = float(np.max(np.linalg.norm(r_w - r_o, axis=1)))
            md = float(np.max(np.linalg.norm(d_o, axis=1)))
            mr = float(np.max(np.linalg.norm(r_o, axis=1)))
            good = ed < 2e-3 * md + 1e-9 and er < 2e-3 * mr + 1e-12
            ok &= good
            lines.append(f"* {key} {which}-arm beam: closed form vs Euler-Bernoulli integration (4000 steps), 50 poses: "
                         f"end deflection max {md * 1e6:.1f} um, difference {ed * 1e6:.3f} um; end rotation max "
                         f"{mr * 1e6:.1f} urad, difference {er * 1e6:.3f} urad {'(ok)' if good else '(FAIL)'}")
    lines.append("")
    return ok


def _rotvec(r):
    from .kinematics import log_so3
    return log_so3(r)


def check_effects(seeds, lines):
    lines.append("## 3. Effect sizes (our own numbers, seeds 0..%d)\n" % (seeds - 1))
    lines.append("Effect RMS: RMS over all reflector observations of the 3-D displacement the effect causes (noise-free). "
                 "Left: what our own full rigid calibration (fitted on the identification poses) leaves of it on the "
                 "validation poses. Ratio: expected validation RMS / header noise RMS, sqrt(f^2 noise^2 + left^2) / noise. "
                 "Within noise: library-like candidates (our implementation) that leave < 0.35x the noise RMS.\n")
    lines.append("| case | arm | category | size (seed 0) | effect RMS (um) | left after rigid fit (um) | noise RMS (um) | expected ratio | best alias (left um) | fits within noise (seed 0) |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|")
    for c in CASES:
        for arm in c.arms:
            raws, lefts, noises, ratios = [], [], [], []
            first = None
            for s in range(seeds):
                cp = build(c.name, arm, s)
                v = visibility(cp)
                raws.append(np.sqrt(np.mean(np.sum((cp.clean - cp.rigid) ** 2, axis=2))) * 1e6)
                lefts.append(v["effect_left_val_um"])
                noises.append(noise_rms(cp.sigma_header, np.flatnonzero(cp.is_val)) * 1e6)
                ratios.append(v["expected_val_ratio"])
                if first is None:
                    first = (cp.size, v)
            size, v = first
            al = v["aliases"][0] if v["aliases"] else None
            altxt = f"{al['candidate']} ({al['left_val_um']:.0f})" if al else "-"
            fw = ", ".join(v["fits_within_noise"][:4]) or "-"
            lines.append(f"| {c.name} | {arm} | {c.category} | {size} | {_rng(raws)} | {_rng(lefts)} | {_rng(noises)} | "
                         f"{_rng(ratios, 2)} | {altxt} | {fw} |")
    lines.append("")


def _rng(v, nd=1):
    return f"{min(v):.{nd}f}-{max(v):.{nd}f}" if len(v) > 1 else f"{v[0]:.{nd}f}"


def check_noise(seeds, lines):
    lines.append("## 4. Noise against the header\n")
    pools = {}
    for c in CASES:
        for arm in c.arms:
            for s in range(seeds):
                cp = build(c.name, arm, s)
                z = (cp.measured - cp.clean) / cp.sigma_header[:, :, None]
                z = z[~np.isnan(z)]
                pools.setdefault(c.noise_factor, []).append(z)
    ok = True
    lines.append("| true factor on the header's noise | observations (per axis) | std of (measured - exact) / header sigma | mean |")
    lines.append("|---|---|---|---|")
    for f, zs in sorted(pools.items()):
        z = np.concatenate(zs)
        sd = float(np.std(z))
        se = f / np.sqrt(2 * len(z))
        good = abs(sd - f) < 4 * se
        ok &= good
        lines.append(f"| {f:g} | {len(z)} | {sd:.4f} (expected {f:g} +- {se:.4f}) | {np.mean(z):+.4f} |")
    lines.append("")
    return ok


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hyperstat", required=True)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    t0 = time.process_time()
    lines = ["# Self-checks of the blind generator", ""]
    with tempfile.TemporaryDirectory(prefix="blind28_selfcheck_") as work:
        ok1 = check_fk(a.hyperstat, work, lines)
    ok2 = check_physics(lines)
    check_effects(a.seeds, lines)
    ok4 = check_noise(a.seeds, lines)
    lines.append(f"Summary: forward kinematics {'pass' if ok1 else 'FAIL'}, physics {'pass' if ok2 else 'FAIL'}, "
                 f"noise {'pass' if ok4 else 'FAIL'} ({time.process_time() - t0:.0f} s CPU in this process).")
    text = "\n".join(lines) + "\n"
    if a.out:
        with open(a.out, "w") as f:
            f.write(text)
    print(text)
    return 0 if (ok1 and ok2 and ok4) else 1


if __name__ == "__main__":
    raise SystemExit(main())
