"""The ``hyperstat`` command line (solver side: model files only).

Units: lengths in mm, angles in rad.

``solver`` knows model files (``*.json``).  The CAD side (:mod:`hyperstat.cad_plugin.cli`)
registers more source kinds (templates ``*.py``, STEP files) and commands
(``build``, ``view``) and is what the ``hyperstat`` console script runs, so that the
solver never imports CAD code.  Every user error is one sentence on stderr and exit
code 2; outputs are written atomically.
"""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from pathlib import Path
from typing import Any, Callable

from hyperstat.solver.atomic import write_json
from hyperstat.solver.errors import HyperstatError
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.solver.kinematics.modelfile import load_model

__all__ = ["register_source", "register_plotter", "register_name_resolver", "load_source", "loaded_source", "jsonable",
           "analysis_of", "common_options", "PLOTTERS", "Stages", "stages", "gate_calibration", "force_option"]

# suffix -> loader(path, overrides) -> (Mechanism, provenance dict)
_SOURCES: dict[str, Callable[[Path, list[str]], tuple[Mechanism, dict]]] = {}
COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {}
PLOTTERS: dict[str, Callable] = {}  # kind -> plotting function, registered by the presentation side


def register_plotter(kind: str, function: Callable) -> None:
    """Let commands write plots of ``kind`` (e.g. ``"diagnosis"``) through ``function``."""
    PLOTTERS[kind] = function


def register_source(suffix: str, loader: Callable[[Path, list[str]], tuple[Mechanism, dict]]) -> None:
    """Let ``hyperstat`` read sources with ``suffix`` (e.g. ``".py"``) through ``loader``."""
    _SOURCES[suffix.lower()] = loader


def _load_json_model(path: Path, overrides: list[str]) -> tuple[Mechanism, dict]:
    if overrides:
        raise HyperstatError(f"{path}: parameter overrides (-p) apply to templates, not to model files.")
    return load_model(path), {"source": str(path), "kind": "model"}


register_source(".json", _load_json_model)


_NAMES: list[Callable[[str], Path]] = []  # bundled-name resolvers, registered by the CAD side (template names)


def register_name_resolver(resolver: Callable[[str], Path]) -> None:
    """Let a source given as a bare name (``tripteor_x7``, no suffix, no such file) resolve through ``resolver``."""
    _NAMES.append(resolver)


def load_source(path: str | Path, overrides: list[str] | None = None) -> tuple[Mechanism, dict]:
    """Mechanism from a model file, or a template / STEP file when the CAD side is loaded.

    A bare name that is no file (``tripteor_x7``) is a bundled template's, when the CAD side is loaded.
    """
    path = Path(path)
    if not path.suffix and not path.exists() and _NAMES:
        path = _NAMES[0](str(path))
    loader = _SOURCES.get(path.suffix.lower())
    if loader is None:
        known = ", ".join(sorted(_SOURCES))
        raise HyperstatError(f"{path}: unknown source kind '{path.suffix}'; hyperstat reads {known}.")
    if not path.exists():
        raise HyperstatError(f"{path}: no such file.")
    return loader(path, list(overrides or []))


def jsonable(obj: Any) -> Any:
    """Plain JSON types: numpy scalars to Python, infinities and NaN to ``None``."""
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def loaded_source(args: argparse.Namespace) -> tuple[Mechanism, dict]:
    """:func:`load_source` of ``args.source`` and ``args.param``, loaded once per command (kept on ``args``)."""
    loaded = getattr(args, "_loaded_source", None)
    if loaded is None:
        loaded = args._loaded_source = load_source(args.source, args.param)
    return loaded


def analysis_of(args: argparse.Namespace) -> tuple:
    """Load the source of ``args`` and run the stationarity analysis: (mechanism, provenance, kinematics, result)."""
    from hyperstat.solver.kinematics.closure import Kinematics
    from hyperstat.solver.analysis.stationarity import analyze

    mech, provenance = loaded_source(args)
    kin = Kinematics(mech)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = analyze(mech, n_configurations=args.configurations, seed=args.seed, kinematics=kin)
    return mech, provenance, kin, result


