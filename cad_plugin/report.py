"""The tolerance report: ``report.html`` (self-contained), ``report.md``, ``report.json`` and the skeleton drawing.

Units: lengths in mm, angles in rad; residuals printed in µm.

:func:`write_report` lays out the document of
:func:`hyperstat.solver.export.report_content.report_document`: the HTML
(:mod:`hyperstat.cad_plugin.report_html`) inlines its pictures (the skeleton drawing and the
diagnosis plots as SVG with their text kept as text, so that they print sharp and at their type
size) and its style, loads nothing from the network, reads on a projector and prints on A4;
the Markdown (:mod:`hyperstat.cad_plugin.report_markdown`) says the same in text.  The
skeleton drawing is also written as ``skeleton_views.png`` (with ``skeleton_views.png.json``,
the words it shows).  The same inputs give byte-identical files: no timestamps beyond the
title block's date, sorted JSON keys.
"""

from __future__ import annotations

from pathlib import Path

from hyperstat.solver.atomic import all_or_nothing, dumps_json, write_bytes, write_text

from hyperstat.cad_plugin.report_html import SECTIONS, render_html
from hyperstat.cad_plugin.report_markdown import render_markdown

__all__ = ["write_report", "skeleton_views", "skeleton_views_drawn", "skeleton_drawing", "render_html",
           "render_markdown", "SECTIONS", "step_name", "part_pages_worker", "cached_diagnosis", "store_diagnosis",
           "diagnosis_entry", "decode_entry", "preload_pictures", "cached_views", "store_views"]


def step_name(part: str) -> str:
    """The file name (without ``.step``) of a part's STEP file: its name with anything but letters, digits,
    ``-`` and ``_`` replaced by ``_``.

    >>> step_name("cross 21/a")
    'cross_21_a'
    """
    import re

    return re.sub(r"[^A-Za-z0-9_-]", "_", part) or "part"


def preload_pictures() -> None:
    """Import matplotlib (pyplot, the SVG and PNG writers, the text path) once, before the report forks its children.

    Every process of a report imports it: the skeleton views' child (pyvista imports pyplot), the diagnosis'
    child (its plots), the part pages' child (their SVG) and this process (the skeleton drawing).  Imported here,
    the children forked after inherit it instead of importing it again (about 0.4 s of CPU each); this process
    imports it a little earlier than it would.  The figures are the same: only modules are loaded, no state set.
    """
    import matplotlib.pyplot  # noqa: F401 - imports matplotlib, its figure, axes and projections
    from matplotlib.backends import backend_agg, backend_svg  # noqa: F401
    from matplotlib import textpath  # noqa: F401


def skeleton_views(mechanism, analysis_json: dict | None = None) -> dict:
    """The four rendered views of the skeleton (:func:`hyperstat.cad_plugin.view.render_views`; JSON-ready)."""
    from hyperstat.cad_plugin.view import render_views

    return render_views(mechanism, analysis_json)


def skeleton_drawing(rendered: dict, items: list, title: str) -> tuple[str, bytes, dict]:
    """The skeleton drawing of rendered views: SVG for the HTML, PNG, and the words it shows."""
    from hyperstat.cad_plugin.drawing import figure_png, figure_svg, skeleton_figure

    fig, words = skeleton_figure(rendered, items, title)
    return figure_svg(fig), figure_png(fig, 1800), words


def skeleton_views_drawn(mechanism, analysis_json: dict | None = None) -> dict:
    """The skeleton views (:func:`skeleton_views`) and their drawing without feature control frames, drawn ahead of
    the tolerance values (by the report's views child, while the values are computed).

    Returns ``{"rendered": views, "drawing": {"title", "svg", "png", "words"}}``.  The drawing is
    :func:`skeleton_drawing` of the views with no tolerance item: the same bytes as the drawing of the final items
    when none of them carries a ``drawing`` (frames) list, as in a report with part drawings, whose frames are on
    the parts' pages (:func:`hyperstat.cad_plugin.drawing.skeleton_figure` reads the items only for their
    ``drawing`` lists); :func:`write_report` uses it only then (``images["skeleton"]``), and draws it otherwise.
    """
    rendered = skeleton_views(mechanism, analysis_json)
    title = f"Skeleton of {mechanism.name}"
    svg, png, words = skeleton_drawing(rendered, [], title)
    return {"rendered": rendered, "drawing": {"title": title, "svg": svg, "png": png, "words": words}}


