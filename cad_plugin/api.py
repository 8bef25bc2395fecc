"""The public API for notebooks and scripts, re-exported as ``import hyperstat as hs``.

Units: lengths in mm, angles in rad.

One function per pipeline stage, each taking what the stage before returned:

>>> import hyperstat as hs
>>> mech = hs.load("slider_crank")                      # a bundled template, by name
>>> result = hs.analyze(mech)
>>> result.counts()["forced"], result.rank
(6, 6)

The command line (``hyperstat analyze ...``) runs the same functions.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hyperstat.solver.analysis.stationarity import StationarityResult
from hyperstat.solver.errors import HyperstatError
from hyperstat.solver.kinematics.closure import Kinematics
from hyperstat.solver.kinematics.model import Mechanism
from hyperstat.cad_plugin.templates import template_path

if TYPE_CHECKING:  # imported where used: the identification and the diagnosis pull in scipy's optimisers
    from hyperstat.solver.calibration.identify import IdentificationResult
    from hyperstat.solver.calibration.measurements import MeasurementSet
    from hyperstat.solver.diagnosis.diagnose import Diagnosis

__all__ = ["load", "analyze", "accuracy", "identify", "diagnose", "report", "template_path"]


def load(source: str | Path, **parameters: Any) -> Mechanism:
    """The mechanism of a template, a model file or a STEP file (with its sidecar).

    Parameters
    ----------
    source : str or Path
        A bundled template's name (``"tripteor_x7"``), a template file (``*.py``, run as
        code: only templates you trust), a model file (``*.json``) or a STEP file
        (``*.step`` with ``*.step.json`` beside it).
    **parameters
        Template parameter overrides in the template's units (mm, rad), e.g. ``L1=50``.

    Returns
    -------
    Mechanism
        The joint-invariant model (paper 1, section 2, eq. (2)).

    Examples
    --------
    >>> import hyperstat as hs
    >>> mech = hs.load("slider_crank", L1=50.0)
    >>> mech.name, len(mech.parameters)
    ('slider_crank', 15)
    """
    from hyperstat.cad_plugin import cli  # registers the template and STEP readers

    overrides = [f"{k}={v}" for k, v in parameters.items()]
    mech, _ = cli.solver_cli.load_source(template_path(str(source)), overrides)
    return mech


def analyze(mechanism: Mechanism, configurations: int = 24, seed: int = 0, samples: int = 2) -> StationarityResult:
    """Stationarity analysis: which defects are forced, coupled, free (paper 1, sections 3-4).

    As on the command line (``hyperstat analyze``, ``--samples``), the analysis is repeated on
    ``samples`` independent samples (seeds ``seed``, ``seed + 1``, ...) and compared: rank,
    admissible dimension, mobility, every verdict and the admissible subspace
    (:func:`hyperstat.solver.analysis.stationarity.compare_samples`).  The verdicts are the first
    sample's; ``result.stability["summary"]`` says "stable across 2 independent samples" or names
    every disagreement, and a disagreement is also raised as a :class:`UserWarning` (where the
    command line exits with status 3), so that the answer never depends silently on the seed.

    Parameters
    ----------
    mechanism : Mechanism
        From :func:`load`.
    configurations : int
        Actuated configurations sampled over the workspace, per sample.
    seed : int
        Seed of the first sample.
    samples : int
        Independent samples analysed and compared (default 2, as the command line; more for a
        stronger check; 1 skips the check and leaves ``result.stability`` at ``None``).

    Returns
    -------
    StationarityResult
        A verdict per defect parameter, the relations between coupled ones, the rank of
        the stacked constraint (eq. (11)) with its singular-value gap, and ``stability``.

    Raises
    ------
    HyperstatError
        If ``samples`` is not an integer of at least 1.

    Examples
    --------
    >>> import hyperstat as hs
    >>> result = hs.analyze(hs.load("slider_crank"))
    >>> result.verdict_of("dI2").verdict
    'forced'
    >>> result.gap > 1e6
    True
    >>> result.stability["stable"], result.stability["samples"]
    (True, 2)
    >>> result.stability["summary"].startswith("stable across 2 independent samples")
    True
    >>> hs.analyze(hs.load("slider_crank"), samples=3).stability["seeds"]
    [0, 1, 2]
    """
    from hyperstat.solver.analysis.stationarity import analyze as _analyze

    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise HyperstatError(f"analyze: samples must be an integer of at least 1, got {samples!r}.")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = _analyze(mechanism, n_configurations=configurations, seed=seed, kinematics=Kinematics(mechanism),
                          samples=samples)
    if result.stability is not None and not result.stability["stable"]:
        warnings.warn(f"the analysis of '{mechanism.name}' depends on the sample: "
                      f"{'; '.join(result.stability['disagreements'])}.", UserWarning, stacklevel=2)
    return result


def accuracy(mechanism: Mechanism, analysis: StationarityResult | None = None, configurations: int = 2000,
             seed: int = 0, ranges: dict | None = None, orientation_accuracy: float | None = None,
             position_accuracy: float | None = None) -> dict:
    """Accuracy coefficients over the workspace and the tolerance allocation (paper 2).

    Parameters
    ----------
    mechanism : Mechanism
        From :func:`load`.
    analysis : StationarityResult, optional
        From :func:`analyze`; for an over-constrained mechanism only its admissible
        influential defects are geometric errors (the forced ones are assembly conditions).
    configurations : int
        Configurations sampled over the actuated ranges.
    ranges : dict, optional
        ``{actuated joint: (low, high)}`` in mm or rad.
    orientation_accuracy, position_accuracy : float, optional
        Required ``|dphi|max`` (rad) and ``||dO_p||max`` (mm) for the allocation
        (eqs. 19, 30-31).

    Returns
    -------
    dict
        ``coefficients`` (min / max / mean of each coefficient, eqs. 16-18),
        ``allocation`` (tolerance per class), ``configurations`` (how many assembled).

    Examples
    --------
    >>> import hyperstat as hs
    >>> mech = hs.load("slider_crank")
    >>> acc = hs.accuracy(mech, hs.analyze(mech), configurations=50, position_accuracy=0.01)
    >>> acc["configurations"], acc["coefficients"]["epsilon_gP"]["max"] > 0
    (50, True)
    """
    from hyperstat.solver.tolerances.accuracy import accuracy_maps, allocate, sample_workspace

    kin = Kinematics(mechanism)
    analysis = analysis if analysis is not None else analyze(mechanism)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        q = sample_workspace(mechanism, configurations, seed=seed, ranges=ranges, kinematics=kin)
    if len(q) == 0:
        raise HyperstatError(f"no configuration of '{mechanism.name}' assembles in the actuated ranges.")
    over = analysis.overconstraint > 0
    maps = accuracy_maps(mechanism, q, analysis if over else None, kinematics=kin)
    return {"configurations": int(len(q)), "coefficients": maps.summary(), "coefficient_units": maps.units,
            "allocation": allocate(maps, orientation_accuracy, position_accuracy), "maps": maps}


def _measurements(data: MeasurementSet | str | Path | None, mechanism: Mechanism) -> MeasurementSet | None:
    from hyperstat.solver.calibration.measurements import MeasurementSet, read_measurements

    if data is None or isinstance(data, MeasurementSet):
        return data
    return read_measurements(data, mechanism)


def identify(mechanism: Mechanism, data: MeasurementSet | str | Path,
             validation: MeasurementSet | str | Path | None = None,
             analysis: StationarityResult | None = None) -> IdentificationResult:
    """Identify the influential admissible defects, the tracker frame and the target (paper 1, eq. (10)).

    Parameters
    ----------
    mechanism : Mechanism
        From :func:`load`.
    data, validation : MeasurementSet or path
        Identification measurements and, optionally, validation points never fitted
        (CSV, see ``docs/identification.md``).
    analysis : StationarityResult, optional
        From :func:`analyze` (computed when omitted).

    Returns
    -------
    IdentificationResult
        Estimates with standard deviations, rank, condition number, residuals in mm.

    Examples
    --------
    >>> import hyperstat as hs
    >>> from hyperstat.solver.calibration.virtual import VirtualMachine
    >>> mech = hs.load("slider_crank")
    >>> result = hs.analyze(mech)
    >>> machine = VirtualMachine.random(mech, result, seed=1)
    >>> fit = hs.identify(mech, machine.measure(machine.poses(20, seed=2), seed=3), analysis=result)
    >>> fit.rank <= fit.n_unknowns, fit.identification["rms"] < 0.05   # mm: at the tracker's noise
    (True, True)
    """
    from hyperstat.solver.calibration.identify import identify as _identify

    analysis = analysis if analysis is not None else analyze(mechanism)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _identify(mechanism, analysis, _measurements(data, mechanism), _measurements(validation, mechanism))


def diagnose(mechanism: Mechanism, data: MeasurementSet | str | Path,
             validation: MeasurementSet | str | Path | None = None,
             analysis: StationarityResult | None = None) -> Diagnosis:
    """Diagnose the sim-to-real gap the identified rigid model leaves: is there one, where, which effect.

    Parameters
    ----------
    mechanism : Mechanism
        From :func:`load`.
    data, validation : MeasurementSet or path
        Measurements with a stated noise model; validation points are never fitted.
    analysis : StationarityResult, optional
        From :func:`analyze` (computed when omitted).

    Returns
    -------
    Diagnosis
        The gap test, where the residual lies, the candidate effects ranked by
        cross-validation, and how far the selected ones shrink the validation error.

    Examples
    --------
    >>> import hyperstat as hs
    >>> from hyperstat.solver.calibration.virtual import VirtualMachine
    >>> mech = hs.load("slider_crank")
    >>> result = hs.analyze(mech)
    >>> machine = VirtualMachine.random(mech, result, seed=1)
    >>> data = machine.measure(machine.poses(40, seed=2), seed=3)
    >>> diag = hs.diagnose(mech, data, analysis=result)   # a rigid machine: noise only
    >>> diag.gap_significant
    False
    """
    from hyperstat.solver.diagnosis.diagnose import diagnose as _diagnose

    analysis = analysis if analysis is not None else analyze(mechanism)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _diagnose(mechanism, analysis, _measurements(data, mechanism), _measurements(validation, mechanism),
                         kinematics=Kinematics(mechanism))


def report(source: str | Path, out: str | Path, data: str | Path | None = None,
           validation: str | Path | None = None, **parameters: Any) -> list[Path]:
    """Write the tolerance report (``report.html``, ``report.md``, ``report.json``) into ``out``.

    Parameters
    ----------
    source : str or Path
        As for :func:`load` (a bundled template's name, a template, model or STEP file).
    out : str or Path
        Output directory (created).
    data, validation : path, optional
        Measurement files: the report then has calibration and sim-to-real sections.
    **parameters
        Template parameter overrides (mm, rad).

    Returns
    -------
    list of Path
        The files written (atomically).

    Examples
    --------
    >>> import hyperstat as hs, tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp())
    >>> sorted(p.name for p in hs.report("slider_crank", out))
    ['report.html', 'report.json', 'report.md']
    """
    from hyperstat.cad_plugin import cli

    argv = ["report", str(template_path(str(source))), "--out", str(out), "--quiet"]
    argv += [a for k, v in parameters.items() for a in ("-p", f"{k}={v}")]
    if data is not None:
        argv += ["--data", str(data)]
    if validation is not None:
        argv += ["--validation", str(validation)]
    if cli.main(argv) != 0:
        raise HyperstatError(f"the report of {source} could not be written (see the message above).")
    return [Path(out) / name for name in ("report.html", "report.md", "report.json")]