def gate_calibration(res: Any, args: argparse.Namespace) -> list[str]:
    """Refuse to export a calibration ``identify`` made a refusing finding about, unless ``--force``.

    Every finding is passed on: the notes (refusing nothing) on stderr; with ``--force`` the
    reasons too, and they are returned so that the written file records them.

    Returns
    -------
    list of str
        The reasons the export goes on despite (empty without ``--force`` or without reasons).

    Raises
    ------
    HyperstatError
        One sentence naming the output and the reasons.
    """
    from hyperstat.solver.export.calibration_gate import export_notes, export_refusal, refusals

    quiet = getattr(args, "quiet", False)
    why = export_refusal(res)
    if why is not None and not getattr(args, "force", False):
        raise HyperstatError(f"{args.out}: not written: {why}; check the inputs, or write it anyway with --force "
                             f"(the reasons are then recorded in the file).")
    if not quiet:
        for note in export_notes(res):
            sys.stderr.write(f"hyperstat: note: {args.out}: {note}\n")
    if why is None:
        return []
    sys.stderr.write(f"hyperstat: warning: {args.out} written with --force although {why}.\n")
    return refusals(res)


def force_option(p: argparse.ArgumentParser) -> None:
    """``--force`` (export a calibration identify made a refusing finding about) and ``--exclude-outliers``."""
    p.add_argument("--force", action="store_true",
                   help="write even a calibration identify calls untrustworthy (absurd, missing an effect, worse than "
                        "the nominal model on held-out poses, too few equations, outliers, ...: refused by default); "
                        "the reasons are recorded in the file")
    p.add_argument("--exclude-outliers", action="store_true",
                   help="refit without the observations the outlier test flags (named by pose and target), one at a "
                        "time; they are never removed otherwise")


def common_options(p: argparse.ArgumentParser) -> None:
    """Options shared by most commands: -p, --configurations, --seed, --json, --quiet."""
    p.add_argument("-p", "--param", action="append", metavar="NAME=VALUE", help="template parameter override")
    p.add_argument("--configurations", type=int, default=24, help="configurations sampled (default 24)")
    p.add_argument("--seed", type=int, default=0, help="seed of the configuration sample")
    p.add_argument("--json", metavar="OUT", help="write the result as JSON")
    p.add_argument("--quiet", action="store_true", help="print nothing")


class Stages:
    """Progress of a command over its named stages: a tqdm bar on stderr, nothing with ``--quiet``.

    The bar is drawn only when stderr is a terminal, and erased when the command ends (an
    error message then stands alone); logs and pipes get no control characters.

    >>> with Stages(["analysis", "identification"], quiet=True) as stages:
    ...     stages.next("analysis")
    ...     stages.next("identification")
    """

    def __init__(self, names: list[str], quiet: bool, description: str = "hyperstat") -> None:
        self.names = list(names)
        self.bar = None
        self._started = False
        if not quiet and sys.stderr.isatty():  # a bar is for a person at a terminal, not for logs and pipes
            from tqdm import tqdm

            import os
            import shutil

            try:
                size = os.get_terminal_size(sys.stderr.fileno())
            except OSError:
                size = os.terminal_size((0, 0))
            fallback = shutil.get_terminal_size((80, 24))  # a terminal that reports no size (0 x 0)
            self.bar = tqdm(total=len(self.names), desc=description, unit="stage", file=sys.stderr, leave=False,
                            bar_format="{desc}: {n_fmt}/{total_fmt} {bar} {elapsed} {postfix}",
                            ncols=size.columns or fallback.columns, nrows=size.lines or fallback.lines)

    def next(self, name: str) -> None:
        """Finish the stage under way and start ``name``."""
        if self.bar is None:
            return
        if self._started:
            self.bar.update(1)
        self._started = True
        self.bar.set_postfix_str(name)

    def __enter__(self) -> "Stages":
        return self

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            if self._started and exc[0] is None:
                self.bar.update(1)
            self.bar.close()


def stages(args: argparse.Namespace, names: list[str]) -> Stages:
    """:class:`Stages` for a command's ``args`` (silent with ``--quiet``), labelled by the command."""
    return Stages(names, quiet=bool(getattr(args, "quiet", False)), description=getattr(args, "command", "hyperstat"))