def _views_key(args, mechanism, analysis_json: dict | None) -> str | None:
    """The cache key of the skeleton views and their drawing (:func:`skeleton_views_drawn`): the model (its
    canonical text), the whole analysis JSON the views are coloured and called out from, the drawing code's version
    (:func:`hyperstat.cad_plugin.report_parts.drawing_code_version`: the ``cad_plugin`` sources, CadQuery, OCP,
    matplotlib), the versions of the renderer and the image libraries (pyvista, VTK, Pillow), and the solver's
    (:func:`hyperstat.solver.cache.key`); None without a cache."""
    from importlib.metadata import PackageNotFoundError, version

    from hyperstat.solver.cache import key
    from hyperstat.solver.cli.cached import _digest, command_cache, model_identity

    from hyperstat.cad_plugin.report_parts import drawing_code_version

    if not command_cache(args).enabled:
        return None
    libraries = []
    for name in ("pyvista", "vtk", "pillow"):
        try:
            libraries.append(f"{name}={version(name)}")
        except PackageNotFoundError:  # pragma: no cover - a library installed without metadata
            libraries.append(f"{name}=?")
    return key("skeleton-views", drawing_code_version(), libraries, model_identity(args, mechanism),
               _digest(analysis_json))


def cached_views(args, mechanism, analysis_json: dict | None) -> dict | None:
    """The skeleton views and their drawing as :func:`store_views` kept them for this model and analysis (what
    :func:`skeleton_views_drawn` returns, the same bytes), or None.  A report run again on the same model (new data,
    hypotheses, revision) then renders nothing: the views' child was the last process of a cached report."""
    from hyperstat.solver.cli.cached import command_cache

    from hyperstat.cad_plugin.background import _decode

    k = _views_key(args, mechanism, analysis_json)
    stored = command_cache(args).load("skeleton-views", k) if k else None
    try:
        drawn = _decode(stored) if isinstance(stored, dict) else None
    except (TypeError, ValueError, AttributeError, KeyError):
        return None
    if not (isinstance(drawn, dict) and isinstance(drawn.get("rendered"), dict)
            and isinstance(drawn.get("drawing"), dict) and isinstance(drawn["drawing"].get("png"), bytes)):
        return None
    return drawn


def store_views(args, mechanism, analysis_json: dict | None, drawn: dict) -> None:
    """Keep the skeleton views and their drawing (:func:`cached_views`)."""
    from hyperstat.solver.cli.cached import command_cache

    from hyperstat.cad_plugin.background import _encode

    k = _views_key(args, mechanism, analysis_json)
    if k:
        command_cache(args).store("skeleton-views", k, _encode(drawn))


def _prepare_pages(provisional=None) -> None:
    """What every part page needs whatever the drawing: OCCT's modelling and hidden-line removal, matplotlib's SVG
    writer and the font (imported by the part pages' child while the report computes the values); then the solids
    and views of the drawings ``provisional()`` predicts (``(drawings, joint types)``;
    :func:`hyperstat.cad_plugin.report_parts.prebuild`).  Not CadQuery: the solids are made with OCP directly
    (:mod:`hyperstat.cad_plugin.occ_solids`), without CadQuery's imports of VTK and ezdxf."""
    import gc

    from matplotlib.backends import backend_svg  # noqa: F401

    enabled = gc.isenabled()
    gc.disable()  # the imports make objects kept for good, no garbage: no collection while they run (measured: three
    try:  # full collections, 0.12 s of CPU), and none over what they made after (gc.freeze)
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse  # noqa: F401 - about 0.6 s of imports
        from OCP.HLRBRep import HLRBRep_PolyAlgo  # noqa: F401

        from hyperstat.cad_plugin import part_solids, report_parts  # noqa: F401
    finally:
        if enabled:
            gc.enable()
    import multiprocessing

    if multiprocessing.parent_process() is not None:  # in the pages' forked child only: never a caller's heap for good
        gc.freeze()
    report_parts.text_width_pt("M")
    if provisional is not None:
        try:
            drawings, types = provisional()
        except Exception:  # noqa: BLE001 - a prediction only: the pages are then built from the final drawings
            return
        report_parts.prebuild(drawings, types)


def _pages_of(cache, doc: dict) -> list:
    from hyperstat.cad_plugin.report_parts import part_pages

    return part_pages(doc, cache=cache)


