"""hyperstat benchmarks: medians over repeated runs (units: seconds, configurations per second, MiB).

Run with ``make bench`` (or ``.venv/bin/python benchmarks/run.py``).  Prints a table; with
``--markdown FILE`` also writes it as Markdown.  Timings are wall-clock medians of
``--repeat`` runs after one warm-up run ("warm"); "cold" runs start a fresh Python
process and include the imports.  Peak memory is the peak of Python allocations (numpy
included) measured with ``tracemalloc`` in one extra run, or for a new process its maximum
resident set size.

After the table come the ratios against the peers (pinocchio called per configuration
from Python, a naive per-configuration numpy loop) for the forward kinematics and the
Jacobian of the same 6R arm (``benchmarks/serial6r.py``; poses and Jacobians are checked
to agree to 1e-9 before anything is timed), and the arithmetic limit of this machine:
the floating-point operations per configuration of that forward kinematics, divided into
the peak rate of a large numpy matrix product.

The pinocchio benchmarks are skipped, with the reason printed, when pinocchio (PyPI
``pin``, the ``bench`` extra) is not installed; so are the numba and JAX peers
(``benchmarks/peers6r.py``, the ``bench`` extra installs numba; JAX is optional).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))
warnings.simplefilter("ignore")

TEMPLATES = ["slider_crank", "tripteor_x7", "triflex_ii", "scara", "hexapod"]
BENCHES: dict = {}

#: configurations of the batched forward-kinematics benchmarks
N_BATCH = 100_000
#: configurations timed one by one for the peers
N_PINOCCHIO = 20_000
N_NAIVE = 2_000
#: configurations of the Tripteor assembly benchmark
N_ASSEMBLY = 10_000


class Skip(Exception):
    """Raised by a benchmark's setup when it cannot run here; the message says why."""


def bench(name: str, unit: str = "s", hook: bool = False):
    """Register a benchmark.

    The function returns ``(work, count)``: ``work`` is a setup-free callable, ``count``
    the configurations (unit ``configs/s``) or floating-point operations (``GFLOP/s``) one
    call does, or ``None`` for a duration (``s``).  A ``hook`` benchmark calls code built
    elsewhere: any error in it is reported as a skip instead of stopping the run.
    """

    def deco(fn):
        BENCHES[name] = (fn, unit, hook)
        return fn

    return deco


def _mech(name: str):
    from hyperstat.cad_plugin.templates import build_template

    return build_template(ROOT / "templates" / f"{name}.py").mechanism()


def _optional(module: str, *attributes: str):
    """Import ``module`` and check it has ``attributes``, else :class:`Skip`."""
    if importlib.util.find_spec(module) is None:
        raise Skip(f"module {module} is not in this tree (it is being built in parallel)")
    mod = importlib.import_module(module)
    missing = [a for a in attributes if not hasattr(mod, a)]
    if missing:
        raise Skip(f"{module} has no {', '.join(missing)}: update the hook in benchmarks/run.py")
    return mod


# ---------------------------------------------------------------------------- machine peak
MATMUL_N = 3072


@bench(f"numpy matmul {MATMUL_N}x{MATMUL_N} (machine peak, all cores)", unit="GFLOP/s")
def _peak():
    import numpy as np

    rng = np.random.default_rng(0)
    a, b = rng.random((MATMUL_N, MATMUL_N)), rng.random((MATMUL_N, MATMUL_N))
    out = np.empty_like(a)
    return (lambda: np.matmul(a, b, out=out)), 2 * MATMUL_N**3


# ---------------------------------------------------------------------------- 6R arm and peers
_ARM: dict = {}


