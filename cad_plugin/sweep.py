"""Design sweeps: the stationarity analysis over a grid of template parameters.

Units: template parameters in their declared units (mm, rad); times in s.

``hyperstat sweep TEMPLATE --grid NAME=LOW:HIGH:COUNT ...`` builds every variant of the
Cartesian product of the grids, analyses it (paper 1, eq. 3, automated: forced /
coupled / free defects, rank, singular-value gap, mobility, over-constraint) and writes
one CSV table, one row per variant, written atomically.  A variant that fails to build,
assemble or analyse gets its error sentence in the ``error`` column instead of stopping
the sweep.  Variants run one after the other by default, or as tasks on a Dask cluster
(``--scheduler tcp://HOST:PORT``): every worker must see the template file at the same
path and have hyperstat installed.  Each variant is analysed with the same seed, so a
serial and a distributed run give the same table (up to the ``time_s`` column).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import itertools
import math
import re
import sys
import time
import warnings
from pathlib import Path
from typing import Any

from hyperstat.solver.atomic import write_text
from hyperstat.solver.errors import HyperstatError

from hyperstat.cad_plugin.params import parse_value
from hyperstat.cad_plugin.templates import load_template, template_parameters

__all__ = ["parse_grid", "grid_variants", "analyze_variant", "run_sweep", "sweep_template", "write_table",
           "RESULT_COLUMNS"]

#: Result columns after the parameters (counts of defect parameters per verdict, etc.)
RESULT_COLUMNS = [
    "n_parameters", "gauge", "forced", "coupled", "free", "free_influential", "free_non_influent",
    "rank", "gap", "mobility", "overconstraint", "configurations", "time_s", "error",
]

_GRID = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*([^:]+):([^:]+):\s*([^:]+?)\s*$")


def parse_grid(specs: list[str], parameters_cls: type) -> dict[str, list[float]]:
    """``["L1=30:50:3", "home_angle=10deg:40deg:4"]`` -> ``{"L1": [30, 40, 50], ...}``.

    ``LOW`` and ``HIGH`` take the units the command line accepts for the parameter
    (``40``, ``4cm``, ``30deg``); ``COUNT`` values are spaced evenly, ends included.

    Raises
    ------
    HyperstatError
        On a malformed item, an unknown parameter, a bad number or a parameter given twice.
    """
    fields = {f.name: f for f in dataclasses.fields(parameters_cls)}
    grid: dict[str, list[float]] = {}
    for item in specs:
        m = _GRID.match(item)
        if not m:
            raise HyperstatError(f"--grid '{item}' must read NAME=LOW:HIGH:COUNT (e.g. L1=30:50:5).")
        name, lo_text, hi_text, n_text = m.groups()
        if name not in fields:
            valid = ", ".join(f"{n} [{f.metadata.get('unit', '1')}]" for n, f in fields.items())
            raise HyperstatError(f"--grid '{item}': unknown parameter '{name}'; valid parameters: {valid}.")
        if name in grid:
            raise HyperstatError(f"--grid names parameter '{name}' twice.")
        unit = fields[name].metadata.get("unit", "1")
        lo = parse_value(lo_text, unit, name)
        hi = parse_value(hi_text, unit, name)
        try:
            n = int(n_text)
        except ValueError:
            raise HyperstatError(f"--grid '{item}': COUNT must be a whole number, got '{n_text}'.") from None
        if n < 1 or (n == 1 and lo != hi):
            raise HyperstatError(f"--grid '{item}': COUNT must be at least 2 (or 1 with LOW = HIGH), got {n}.")
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise HyperstatError(f"--grid '{item}': LOW and HIGH must be finite.")
        grid[name] = [lo] if n == 1 else [lo + (hi - lo) * i / (n - 1) for i in range(n)]
    return grid


def grid_variants(grid: dict[str, list[float]], fixed: dict[str, float] | None = None) -> list[dict[str, float]]:
    """Every combination of the grid values (last parameter fastest), with ``fixed`` overrides added."""
    names = list(grid)
    out = []
    for values in itertools.product(*(grid[n] for n in names)):
        variant = dict(fixed or {})
        variant.update(zip(names, values))
        out.append(variant)
    return out


def _montecarlo_columns(mech, analysis, samples: int, angle_tol: float, length_tol: float) -> dict:
    """Monte Carlo summary of one variant (hook into :mod:`hyperstat.solver.tolerances.montecarlo`, built separately)."""
    from hyperstat.solver.tolerances.montecarlo import monte_carlo

    tolerances = {p.name: angle_tol if p.unit == "rad" else length_tol for p in mech.parameters}
    result = monte_carlo(mech, analysis.configurations, tolerances, samples=samples, analysis=analysis)
    s = result.summary()
    return {
        "mc_orientation_p95_rad": s["orientation_rad"]["p95"],
        "mc_orientation_max_rad": s["orientation_rad"]["max"],
        "mc_position_p95_mm": s["position_mm"]["p95"],
        "mc_position_max_mm": s["position_mm"]["max"],
        "mc_not_assembled": s["not_assembled"],
    }


def analyze_variant(
    template: str,
    overrides: dict[str, float],
    configurations: int = 24,
    seed: int = 0,
    montecarlo: dict | None = None,
) -> dict[str, Any]:
    """Build one variant of ``template`` and analyse it; never raises for a bad variant.

    Parameters
    ----------
    template : str
        Path of the template file.
    overrides : dict
        Parameter values (template units, mm / rad).
    configurations, seed : int
        Sample of the stationarity analysis.
    montecarlo : dict, optional
        ``{"samples": N, "angle_tolerance": rad, "length_tolerance": mm}`` to add Monte
        Carlo columns (needs :mod:`hyperstat.solver.tolerances.montecarlo`).

    Returns
    -------
    dict
        The row: the result columns; ``error`` holds one sentence when the variant failed
        (its other results are then empty).
    """
    from hyperstat.solver import Kinematics, analyze

    from hyperstat.cad_plugin.templates import build_template

    t0 = time.perf_counter()
    row: dict[str, Any] = {}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mech = build_template(template, dict(overrides)).mechanism()
            kin = Kinematics(mech)
            result = analyze(mech, n_configurations=configurations, seed=seed, kinematics=kin)
            counts = result.counts()
            row.update(
                n_parameters=counts["total"], gauge=counts["gauge"], forced=counts["forced"],
                coupled=counts["coupled"], free=counts["free"], free_influential=counts["free_influential"],
                free_non_influent=counts["free_non_influent"], rank=result.rank, gap=result.gap,
                mobility=result.mobility, overconstraint=result.overconstraint,
                configurations=result.n_configurations,
            )
            if montecarlo is not None:
                row.update(_montecarlo_columns(mech, result, montecarlo["samples"], montecarlo["angle_tolerance"],
                                               montecarlo["length_tolerance"]))
        row["error"] = ""
    except HyperstatError as exc:
        row = {"error": str(exc)}
    except Exception as exc:  # noqa: BLE001 - one bad variant must not stop a sweep
        row = {"error": f"{exc.__class__.__name__}: {exc}"}
    row["time_s"] = time.perf_counter() - t0
    return row


def run_sweep(
    template: str | Path,
    variants: list[dict[str, float]],
    configurations: int = 24,
    seed: int = 0,
    montecarlo: dict | None = None,
    scheduler: str | None = None,
    progress: bool = True,
    client: Any = None,
) -> list[dict[str, Any]]:
    """Analyse every variant, serially or on a Dask cluster; rows in variant order.

    Parameters
    ----------
    template : str or Path
        Template file (the same path must exist on every Dask worker).
    variants : list of dict
        Parameter values per variant (template units).
    configurations, seed : int
        Sample of each stationarity analysis (the same for every variant).
    montecarlo : dict, optional
        See :func:`analyze_variant`.
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:8786``); serial when omitted.
    progress : bool
        Show a progress bar on stderr.
    client : distributed.Client, optional
        An existing Dask client (instead of ``scheduler``).

    Returns
    -------
    list of dict
        One row per variant: ``variant`` index, the parameters, then :data:`RESULT_COLUMNS`.

    Raises
    ------
    HyperstatError
        If the scheduler cannot be reached.
    """
    from tqdm import tqdm

    path = str(Path(template).resolve())
    rows: list[dict | None] = [None] * len(variants)
    bar = tqdm(total=len(variants), desc="sweep", unit="variant", file=sys.stderr, disable=not progress)
    try:
        if scheduler is None and client is None:
            for i, v in enumerate(variants):
                rows[i] = analyze_variant(path, v, configurations, seed, montecarlo)
                bar.update(1)
        else:
            own = client is None
            if own:
                client = _connect(scheduler)
            try:
                from distributed import as_completed

                futures = client.map(analyze_variant, [path] * len(variants), variants,
                                     [configurations] * len(variants), [seed] * len(variants),
                                     [montecarlo] * len(variants), pure=False)
                index = {f.key: i for i, f in enumerate(futures)}
                for fut in as_completed(futures):
                    rows[index[fut.key]] = fut.result()
                    bar.update(1)
            finally:
                if own:
                    client.close()
    finally:
        bar.close()
    return [{"variant": i, **variants[i], **rows[i]} for i in range(len(variants))]


def _connect(address: str):
    from distributed import Client

    try:
        return Client(address, timeout="5s")
    except (OSError, TimeoutError) as exc:
        raise HyperstatError(f"--scheduler '{address}': cannot reach the Dask scheduler ({exc.__class__.__name__}).") \
            from None


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return repr(value)  # full precision: a serial and a distributed table compare exactly
    return "" if value is None else str(value)


def write_table(path: str | Path, rows: list[dict[str, Any]], parameter_units: dict[str, str]) -> Path:
    """Write the sweep table as CSV atomically.

    Parameter columns are headed ``NAME_UNIT`` (``L1_mm``, ``home_angle_rad``); the other
    columns are :data:`RESULT_COLUMNS` (plus the Monte Carlo columns when present).
    """
    params = list(parameter_units)
    extra = sorted({k for r in rows for k in r if k.startswith("mc_")})
    columns = ["variant"] + params + RESULT_COLUMNS[:-2] + extra + RESULT_COLUMNS[-2:]
    header = ["variant"] + [f"{p}_{parameter_units[p]}" if parameter_units[p] != "1" else p for p in params] \
        + columns[1 + len(params):]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    for r in rows:
        writer.writerow([_cell(r.get(c)) for c in columns])
    return write_text(path, buf.getvalue())


def sweep_template(
    template: str | Path,
    grid_specs: list[str],
    fixed: list[str] | None = None,
    **kwargs: Any,
) -> tuple[list[dict[str, Any]], dict[str, str]]:
    """Parse grids and fixed overrides for ``template``, run the sweep; rows and parameter units."""
    from hyperstat.cad_plugin.params import parse_overrides

    module = load_template(template)
    cls = template_parameters(module)
    grid = parse_grid(grid_specs, cls)
    fixed_values = parse_overrides(fixed, cls)
    both = sorted(set(grid) & set(fixed_values))
    if both:
        raise HyperstatError(f"parameter '{both[0]}' is given both as --grid and as -p.")
    units = {f.name: f.metadata.get("unit", "1") for f in dataclasses.fields(cls)}
    names = list(fixed_values) + list(grid)
    rows = run_sweep(template, grid_variants(grid, fixed_values), **kwargs)
    return rows, {n: units[n] for n in names}