def part_pages_worker(cache=None, provisional=None, nice: int = 0):
    """The part pages drawn by a forked child started now (:class:`hyperstat.cad_plugin.background.Deferred`): it
    imports OCCT (OCP) while the report computes the values, then draws the pages of the ``{"drawings", "joints"}``
    given to its ``result`` (:func:`hyperstat.cad_plugin.report_parts.part_pages`, without the solids; read from
    and stored in ``cache``).  The same pages as drawing them in-process; drawn here if the child fails, and
    without a child once OCCT is loaded in this process.  ``provisional`` (a function returning ``(drawings, joint
    types)`` predicted before the values) lets the child build the parts' solids and views meanwhile; ``nice`` is
    added to the child's niceness (:data:`hyperstat.cad_plugin.background.PAGES_NICE`)."""
    import sys
    from functools import partial

    from hyperstat.cad_plugin.background import Deferred

    # OCCT's parallel meshing leaves its thread pool's locks in a forked child (measured: the child hangs at its
    # first mesh): once OCCT is loaded in this process (a template built with CadQuery, an earlier report in the
    # same process; FreeCAD's own OCCT), the pages are drawn here
    fork = not {"OCP", "FreeCAD"} & set(sys.modules)
    return Deferred(partial(_pages_of, cache), partial(_prepare_pages, provisional if fork else None), fork=fork,
                    nice=nice)


def _diagnosis_key(args, mechanism, result, data_paths: list) -> str | None:
    from hyperstat.solver.cache import file_digest, key
    from hyperstat.solver.cli.cached import _digest, command_cache, model_identity

    from hyperstat.cad_plugin.report_parts import drawing_code_version

    if not command_cache(args).enabled:
        return None
    import numpy as np

    return key("report-diagnosis", drawing_code_version(), model_identity(args, mechanism),
               _digest(np.asarray(result.configurations)), [file_digest(p) if p else None for p in data_paths])


def cached_diagnosis(args, mechanism, result, data_paths: list, figures: bool) -> dict | None:
    """A report's diagnosis as :func:`store_diagnosis` kept it for this model, analysis and data files (their bytes),
    or None: ``identification`` and ``diagnosis`` (the report's JSON of them), ``selected`` and ``violated_defect``
    (what ``export-controller --diagnose`` takes), ``figures`` (the diagnosis plots, SVG; None if none were drawn:
    then not an answer when ``figures`` are wanted).  The key holds the code's version, the solver's and the drawing
    code's (:func:`hyperstat.cad_plugin.report_parts.drawing_code_version`)."""
    from hyperstat.solver.cli.cached import command_cache

    k = _diagnosis_key(args, mechanism, result, data_paths)
    stored = command_cache(args).load("report-diagnosis", k) if k else None
    if not (isinstance(stored, dict) and isinstance(stored.get("diagnosis"), dict)
            and isinstance(stored.get("identification"), dict) and isinstance(stored.get("selected"), list)):
        return None
    if figures and not isinstance(stored.get("figures"), dict):
        return None
    return stored


def diagnosis_entry(mechanism, result, data, validation, kin, figures: bool) -> str:
    """The report's diagnosis of ``data`` (:func:`hyperstat.solver.diagnosis.diagnose.diagnose`) as the JSON text
    of the entry :func:`cached_diagnosis` reads (arrays and floats bit for bit: :func:`hyperstat.solver.cache.encode`),
    with its plots (SVG) when ``figures``: what a forked child hands back (:func:`decode_entry`)."""
    import json

    from hyperstat.solver.cache import encode
    from hyperstat.solver.diagnosis.diagnose import diagnose
    from hyperstat.solver.export.report_content import _diagnosis_summary, _report_identification

    diag = diagnose(mechanism, result, data, validation, kinematics=kin)
    entry = {"identification": _report_identification(diag.final or diag.rigid), "diagnosis": _diagnosis_summary(diag),
             "selected": list(diag.selected), "violated_defect": diag.violated_defect, "figures": None}
    if figures:
        from hyperstat.cad_plugin.plots import diagnosis_figures

        entry["figures"] = diagnosis_figures(diag, data, "svg")
    return json.dumps(encode(entry), separators=(",", ":"))


def decode_entry(text: str):
    """The value :func:`diagnosis_entry` encoded."""
    import json

    from hyperstat.solver.cache import decode

    return decode(json.loads(text))


