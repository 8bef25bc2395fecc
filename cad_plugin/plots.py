"""Residual plots of a diagnosis (PNG or SVG, matplotlib with the Agg backend; residuals in µm, joints in mm / rad).

Plotting lives on the CAD / presentation side: ``solver`` stays numpy / scipy / sympy only
and reaches these through :func:`hyperstat.solver.cli.register_plotter`.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from hyperstat.solver.atomic import all_or_nothing, write_bytes

__all__ = ["write_diagnosis_plots", "diagnosis_figures", "revolute_spectra_figure", "answered_frequency"]


#: the figures are drawn at the size they print on A4 (the text width, 186 mm), with 8 pt type
A4_WIDTH_IN = 186.0 / 25.4
PRINT_STYLE = {"font.size": 8.0, "axes.titlesize": 8.5, "axes.labelsize": 8.0, "xtick.labelsize": 7.5,
               "ytick.labelsize": 7.5, "legend.fontsize": 7.5, "figure.titlesize": 9.0, "font.family": "DejaVu Sans"}


def diagnosis_figures(diag, data, fmt: str = "png") -> dict:
    """Figures by file name (``fmt``: ``"png"`` bytes, or ``"svg"`` text with the type kept as text), drawn at
    their printed size on A4: residuals against each actuated joint, per region, spectra, before/after."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with matplotlib.rc_context(PRINT_STYLE):
        figures = _diagnosis_figures(diag, data, plt)
    out = {}
    for name, fig in figures.items():
        out[f"{name}.{fmt}"] = _save(fig, fmt)
        plt.close(fig)
    return out


def _save(fig, fmt: str):
    from hyperstat.cad_plugin.drawing import figure_png, figure_svg

    return figure_svg(fig) if fmt == "svg" else figure_png(fig, int(150 * fig.get_figwidth()))


