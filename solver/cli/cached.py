"""The commands' stages through the on-disk cache (:mod:`hyperstat.solver.cache`): computed once per model.

Units: lengths in mm, angles in rad.

What is cached, and what its key holds besides the version of the code (:func:`hyperstat.solver.cache.key`):

* ``sample``: a workspace sample (:func:`hyperstat.solver.tolerances.accuracy.sample_workspace`); the model,
  the number of draws, the seed and the workspace's bounds.  Samples of more than :data:`SAMPLE_BYTES` are
  not stored (a million configurations would take 120 MB);
* ``values``: what :func:`hyperstat.solver.tolerances.values.assign_values` writes into a classification
  (the values, their sources and evidence, the allocation, the calibrated values, the drawing values, the
  warnings); the model, the classification it starts from, the configurations (their bytes) and every
  option of the call that changes its answer (given or left at its default alike: ``report`` and ``accuracy``
  on the same sample share the entry).  The classification is recomputed (it is cheap) and the stored changes are applied
  to it, tolerance by tolerance, after checking that the tolerances are the same;
* ``diagnosis-selection``: the effects the diagnosis selects and the violated defect it names, which
  ``export-controller --diagnose`` adds to the controller file; the model, the analysis' configurations and
  the bytes of the data files.  ``report --data`` stores it when it diagnoses;
* ``accuracy`` and ``montecarlo``: the command's whole JSON document; the model and every option.

``report`` also keeps ``report-diagnosis`` (the report's JSON of the diagnosis, and its plots) and ``part-page``
(one part drawing's page) entries, keyed with the drawing code's version too (:mod:`hyperstat.cad_plugin.report`,
:func:`hyperstat.cad_plugin.report_parts.page_key`).

``--no-cache`` (or ``HYPERSTAT_CACHE=off``) computes everything and stores nothing.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from typing import Any, Callable

import numpy as np

from hyperstat.solver.cache import Cache, default_directory, encode, file_digest, key

__all__ = ["cache_option", "command_cache", "model_identity", "cached_sample", "cached_sample_started", "cached_values",
           "cached_document", "store_selection", "cached_selection", "SAMPLE_BYTES", "stage_memo"]

#: the largest workspace sample stored (bytes of its configurations)
SAMPLE_BYTES = 32 * 2**20


def cache_option(p: argparse.ArgumentParser) -> None:
    """``--no-cache``: compute every stage, read and store nothing."""
    p.add_argument("--no-cache", action="store_true",
                   help="compute everything again: do not read or write the cache of results "
                        "(folder: $HYPERSTAT_CACHE, default ~/.cache/hyperstat; safe to delete)")


def command_cache(args: argparse.Namespace) -> Cache:
    """The cache of a command (one per command run, kept on ``args``): off with ``--no-cache``."""
    cache = getattr(args, "_cache", None)
    if cache is None:
        cache = Cache(None if getattr(args, "no_cache", False) else default_directory())
        args._cache = cache
    return cache


def model_identity(args: argparse.Namespace, mechanism) -> dict:
    """The model as a key: the SHA-256 of its canonical model-file text (:func:`dumps_model`), and nothing of how it
    was obtained.

    Every cached stage is computed from the :class:`Mechanism` alone, whose model-file text holds all of it (geometry,
    defects, ranges, workspace, metadata; ``-p`` overrides are in the built geometry), so a template, the model file
    ``hyperstat build`` writes of it (FreeCAD's Analyse reads that one) and a copy elsewhere are one key: the same
    values are computed once.  A changed file, parameter or model is another text, hence another key.  (The whole
    documents of ``accuracy`` and ``montecarlo`` name their source: their options, also in their key, hold its path.)
    """
    ident = getattr(args, "_model_identity", None)
    if ident is None:
        from hyperstat.solver.kinematics.modelfile import dumps_model

        ident = {"model": hashlib.sha256(dumps_model(mechanism).encode()).hexdigest()}
        args._model_identity = ident
    return ident


def _digest(a: Any) -> str:
    """SHA-256 of an array's bytes, dtype and shape (or of anything :func:`encode` takes, its arrays by their digests).

    An array's bytes are hashed where they lie (little-endian), not encoded as text first: the base64 and JSON
    copies of a 683,000-configuration sample held about 400 MiB at once (issue 39).

    >>> _digest(np.arange(3.0)) == _digest(np.arange(3.0)) != _digest(np.arange(3))
    True
    """
    from hyperstat.solver.tolerances.spilled import SpilledArray, array_digest

    if isinstance(a, SpilledArray):  # the same digest as the array in memory, read a block at a time
        return array_digest(a, f"array {np.dtype('<f8').str} {list(a.shape)} ".encode())
    if isinstance(a, np.ndarray):
        if a.dtype.kind not in "biuf":
            raise TypeError(f"an array of {a.dtype} is not cached")
        data = np.ascontiguousarray(a.astype(a.dtype.newbyteorder("<"), copy=False))
        h = hashlib.sha256(f"array {data.dtype.str} {list(data.shape)} ".encode())
        h.update(memoryview(data.reshape(-1)).cast("B"))
        return h.hexdigest()
    return hashlib.sha256(json.dumps(encode(_arrays_digested(a)), separators=(",", ":")).encode()).hexdigest()


def _arrays_digested(a: Any) -> Any:
    """``a`` with every array replaced by ``{"array-sha256": its digest}`` (lists, tuples and dict values)."""
    from hyperstat.solver.tolerances.spilled import SpilledArray

    if isinstance(a, (np.ndarray, SpilledArray)):
        return {"array-sha256": _digest(a)}
    if isinstance(a, tuple):
        return tuple(_arrays_digested(v) for v in a)
    if isinstance(a, list):
        return [_arrays_digested(v) for v in a]
    if isinstance(a, dict):
        return {k: _arrays_digested(v) for k, v in a.items()}
    return a


def _workspace_key(ws) -> Any:
    return None if ws is None else {k: v for k, v in vars(ws).items()}


def cached_sample(args: argparse.Namespace, mechanism, n: int, seed: int, workspace,
                  compute: Callable[[], np.ndarray]) -> np.ndarray:
    """The workspace sample of ``compute()`` (``n`` draws, ``seed``, ``workspace``), from the cache when stored."""
    def start() -> Callable[[], Any]:  # computed now, handed over when asked
        q = compute()
        return lambda: q

    return cached_sample_started(args, mechanism, n, seed, workspace, start)()


def cached_sample_started(args: argparse.Namespace, mechanism, n: int, seed: int, workspace,
                          start: Callable[[], Callable[[], Any]]) -> Callable[[], Any]:
    """:func:`cached_sample` whose computation runs while the caller goes on: ``start()`` begins it and returns what
    waits for its sample; returned: what gives the sample (stored, or computed and then stored)."""
    cache = command_cache(args)
    if not cache.enabled:
        return start()
    k = key("sample", model_identity(args, mechanism), int(n), int(seed), _workspace_key(workspace))
    q = cache.load("sample", k)
    if isinstance(q, np.ndarray) and q.ndim == 2 and q.shape[1] == len(mechanism.joints):
        return lambda: q
    wait = start()

    def finish():
        q = wait()
        if q.nbytes <= SAMPLE_BYTES:
            cache.store("sample", k, q if isinstance(q, np.ndarray) else q.copy())
        return q
    return finish


# ---------------------------------------------------------------------------------------------- values
#: attributes of a classification that hold the objects it was computed from (never cached, never compared)
_INPUTS = {"analysis", "declaration", "configurations", "items"}


def _signature(obj, skip: set = frozenset()) -> dict:
    """Attribute -> its encoded JSON text, or its identity when it cannot be encoded."""
    out = {}
    for name, value in vars(obj).items():
        if name in skip:
            continue
        try:
            out[name] = json.dumps(encode(value), separators=(",", ":"))
        except (TypeError, ValueError):
            out[name] = ("object", type(value).__name__, id(value))
    return out


def _keyed(signature: dict) -> dict:
    """A signature without identities (the same in every process): an object that cannot be encoded counts by
    its type (it comes from the model and the analysis, which the key holds)."""
    return {name: sig[:2] if isinstance(sig, tuple) else sig for name, sig in signature.items()}


def _changes(before: dict, after: dict, obj) -> dict | None:
    """Attributes of ``obj`` whose signature changed: name -> value; None if one of them cannot be stored."""
    out = {}
    for name, sig in after.items():
        if before.get(name) != sig:
            if isinstance(sig, tuple):
                return None
            out[name] = getattr(obj, name)
    return out


#: options of :func:`~hyperstat.solver.tolerances.values.assign_values` that do not change its answer: ``task_maps_at``
#: (the task rows at the configurations, handed over when ``accuracy`` has them from its own Jacobians; computed from
#: the model and the configurations, both in the key, otherwise) and ``memo`` (:func:`stage_memo`)
_NOT_IN_KEY = ("task_maps_at", "memo")
#: the defaults of the options of ``assign_values`` a caller may give or leave out (the same call either way)
_DEFAULTS = {"assembly": True, "refine": True, "workspace": None, "calibrate": True}


def _answer_options(options: dict) -> dict:
    """The options of a values call that its answer depends on, given the same way by every command: without
    :data:`_NOT_IN_KEY` and without an option at its default, so that ``report`` and ``accuracy`` on the same
    sample, spec and analysis are one key.

    >>> _answer_options({"assembly": True, "workspace": None, "task_maps_at": (1,), "position_accuracy": 0.05})
    {'position_accuracy': 0.05}
    >>> _answer_options({"assembly": False, "calibrate": True})
    {'assembly': False}
    """
    return {name: v for name, v in options.items() if name not in _NOT_IN_KEY
            and not (name in _DEFAULTS and (v is _DEFAULTS[name] or (isinstance(v, bool) and v == _DEFAULTS[name])))}


def cached_values(args: argparse.Namespace, cl, mechanism, kin, configurations: np.ndarray,
                  assign: Callable, on_miss: Callable | None = None, **options) -> Any:
    """``assign(cl, mechanism, kin, configurations, **options)`` (:func:`assign_values`), its changes cached.

    The key holds the model, the classification as it is before the call, the configurations and
    the options (arrays by their bytes).  On a hit the stored changes are applied to ``cl``; a
    stored entry whose tolerances are not those of ``cl`` is ignored.  ``on_miss()`` is called just
    before the values are computed (not when they are read): ``report`` starts its part pages'
    child there.
    """
    cache = command_cache(args)
    if not cache.enabled:
        if on_miss is not None:
            on_miss()
        return assign(cl, mechanism, kin, configurations, **options)
    before_cl = _signature(cl, _INPUTS)
    before_items = [_signature(t) for t in cl.items]
    ids = [t.id for t in cl.items]
    from hyperstat.solver.tolerances.spilled import SpilledArray
    from hyperstat.solver.tolerances.task_summary import TaskSummary

    keyed = {name: v.as_tuple() if isinstance(v, TaskSummary) else v for name, v in _answer_options(options).items()}
    opts = {name: (_digest(v) if isinstance(v, (np.ndarray, tuple)) and name != "workspace" else
                   _workspace_key(v) if name == "workspace" else v) for name, v in sorted(keyed.items())}
    k = key("values", model_identity(args, mechanism), _digest(_keyed(before_cl)),
            _digest([_keyed(b) for b in before_items]),
            _digest(configurations if isinstance(configurations, SpilledArray) else np.asarray(configurations)),
            None if cl.analysis is None else _digest(np.asarray(cl.analysis.configurations)), opts)
    if _restore_values(cache.load("values", k), cl, ids):
        return cl
    with cache.computing("values", k):  # another process computing the same values: wait for them, then read
        again = Cache(cache.directory)
        if _restore_values(again.load("values", k), cl, ids):
            cache.misses.pop()
            cache.hits.append("values")
            return cl
        if on_miss is not None:
            on_miss()
        result = assign(cl, mechanism, kin, configurations, memo=stage_memo(args, mechanism), **options)
        changed_cl = _changes(before_cl, _signature(cl, _INPUTS), cl)
        changed_items = [_changes(b, _signature(t), t) for b, t in zip(before_items, cl.items)]
        if changed_cl is not None and all(c is not None for c in changed_items) and [t.id for t in cl.items] == ids:
            cache.store("values", k, {"ids": ids, "classification": changed_cl, "items": changed_items})
    return result


def stage_memo(args: argparse.Namespace, mechanism) -> Callable[[str, Any, Callable[[], Any]], Any]:
    """``memo(stage, inputs, compute)`` for the stages of a values call that do not depend on its sample
    (:func:`~hyperstat.solver.tolerances.values.assign_values`' ``memo``): ``compute()``, stored in the command's cache
    under the model, the stage, its ``inputs`` (arrays by their bytes) and the code's version, or read from it.

    ``accuracy`` at 100,000 configurations, ``report`` at 200 and ``montecarlo`` at 2,000 of one model differ in their
    samples, so their values are three entries; the assembly conditions and the whole drawing start from the analysis'
    configurations and the workspace's fixed checkpoints in all three: one entry, computed by the first command.  A
    result the cache cannot encode is computed every time.

    >>> import argparse, tempfile, hyperstat as hs
    >>> args = argparse.Namespace(_cache=Cache(tempfile.mkdtemp()))  # a command's cache, in a new folder
    >>> memo = stage_memo(args, hs.load("slider_crank"))
    >>> memo("demo", {"n": 1}, lambda: np.arange(3.0)).tolist(), memo("demo", {"n": 1}, lambda: None).tolist()
    ([0.0, 1.0, 2.0], [0.0, 1.0, 2.0])
    >>> command_cache(args).hits, command_cache(args).misses
    (['demo'], ['demo'])
    """
    cache = command_cache(args)

    def memo(stage: str, inputs: Any, compute: Callable[[], Any]) -> Any:
        if not cache.enabled:
            return compute()
        try:
            k = key(stage, model_identity(args, mechanism), _digest(inputs))
        except (TypeError, ValueError):  # an input the cache does not encode: no key, computed
            return compute()
        stored = cache.load(stage, k)
        if stored is not None:
            return stored
        with cache.computing(stage, k):  # another process on the same entry: wait, then read it
            stored = Cache(cache.directory).load(stage, k)
            if stored is not None:
                cache.misses.pop()
                cache.hits.append(stage)
                return stored
            value = compute()
            cache.store(stage, k, value)
        return value

    return memo


def _restore_values(stored: Any, cl, ids: list) -> bool:
    """Apply a stored entry of :func:`cached_values` to ``cl``; False (nothing changed) when it is not ``cl``'s."""
    if not (isinstance(stored, dict) and stored.get("ids") == ids and len(stored.get("items", [])) == len(ids)):
        return False
    for name, value in stored["classification"].items():
        setattr(cl, name, value)
    for t, changes in zip(cl.items, stored["items"]):
        for name, value in changes.items():
            setattr(t, name, value)
    return True


# ---------------------------------------------------------------------------------------------- whole documents
def cached_document(args: argparse.Namespace, command: str, mechanism, options: dict,
                    compute: Callable[[], dict]) -> dict:
    """A command's JSON document (``compute()``), from the cache when stored under the model and ``options``."""
    cache = command_cache(args)
    if not cache.enabled:
        return compute()
    k = key(command, model_identity(args, mechanism), options)
    doc = cache.load(command, k)
    if isinstance(doc, dict):
        return doc
    doc = compute()
    cache.store(command, k, doc)
    return doc


# ---------------------------------------------------------------------------------------------- diagnosis
def _selection_key(args, mechanism, result, data_paths: list) -> str:
    files = [file_digest(p) if p else None for p in data_paths]
    return key("diagnosis-selection", model_identity(args, mechanism), _digest(np.asarray(result.configurations)),
               files)


def store_selection(args: argparse.Namespace, mechanism, result, data_paths: list, diagnosis) -> None:
    """Keep what ``export-controller --diagnose`` takes from a diagnosis of these data (selected effects,
    violated defect)."""
    cache = command_cache(args)
    if cache.enabled:
        cache.store("diagnosis-selection", _selection_key(args, mechanism, result, data_paths),
                    {"selected": list(diagnosis.selected), "violated_defect": diagnosis.violated_defect})


def cached_selection(args: argparse.Namespace, mechanism, result, data_paths: list,
                     diagnose: Callable) -> tuple[list, dict | None]:
    """(selected effects, violated defect) of the diagnosis of these data: stored, or ``diagnose()`` run."""
    cache = command_cache(args)
    k = _selection_key(args, mechanism, result, data_paths) if cache.enabled else None
    stored = cache.load("diagnosis-selection", k) if k else None
    if isinstance(stored, dict) and isinstance(stored.get("selected"), list):
        return stored["selected"], stored.get("violated_defect")
    diag = diagnose()
    if k:
        cache.store("diagnosis-selection", k, {"selected": list(diag.selected),
                                               "violated_defect": diag.violated_defect})
    return list(diag.selected), diag.violated_defect