def store_diagnosis(args, mechanism, result, data_paths: list, entry: dict) -> None:
    """Keep a report's diagnosis (:func:`cached_diagnosis`)."""
    from hyperstat.solver.cli.cached import command_cache

    k = _diagnosis_key(args, mechanism, result, data_paths)
    if k:
        command_cache(args).store("report-diagnosis", k, entry)


def write_report(doc: dict, out_dir: str | Path, mechanism=None, analysis_json: dict | None = None,
                 images: dict | None = None, step_drawings: bool = False, pdf: bool = False,
                 cache=None) -> list[Path]:
    """Draw the skeleton and write the report's files atomically into ``out_dir``.

    ``images`` may hold ``rendered`` (views already rendered, e.g. by a background process), or a
    finished ``views`` picture; otherwise the views of ``mechanism`` are rendered here.  With ``rendered``,
    ``skeleton`` may hold their drawing without frames (:func:`skeleton_views_drawn`'s ``drawing``), used when
    no tolerance item draws frames on the skeleton and its title is this document's.  The part
    drawings of ``doc["drawings"]`` get a page each (:mod:`hyperstat.cad_plugin.report_parts`); with
    ``step_drawings``, each part is also written as ``parts/<part>.step``, STEP AP242 with its datums
    and frames as semantic PMI (:mod:`hyperstat.cad_plugin.pmi`), with the report's files or not at all;
    with ``pdf``, ``report.pdf`` printed on A4 by headless Chromium (:mod:`hyperstat.cad_plugin.report_pdf`).
    ``images["parts"]`` may hold the pages already drawn (:func:`part_pages_worker`); ``cache`` (a
    :class:`hyperstat.solver.cache.Cache`) keeps and reads the part pages.
    """
    out_dir = Path(out_dir)
    images = dict(images or {})
    rendered = images.pop("rendered", None)
    ahead = images.pop("skeleton", None)
    if rendered is None and mechanism is not None and "views" not in images:
        rendered = skeleton_views(mechanism, analysis_json)
    extra = []
    if rendered is not None:
        items = doc["tolerances"]["items"]
        if doc.get("drawings"):  # the frames are on the part drawings' pages; the skeleton calls out the ids
            items = [{**t, "drawing": []} for t in items]
        title = f"Skeleton of {doc['mechanism']}"
        if ahead is not None and ahead.get("title") == title and not any(t.get("drawing") for t in items):
            svg, png, words = ahead["svg"], ahead["png"], ahead["words"]  # the same drawing, drawn by a child
        else:
            svg, png, words = skeleton_drawing(rendered, items, title)
        images["views"] = svg
        views = [(out_dir / "skeleton_views.png", png), (out_dir / "skeleton_views.png.json", dumps_json(words))]
    else:
        views = []
    if hasattr(images.get("parts"), "result"):  # drawn by a child (part_pages_worker) while this drew the skeleton
        images["parts"] = images["parts"].result(timeout=600.0)
    if doc.get("drawings") and ("parts" not in images or step_drawings):
        from hyperstat.cad_plugin.report_parts import part_pages

        images["parts"] = part_pages(doc, solids=step_drawings, cache=cache)
    if step_drawings:
        from hyperstat.cad_plugin.pmi import part_step_bytes

        for page in images.get("parts") or []:
            if page.get("error"):
                from hyperstat.solver.errors import HyperstatError

                raise HyperstatError(f"--step-drawings: part '{page['part']}' cannot be written as STEP: "
                                     f"{page['error'].rstrip('.')}; no output was written.")
            drawing = next(d for d in doc["drawings"] if d["part"] == page["part"])
            extra.append((out_dir / "parts" / f"{step_name(page['part'])}.step",
                          part_step_bytes(page["solid"], drawing)))
    extra += views
    html = render_html(doc, images)
    if pdf:
        from hyperstat.cad_plugin.report_pdf import print_pdf

        extra.append((out_dir / "report.pdf", print_pdf(html)))
    with all_or_nothing():  # every file of the report or none
        written = [write_text(out_dir / "report.json", dumps_json(doc)),
                   write_text(out_dir / "report.md", render_markdown(doc)),
                   write_text(out_dir / "report.html", html)]
        for path, data in extra:
            written.append(write_bytes(path, data) if isinstance(data, bytes) else write_text(path, data))
    return written