def _arm():
    """The 6R arm at a random small defect vector (general D matrices), configurations, references."""
    if not _ARM:
        import numpy as np

        from serial6r import arm_6r, arm_geometry, naive_fk_jacobian
        from hyperstat.solver import Kinematics

        mech = arm_6r()
        kin = Kinematics(mech)
        rng = np.random.default_rng(1)
        xi = rng.normal(0.0, 1e-3, kin.n_xi)  # rad / mm: an "identified" arm, every D general
        lo, hi = mech.ranges[:, 0], mech.ranges[:, 1]
        q = lo + rng.random((N_BATCH, kin.n_q)) * (hi - lo)
        geometry = arm_geometry(kin, xi)
        pose, jac = kin.forward(q[:500], xi, jacobian=True)
        pose_n, jac_n = naive_fk_jacobian(geometry, q[:500])
        err = max(np.abs(pose - pose_n).max(), np.abs(jac - jac_n).max())
        if err > 1e-9:
            raise AssertionError(f"batched and naive 6R kinematics disagree by {err:.3g}")
        _ARM.update(mech=mech, kin=kin, xi=xi, q=q, geometry=geometry)
    return _ARM


def _pinocchio():
    """pinocchio twin of the arm, checked against the batched poses and Jacobians to 1e-9."""
    if "pin" not in _ARM:
        try:
            import pinocchio as pin
        except ImportError:
            raise Skip("pinocchio (PyPI 'pin') is not installed: pip install -e '.[bench]'") from None
        import numpy as np

        from serial6r import pinocchio_arm

        arm = _arm()
        model, data, fid = pinocchio_arm(arm["geometry"])
        q = arm["q"][:1000]
        pose, jac = arm["kin"].forward(q, arm["xi"], jacobian=True)
        worst = 0.0
        for k in range(len(q)):
            jp = pin.computeFrameJacobian(model, data, q[k], fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            pin.forwardKinematics(model, data, q[k])
            m = pin.updateFramePlacement(model, data, fid).homogeneous
            # pinocchio's rows are (v, omega); ours (omega, v), both at the output origin, base axes
            worst = max(worst, np.abs(m - pose[k]).max(), np.abs(jp[:3] - jac[k, 3:]).max(),
                        np.abs(jp[3:] - jac[k, :3]).max())
        if worst > 1e-9:
            raise AssertionError(f"pinocchio and hyperstat disagree on the 6R arm by {worst:.3g}")
        _ARM.update(pin=pin, model=model, data=data, fid=fid, pin_check=worst)
    return _ARM


@bench("FK 6R: hyperstat batched (Kinematics.forward), all cores", unit="configs/s")
def _fk_batched():
    arm = _arm()
    kin, q, xi = arm["kin"], arm["q"], arm["xi"]
    return (lambda: kin.forward(q, xi)), len(q)


@bench("FK 6R: hyperstat batched, 1 thread", unit="configs/s")
def _fk_batched_1():
    arm = _arm()
    kin, q, xi = arm["kin"], arm["q"], arm["xi"]
    return (lambda: kin.forward(q, xi, threads=1)), len(q)


@bench("FK 6R: hyperstat element-by-element path (before fastfk)", unit="configs/s")
def _fk_generic():
    from hyperstat.solver import Kinematics

    arm = _arm()
    kin = Kinematics(arm["mech"])
    kin.use_plan = False
    q, xi = arm["q"], arm["xi"]
    return (lambda: kin.evaluate(q, xi, jacobians=False)), len(q)


def _pinocchio_loop(make_call):
    """Benchmark setup: ``make_call(pin)(model, data, q, frame_id)`` once per configuration
    (everything that does not depend on the configuration is looked up before timing)."""

    def setup():
        arm = _pinocchio()
        model, data, fid = arm["model"], arm["data"], arm["fid"]
        call = make_call(arm["pin"])
        q = list(arm["q"][:N_PINOCCHIO])

        def work():
            for qk in q:
                call(model, data, qk, fid)

        return work, len(q)

    return setup


def _naive_loop(function_name: str):
    """Benchmark setup: ``serial6r.<function_name>(geometry, q)``, a per-configuration numpy loop."""

    def setup():
        import serial6r

        arm = _arm()
        geometry, q = arm["geometry"], arm["q"][:N_NAIVE]
        function = getattr(serial6r, function_name)
        return (lambda: function(geometry, q)), len(q)

    return setup


def _pin_fk(pin):
    forward, place = pin.forwardKinematics, pin.updateFramePlacement

    def call(model, data, qk, fid):
        forward(model, data, qk)
        place(model, data, fid)

    return call


def _pin_jacobian(pin):
    jacobian, ref = pin.computeFrameJacobian, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    return lambda model, data, qk, fid: jacobian(model, data, qk, fid, ref)


bench("FK 6R: pinocchio, one call per configuration", unit="configs/s")(_pinocchio_loop(_pin_fk))


def _peer(builder: str, package: str):
    """Benchmark setup: the peer ``peers6r.<builder>`` on the batched 6R arm, checked to 1e-9 first."""

    def setup():
        import numpy as np

        import peers6r

        arm = _arm()
        try:
            fk = getattr(peers6r, builder)(arm["geometry"])
        except ImportError:
            raise Skip(f"{package} is not installed (pip install {package}); not a dependency of hyperstat") from None
        q = arm["q"]
        ref = arm["kin"].forward(q[:1000], arm["xi"])[0]
        err = float(np.abs(fk(q[:1000]) - ref).max())
        if err > 1e-9:
            raise AssertionError(f"{builder} and hyperstat disagree on the 6R arm by {err:.3g}")
        _ARM[f"{builder}_check"] = err
        return (lambda: fk(q)), len(q)

    return setup


bench("FK 6R: numba compiled loop, all cores (compiled reference)", unit="configs/s")(_peer("numba_fk", "numba"))
bench("FK 6R: JAX jit + vmap, float64", unit="configs/s")(_peer("jax_fk", "jax[cpu]"))


bench("FK 6R: naive numpy loop per configuration", unit="configs/s")(_naive_loop("naive_fk"))


@bench("trig only: tan(q/2) of 6 joints (part of batched FK)", unit="configs/s")
def _trig():
    import numpy as np

    q = np.ascontiguousarray(_arm()["q"].T)
    return (lambda: np.tan(q * 0.5)), q.shape[1]


@bench("trig only: sin and cos of 6 joints (what a sin/cos FK pays)", unit="configs/s")
def _trig_sincos():
    import numpy as np

    q = np.ascontiguousarray(_arm()["q"].T)
    return (lambda: (np.sin(q), np.cos(q))), q.shape[1]


@bench("FK+Jacobian 6R: hyperstat batched, all cores", unit="configs/s")
def _jac_batched():
    arm = _arm()
    kin, q, xi = arm["kin"], arm["q"], arm["xi"]
    return (lambda: kin.forward(q, xi, jacobian=True)), len(q)


bench("FK+Jacobian 6R: pinocchio computeFrameJacobian per configuration", unit="configs/s")(
    _pinocchio_loop(_pin_jacobian))


bench("FK+Jacobian 6R: naive numpy loop per configuration", unit="configs/s")(_naive_loop("naive_fk_jacobian"))


# ---------------------------------------------------------------------------- Tripteor
_TRIPTEOR: dict = {}


def _tripteor():
    if not _TRIPTEOR:
        import numpy as np

        from hyperstat.solver import Kinematics, analyze

        mech = _mech("tripteor_x7")
        kin = Kinematics(mech)
        analysis = analyze(mech, kinematics=kin)
        rng = np.random.default_rng(2)
        act = mech.actuated
        lo, hi = mech.ranges[act, 0], mech.ranges[act, 1]
        qa = lo + (0.1 + 0.8 * rng.random((N_ASSEMBLY, len(act)))) * (hi - lo)
        res = kin.solve(qa[:2000])
        q = res.q[res.converged]
        q = np.tile(q, (N_BATCH // len(q) + 1, 1))[:N_BATCH]  # assembled configurations
        _TRIPTEOR.update(mech=mech, kin=kin, analysis=analysis, qa=qa, q=q)
    return _TRIPTEOR


@bench("FK Tripteor: all frames + loop residuals (Kinematics.evaluate)", unit="configs/s")
def _fk_tripteor():
    t = _tripteor()
    kin, q = t["kin"], t["q"]
    return (lambda: kin.evaluate(q, jacobians=False)), len(q)


@bench("FK Tripteor: output pose only (Kinematics.forward)", unit="configs/s")
def _fk_tripteor_out():
    t = _tripteor()
    kin, q = t["kin"], t["q"]
    return (lambda: kin.forward(q)), len(q)


@bench("closure assembly Tripteor (Kinematics.solve, certified adaptive continuation from home)", unit="configs/s")
def _assembly_tripteor():
    t = _tripteor()
    kin, qa = t["kin"], t["qa"]
    return (lambda: kin.solve(qa)), len(qa)


# ---------------------------------------------------------------------------- analyses
for _t in TEMPLATES:
    def _make(t=_t):
        def setup():
            from hyperstat.solver import Kinematics, analyze

            mech = _mech(t)
            kin = Kinematics(mech)
            return (lambda: analyze(mech, kinematics=kin)), None
        return setup
    bench(f"stationarity analysis, {_t} (warm)")(_make())


@bench("stationarity analysis, tripteor_x7 (cold, new process)")
def _cold_tripteor():
    code = ("import warnings; warnings.simplefilter('ignore');"
            "from hyperstat.cad_plugin.templates import build_template; from hyperstat.solver import analyze;"
            f"analyze(build_template(r'{ROOT / 'templates' / 'tripteor_x7.py'}').mechanism())")
    return (lambda: _child([sys.executable, "-c", code])), None


@bench("identification, tripteor_x7, 107 + 30 validation points (warm)")
def _identify_tripteor():
    from hyperstat.solver import Kinematics, analyze
    from hyperstat.solver.calibration.identify import identify
    from hyperstat.solver.calibration.virtual import VirtualMachine

    mech = _mech("tripteor_x7")
    kin = Kinematics(mech)
    analysis = analyze(mech, kinematics=kin)
    vm = VirtualMachine.random(mech, analysis, seed=0, kinematics=kin)
    q = vm.poses(137, seed=1)
    data, val = vm.measure(q[:107], seed=2), vm.measure(q[107:], seed=3, prefix="V")
    return (lambda: identify(mech, analysis, data, val, kinematics=kin)), None


@bench("D-optimal choice of 107 poses among 1000, tripteor_x7")
def _select_tripteor():
    from hyperstat.solver import Kinematics, analyze
    from hyperstat.solver.calibration.identify import MeasurementModel
    from hyperstat.solver.calibration.poses import select_poses
    from hyperstat.solver.calibration.virtual import VirtualMachine

    mech = _mech("tripteor_x7")
    kin = Kinematics(mech)
    analysis = analyze(mech, kinematics=kin)
    vm = VirtualMachine.random(mech, analysis, seed=0, kinematics=kin)
    candidates = vm.poses(1000, seed=1)
    model = MeasurementModel(mech, analysis, kin)
    return (lambda: select_poses(model, candidates, 107, noise=vm.noise)), None


# ---------------------------------------------------------------------------- assembly branches (issue 18)
_MODEL_FILES: dict = {}
BRANCH_MODELS = ["slider_crank", "tripteor_x7", "triflex_ii", "hexapod", "crossed_isogram"]


def _model_file(name: str) -> str:
    """A model file (mm, rad) of a template, or of the crossed isogram written from its geometry."""
    if name not in _MODEL_FILES:
        import json

        from hyperstat.solver import save_model

        tmp = Path(tempfile.mkdtemp(prefix="hyperstat-bench-"))
        path = tmp / f"{name}.json"
        if name == "crossed_isogram":
            from tests.solver.kinematics.fourbar import fourbar_document

            import numpy as np

            path.write_text(json.dumps(fourbar_document(100.0, 300.0, 100.0, 300.0, -0.2, 1, (-np.pi, 0.0),
                                                        name=name)))
        else:
            save_model(_mech(name), path)
        _MODEL_FILES[name] = str(path)
    return _MODEL_FILES[name]


for _t in BRANCH_MODELS:
    for _n in (1, 2):
        def _make(t=_t, n=_n):
            def setup():
                cmd = [sys.executable, "-m", "hyperstat.solver", "analyze", _model_file(t), "--quiet",
                       "--samples", str(n)]
                return (lambda: _child(cmd)), None
            return setup
        bench(f"analyze command, {_t} model file, --samples {_n} (whole command, new process)")(_make())


for _t in BRANCH_MODELS:
    def _make_sampling(t=_t):
        def setup():
            from hyperstat.solver import Kinematics, load_model
            from hyperstat.solver.kinematics.sampling import sample_configurations

            kin = Kinematics(load_model(_model_file(t)))
            return (lambda: sample_configurations(kin, 200, seed=0)), 200
        return setup
    bench(f"workspace sampling, {_t}: 200 configurations, nearest-neighbour certified continuation",
          unit="configs/s")(_make_sampling())


# ---------------------------------------------------------------------------- accuracy (paper 2)
def _triflex_configurations(n: int):
    import numpy as np

    from hyperstat.solver import Kinematics
    from hyperstat.solver.tolerances.accuracy import sample_workspace

    mech = _mech("triflex_ii")
    kin = Kinematics(mech)
    base = sample_workspace(mech, 2000, seed=0, kinematics=kin)
    return mech, kin, base[np.arange(n) % len(base)]


@bench("accuracy coefficients, triflex_ii, 100,000 configurations")
def _accuracy_triflex():
    from hyperstat.solver.tolerances.accuracy import accuracy_maps

    mech, kin, q = _triflex_configurations(100_000)
    return (lambda: accuracy_maps(mech, q, kinematics=kin)), None


@bench("Monte Carlo, triflex_ii, 100,000 samples (nonlinear re-assembly)")
def _montecarlo_triflex():
    from hyperstat.solver.tolerances.montecarlo import monte_carlo

    mech, kin, q = _triflex_configurations(2000)
    tolerances = {p.name: (6.76e-3 if p.unit == "rad" else 5e-3) for p in mech.parameters}  # rad / mm
    return (lambda: monte_carlo(mech, q, tolerances, samples=100_000, kinematics=kin)), None


@bench("hyperstat report, tripteor_x7 (cold, new process)")
def _report_tripteor():
    from hyperstat.cad_plugin.cli import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    if "report" not in sub.choices:
        raise Skip("the 'report' command is not in this tree (it is being built in parallel)")
    exe = str(Path(sys.executable).with_name("hyperstat"))
    tmp = Path(tempfile.mkdtemp(prefix="hyperstat-bench-"))
    template = str(ROOT / "templates" / "tripteor_x7.py")
    _child([exe, "simulate", template, "--out", str(tmp / "d.csv"), "--quiet"])
    cmd = [exe, "report", template, "--data", str(tmp / "d.csv"), "--validation", str(tmp / "d.validation.csv"),
           "--hypotheses", str(ROOT / "templates" / "tripteor_x7.hypotheses.yaml"), "--out", str(tmp / "report"),
           "--quiet"]
    return (lambda: _child(cmd)), None


# ---------------------------------------------------------------------------- runner
_CHILD_PEAK: list[float] = []
_CHILD_TIME: list[float] = []

# A small launcher runs the command and reports its wall time and maximum resident set: measured
# from this (large) process, a forked child would be charged this process's memory.
_LAUNCHER = (
    "import os, subprocess, sys, time\n"
    "t0 = time.perf_counter()\n"
    "p = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL)\n"
    "_, status, usage = os.wait4(p.pid, 0)\n"
    "print(time.perf_counter() - t0, usage.ru_maxrss, os.waitstatus_to_exitcode(status))\n"
)


def _child(cmd: list[str]) -> None:
    """Run a new process; record its wall time (s) and maximum resident set size (MiB)."""
    out = subprocess.run([sys.executable, "-S", "-c", _LAUNCHER, *cmd], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout.split()
    elapsed, maxrss, code = float(out[0]), int(out[1]), int(out[2])
    if code:
        raise subprocess.CalledProcessError(code, cmd)
    _CHILD_TIME.append(elapsed)
    _CHILD_PEAK.append(maxrss / 1024)  # KiB -> MiB


def _value(unit: str, med: float, count) -> float:
    if unit == "configs/s":
        return count / med
    if unit == "GFLOP/s":
        return count / med / 1e9
    return med


def run(names: list[str], repeat: int) -> dict:
    """Run benchmarks; returns name -> (value, unit, peak MiB, note)."""
    rows = {}
    for name in names:
        fn, unit, hook = BENCHES[name]
        try:
            work, count = fn()
            work()  # warm-up
            times = []
            _CHILD_PEAK.clear()
            _CHILD_TIME.clear()
            for _ in range(repeat):
                t0 = time.perf_counter()
                work()
                times.append(time.perf_counter() - t0)
            if _CHILD_TIME:
                times = _CHILD_TIME[-repeat:]  # the new process alone, without the launcher
            if _CHILD_PEAK:
                peak = max(_CHILD_PEAK)
            else:
                tracemalloc.start()  # a separate run: tracing slows Python down
                work()
                peak = tracemalloc.get_traced_memory()[1] / 2**20
                tracemalloc.stop()
        except Skip as exc:
            rows[name] = (None, unit, None, f"skipped: {exc}")
            print(f"{name:<72} skipped: {exc}", flush=True)
            continue
        except Exception as exc:  # noqa: BLE001 - a hook into code built elsewhere
            if not hook:
                raise
            rows[name] = (None, unit, None, f"skipped: {exc.__class__.__name__}: {exc}")
            print(f"{name:<72} skipped: {exc.__class__.__name__}: {exc}", flush=True)
            continue
        value = _value(unit, statistics.median(times), count)
        rows[name] = (value, unit, peak, "")
        print(f"{name:<72} {value:>12.4g} {unit:<10} peak {peak:8.1f} MiB", flush=True)
    return rows


def summary(rows: dict) -> list[str]:
    """Ratios against the peers and the arithmetic limit, as Markdown lines."""

    def val(prefix: str):
        for n, r in rows.items():
            if n.startswith(prefix) and r[0] is not None:
                return r[0]
        return None

    lines = []
    fk, fk1 = val("FK 6R: hyperstat batched (K"), val("FK 6R: hyperstat batched, 1 thread")
    pairs = [
        ("FK 6R", fk, val("FK 6R: pinocchio"), val("FK 6R: naive")),
        ("FK+Jacobian 6R", val("FK+Jacobian 6R: hyperstat"), val("FK+Jacobian 6R: pinocchio"),
         val("FK+Jacobian 6R: naive")),
    ]
    lines += ["| quantity | hyperstat batched (configs/s) | / pinocchio per call | / naive numpy loop |",
              "|---|---|---|---|"]
    for label, ours, pin, naive in pairs:
        if ours is None:
            continue
        r_pin = f"{ours / pin:.1f}x" if pin else "n/a"
        r_naive = f"{ours / naive:.0f}x" if naive else "n/a"
        lines.append(f"| {label} | {ours:.4g} | {r_pin} | {r_naive} |")
    peers = [(label, val(prefix)) for label, prefix in (
        ("pinocchio, one call per configuration", "FK 6R: pinocchio"),
        ("JAX jit + vmap (float64)", "FK 6R: JAX"),
        ("numba compiled loop, all cores (compiled reference)", "FK 6R: numba"),
        ("naive numpy loop per configuration", "FK 6R: naive"))]
    if fk and any(v for _, v in peers):
        lines += ["", "| FK 6R, 100,000 configurations | configs/s | hyperstat batched relative to it |", "|---|---|---|",
                  f"| hyperstat batched (Kinematics.forward), all cores | {fk:.4g} | 1 |"]
        for label, v in peers:
            if v:
                rel = fk / v
                lines.append(f"| {label} | {v:.4g} | " + (f"{rel:.2g}x faster |" if rel >= 1 else f"{1 / rel:.2g}x slower |"))
        checks = [f"{n[:-6]} {_ARM[n]:.1e}" for n in ("numba_fk_check", "jax_fk_check") if n in _ARM]
        if checks:
            lines.append(f"\nPeers checked against hyperstat's poses before timing (largest difference, mm / rad, "
                         f"1000 configurations): {', '.join(checks)}.")
    generic = val("FK 6R: hyperstat element-by-element")
    if fk and generic:
        lines.append(f"\nBatched path vs the element-by-element path it replaces: {fk / generic:.1f}x.")
    peak = val("numpy matmul")
    if peak and fk and "mech" in _ARM:
        flops = _ARM["kin"].plan(_ARM["xi"]).flops_per_configuration()
        limit = peak * 1e9 / flops["flops"]
        lines.append(
            f"\nArithmetic limit: the 6R forward kinematics costs {flops['flops']} floating-point operations per "
            f"configuration (+ {flops['trig_pairs']} cos/sin pairs, not counted); at the measured peak of "
            f"{peak:.1f} GFLOP/s (numpy matmul, all cores) the limit is {limit:.3g} configs/s. Batched FK reaches "
            f"{fk:.3g} configs/s on all cores: {limit / fk:.1f}x below the limit"
            + (f" ({limit / fk1:.1f}x on one thread)." if fk1 else "."))
        trig = val("trig only: tan(q/2)")
        if trig:  # the transcendental functions are part of the work: the limit counted with them
            with_trig = 1.0 / (1.0 / limit + 1.0 / trig)
            lines.append(
                f"\nLimit counted with the transcendental functions: the kernel's {flops['trig_pairs']} half-angle "
                f"tangents alone run at {trig:.3g} configs/s, so arithmetic plus tangents allow {with_trig:.3g} "
                f"configs/s: batched FK is {with_trig / fk:.1f}x below that limit"
                + (f" ({with_trig / fk1:.1f}x on one thread)." if fk1 else "."))
            sincos = val("trig only: sin and cos")
            if sincos:
                lines.append(f"A kernel that takes sin and cos of the 6 joints (as the peers do) pays {1e9 / sincos:.0f} "
                             f"ns per configuration for them alone ({sincos:.3g} configs/s), "
                             f"{fk / sincos:.2f}x the time of the whole batched FK.")
    if "pin_check" in _ARM:
        lines.append(f"\nPoses and Jacobians of pinocchio and hyperstat agree to {_ARM['pin_check']:.1e} "
                     f"(mm, rad; 1000 configurations) before timing.")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--only", help="substring of the benchmarks to run")
    parser.add_argument("--markdown", help="also write the table as Markdown")
    args = parser.parse_args()
    names = [n for n in BENCHES if not args.only or args.only in n]
    load0 = os.getloadavg()
    rows = run(names, args.repeat)
    load1 = os.getloadavg()
    lines = summary(rows)
    machine = (f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, Python "
               f"{platform.python_version()}, numpy {importlib.import_module('numpy').__version__}; load average "
               f"{load0[0]:.2f} at start, {load1[0]:.2f} at end")
    print()
    print("\n".join(lines))
    print(f"\n{machine}")
    if args.markdown:
        out = ["| benchmark | median | unit | peak memory (MiB) |", "|---|---|---|---|"]
        for n, (v, u, m, note) in rows.items():
            out.append(f"| {n} | {note} | | |" if v is None else f"| {n} | {v:.4g} | {u} | {m:.1f} |")
        out += [""] + lines + ["", f"Machine: {machine}.", "",
                               f"Command: `{' '.join([Path(sys.executable).name, 'benchmarks/run.py'] + sys.argv[1:])}`"]
        from hyperstat.solver.atomic import write_text

        write_text(args.markdown, "\n".join(out) + "\n")


if __name__ == "__main__":
    main()
