"""Whether a calibration may leave hyperstat: every finding of ``identify`` that makes it untrustworthy stops it.

Units: lengths in mm.

``export-controller``, ``export-urdf`` and ``export-dh`` write what a controller will run. They
refuse, unless ``--force``, a calibration for which ``identify`` made a finding that refuses
(:attr:`~hyperstat.solver.calibration.identify.IdentificationResult.findings`, the same words as
its warnings, worst first):

* **inputs wrong** (``fit_quality``): residuals in the hundreds of times the noise the data state,
  on the fitted or the held-out poses of any target, or beyond 1 % of the machine's size (a wrong
  joint map, wrong units, one target's columns copied from another's, targets stacked in one
  column, a moved tracker);
* **the model misses an effect** (``fit_quality``): residuals more than 3 times the stated noise,
  on the fitted poses or on the held-out poses of any target.  The calibrated model is then not
  what the data say the machine is: a controller running it would be off by several times what
  the measurements resolve.  Export it with the effect (``export-controller --diagnose`` or
  ``--effect``), or with ``--force``, which records why in the file;
* **worse than nominal** on the held-out poses (``--validation``);
* **too few equations** (fewer than 2 per identified parameter, a pose counting at most 6 for the
  machine), **poor conditioning** (condition number above 1e6), a **fragile rank** decision, a fit
  that **did not converge**;
* **targets that coincide**, **poses repeated** within the noise, held-out poses that repeat
  fitted ones, held-out poses that do not assemble;
* **outliers** still in the data (named by pose and target; ``--exclude-outliers`` takes them out).

Findings that refuse nothing (the model size chosen on small data, outliers excluded on request)
are passed on all the same: printed, and recorded in the controller file.  With ``--force`` the
file is written, stderr says why it should not have been, and the reasons are recorded in it
(:func:`calibration_record`; a URDF or DH table carries them in its comment).  This is the one
place the exports ask.

Examples
--------
>>> from types import SimpleNamespace as R
>>> ok = R(findings=[{"code": "model-size", "refuses": False, "message": "small data ...", "reason": None}])
>>> export_refusal(ok) is None, export_notes(ok)
(True, ['small data ...'])
>>> bad = R(findings=[{"code": "worse-than-nominal", "refuses": True, "message": "...",
...                    "reason": "it predicts the held-out poses worse than the nominal model"}])
>>> export_refusal(bad)
'it predicts the held-out poses worse than the nominal model'
"""

from __future__ import annotations

__all__ = ["refusals", "export_refusal", "export_notes", "calibration_record"]


def refusals(identification) -> list[str]:
    """The reasons, in words, why the calibration ``identification`` (an
    :class:`~hyperstat.solver.calibration.identify.IdentificationResult`) must not be exported; empty when it may."""
    return [f["reason"] for f in getattr(identification, "findings", []) or [] if f.get("refuses")]


def export_refusal(identification) -> str | None:
    """The reasons of :func:`refusals` in one clause (joined by ``; and``), or None when the export may go on."""
    return "; and ".join(refusals(identification)) or None


def export_notes(identification) -> list[str]:
    """The findings that stop nothing, passed on with the export (their warning text)."""
    return [f["message"] for f in getattr(identification, "findings", []) or [] if not f.get("refuses")]


def calibration_record(identification, forced: bool = False) -> dict:
    """What a controller file records about its calibration: the gate's verdict and the numbers it was made from.

    ``fit_quality``; ``reference`` (``"stated noise"``, or ``"fit"`` with ``reference_rms``, mm, when the
    data state no noise); ``sigma``; ``targets``: per target the ``identification`` and ``validation``
    stats of the 3-D residual norms (``mean, max, rms, n``, mm) with the ``noise_rms`` their rows state;
    ``equations`` (poses, equations, machine equations, parameters, machine parameters); ``region``: the
    actuated values the identification poses cover; ``repeated_poses`` (the groups whose readings were copied);
    ``excluded`` (outliers excluded on
    request); ``findings`` (``code``, ``refuses``, ``message``); ``forced`` and ``reasons`` (the gate's
    reasons when written with ``--force``; both empty otherwise).

    Raises
    ------
    ValueError
        When the calibration is refused and ``forced`` is false (the command line refuses it before).
    """
    reasons = refusals(identification)
    if reasons and not forced:
        raise ValueError("; and ".join(reasons))
    ratios = identification.noise_ratios or {}
    counts = identification.equations or {}
    reference_rms = None
    if ratios.get("reference") == "fit":
        reference_rms = float(3.0 ** 0.5 * identification.sigma)
    return {
        "fit_quality": identification.fit_quality,
        "reference": ratios.get("reference", "stated noise"),
        "reference_rms": reference_rms,
        "sigma": float(identification.sigma),
        "targets": {name: {"identification": dict(t["identification"]),
                           "validation": None if t["validation"] is None else dict(t["validation"])}
                    for name, t in identification.targets.items()},
        "equations": {k: int(counts[k]) for k in ("poses", "equations", "machine_equations", "parameters",
                                                  "machine_parameters")},
        "region": dict(identification.region),
        # the groups whose readings were copied (they refuse); poses measured again are a note's, with its groups
        "repeated_poses": [list(g) for f in identification.findings if f["code"] == "repeated-poses"
                           for g in f.get("groups", [])],
        "excluded": [{"set": e["set"], "pose": str(e["pose"]), "target": str(e["target"])}
                     for e in identification.excluded],
        "findings": [{"code": f["code"], "refuses": bool(f["refuses"]), "message": f["message"]}
                     for f in identification.findings],
        "forced": bool(reasons),
        "reasons": list(reasons),
    }