def _diagnosis_figures(diag, data, plt) -> dict:
    out = {}
    um = 1000.0
    resid = diag.rigid.residuals
    norm = np.linalg.norm(resid, axis=1) * um
    n_act = data.q.shape[1]
    cols = min(n_act, 3)
    rows = -(-n_act // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(A4_WIDTH_IN, 2.1 * rows + 0.4), squeeze=False)
    for a in range(rows * cols):
        ax = axes[a // cols, a % cols]
        if a >= n_act:
            ax.set_axis_off()
            continue
        ax.scatter(data.q[:, a], norm, s=6)
        ax.set_xlabel(f"joint {data.joints[a]}")
        ax.set_ylabel("|residual| (\u00b5m)" if a % cols == 0 else "")
    fig.suptitle("Rigid-model residuals against the actuated joints (mm or rad)")
    fig.tight_layout()
    out["residuals_vs_joints"] = fig
    fig, ax = plt.subplots(figsize=(A4_WIDTH_IN, 2.4))
    regions = diag.where["regions"]
    ax.bar([f"#{r['region']}" for r in regions], [um * r["rms"] for r in regions])
    if diag.rigid.noise_rms:
        ax.axhline(um * diag.rigid.noise_rms, color="k", ls="--", label="noise RMS")
        ax.legend()
    ax.set_ylabel("RMS residual (\u00b5m)")
    ax.set_title("Residual RMS per workspace region")
    fig.tight_layout()
    out["residuals_by_region"] = fig
    if diag.where["spectra"]:
        fig, ax = plt.subplots(figsize=(A4_WIDTH_IN, 2.4))
        for s in diag.where["spectra"]:
            ax.plot(s["periods_mm"], s["power"], label=f"q{s['joint']}")
        ax.set_xlabel("period along the actuator travel (mm)")
        ax.set_ylabel("share of the residual variance")
        ax.set_title("Periodic error per screw (harmonic regression)")
        ax.legend()
        fig.tight_layout()
        out["spectra"] = fig
    rspectra = diag.where.get("revolute_spectra") or []
    if rspectra:
        out["spectra_revolute"] = revolute_spectra_figure(diag, rspectra, plt)
    if diag.validation_before:
        fig, ax = plt.subplots(figsize=(0.5 * A4_WIDTH_IN, 2.2))
        labels = ["before"] + (["after"] if diag.validation_after else [])
        values = [diag.validation_before] + ([diag.validation_after] if diag.validation_after else [])
        x = np.arange(len(labels))
        for i, key in enumerate(("mean", "rms", "max")):
            ax.bar(x + 0.25 * (i - 1), [um * v[key] for v in values], width=0.25, label=key)
        if diag.rigid.noise_rms:
            ax.axhline(um * diag.rigid.noise_rms, color="k", ls="--", label="noise RMS")
        ax.set_xticks(x, labels)
        ax.set_ylabel("validation error (\u00b5m)")
        ax.legend()
        fig.tight_layout()
        out["before_after"] = fig
    return out


def answered_frequency(diag) -> tuple[str, float] | None:
    """(joint, cycles per revolution) the diagnosis's answer points at, when its 'where' is a revolute frequency."""
    for block in (diag.verdict.get("remaining_structure"), diag.verdict.get("structure")):
        best = (block or {}).get("best") or {}
        if (block or {}).get("structured") and "cycles_per_revolution" in best:
            return str(best["joint"]), float(best["cycles_per_revolution"])
    return None


def revolute_spectra_figure(diag, rspectra: list, plt):
    """One panel per revolute joint: share of the rigid residual variance a harmonic error of that joint
    explains, against its frequency in cycles per revolution (the structure tests' spectrum, F-tested).

    The peak of each joint is marked with its p-value; the frequency the diagnosis's answer names
    ("unexplained" or "partly explained", see :func:`answered_frequency`) is drawn as a red line.
    """
    n = len(rspectra)
    cols = min(n, 3)
    rows = -(-n // cols)
    fig, grid = plt.subplots(rows, cols, figsize=(A4_WIDTH_IN, 2.1 * rows + 0.4), squeeze=False, sharey=True)
    for k in range(n, rows * cols):
        grid[k // cols, k % cols].set_axis_off()
    axes = grid.reshape(1, -1)
    named = answered_frequency(diag)
    for ax, sp in zip(axes[0], rspectra):
        ax.plot(sp["cycles_per_revolution"], sp["share"], marker=".", ms=3)
        ax.plot([sp["peak_cycles_per_revolution"]], [sp["peak_share"]], "o", mfc="none", color="k")
        ax.annotate(f"p = {sp['peak_p_value']:.1g}", (sp["peak_cycles_per_revolution"], sp["peak_share"]),
                    textcoords="offset points", xytext=(4, 4), fontsize=7.5)
        if named is not None and named[0] == str(sp["joint"]):
            ax.axvline(named[1], color="r", lw=1.0, label=f"answer: {named[1]:g} /rev")
            ax.legend(fontsize=7.5)
        ax.set_title(f"joint {sp['joint']}")
        ax.set_xlabel("cycles per revolution")
    for r in range(rows):
        grid[r, 0].set_ylabel("share of the residual variance")
    fig.suptitle(f"Residual spectrum per revolute joint ({diag.outcome})")
    fig.tight_layout()
    return fig


def write_diagnosis_plots(diag, data, directory: str | Path) -> list[Path]:
    """Write the figures of :func:`diagnosis_figures` atomically into ``directory``."""
    directory = Path(directory)
    figures = diagnosis_figures(diag, data)
    with all_or_nothing():  # every figure or none
        return [write_bytes(directory / name, png) for name, png in figures.items()]


def accuracy_map_png(mech, analysis, axes: tuple, slices: list, path, coefficients=("delta_gR", "epsilon_gR"),
                     ranges: dict | None = None, n: int = 61, kinematics=None):
    """Maps of accuracy coefficients over a grid of two actuated joints, one row per slice (PNG).

    Parameters
    ----------
    axes : tuple of str
        The two actuated joints of the grid.
    slices : list of dict
        Values of the other actuated joints for each row (e.g. ``[{"1": 0.0}, {"1": 0.75}]``).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from hyperstat.solver.tolerances.accuracy import accuracy_maps, grid_slice
    from hyperstat.solver.kinematics.closure import Kinematics

    kin = kinematics or Kinematics(mech)
    slices = slices or [{}]
    fig, axs = plt.subplots(len(slices), len(coefficients), figsize=(5.2 * len(coefficients), 4.2 * len(slices)),
                            squeeze=False)
    for r, fixed in enumerate(slices):
        u, v, q = grid_slice(mech, axes, fixed, n, ranges, kin)
        ok = ~np.isnan(q[:, 0])
        maps = accuracy_maps(mech, q[ok], analysis, kinematics=kin)
        for c, name in enumerate(coefficients):
            grid = np.full(len(q), np.nan)
            grid[ok] = maps.coefficients[name]
            ax = axs[r, c]
            img = ax.contourf(u, v, grid.reshape(n, n).T, levels=20, cmap="viridis")
            ax.contour(u, v, grid.reshape(n, n).T, levels=10, colors="k", linewidths=0.4)
            fig.colorbar(img, ax=ax, label=f"{name} [{maps.units[name]}]")
            where = ", ".join(f"q{k} = {val:g}" for k, val in fixed.items()) or "others at home"
            ax.set_title(f"{name}  ({where})")
            ax.set_xlabel(f"q{axes[0]}")
            ax.set_ylabel(f"q{axes[1]}")
            ax.set_aspect("equal", adjustable="box")
    fig.suptitle(f"Accuracy coefficients of {mech.name} (paper 2, eq. 18); blank: no assembly")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)
    return write_bytes(path, buf.getvalue())
