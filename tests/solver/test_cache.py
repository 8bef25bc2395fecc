"""The on-disk cache (units: none): exact round trip, keys that change with every input, entries that are whole
and their own or ignored, a cache that cannot be written costs only the time."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from hyperstat.solver.cache import Cache, FORMAT, code_version, decode, default_directory, encode, key


def test_values_come_back_bit_for_bit():
    rng = np.random.default_rng(0)
    value = {"q": rng.normal(size=(7, 5)), "ints": np.arange(4, dtype=np.int32), "flags": np.array([True, False]),
             "special": [float("nan"), float("inf"), -float("inf"), -0.0, 5e-324], "tuple": (1, "a", None),
             3: {"nested": (np.float64(0.1), np.int64(2))}, "$odd": "key"}
    back = decode(json.loads(json.dumps(encode(value))))
    assert np.array_equal(back["q"], value["q"]) and back["q"].dtype == value["q"].dtype
    assert back["q"].tobytes() == value["q"].tobytes()
    assert back["ints"].dtype == np.int32 and back["flags"].dtype == bool
    assert np.isnan(back["special"][0]) and back["special"][1:3] == [float("inf"), -float("inf")]
    assert str(back["special"][3]) == "-0.0" and back["special"][4] == 5e-324
    assert back["tuple"] == (1, "a", None) and back[3] == {"nested": (0.1, 2)} and back["$odd"] == "key"


def test_what_cannot_be_encoded_is_refused():
    with pytest.raises(TypeError):
        encode({"x": object()})
    with pytest.raises(TypeError):
        encode(np.array(["a", "b"]))


def test_keys_change_with_every_part_and_the_stage():
    base = key("values", {"model": "abc"}, np.zeros(3), {"seed": 0})
    assert base == key("values", {"model": "abc"}, np.zeros(3), {"seed": 0})
    assert base != key("values", {"model": "abd"}, np.zeros(3), {"seed": 0})
    assert base != key("values", {"model": "abc"}, np.array([0.0, 0.0, 1e-300]), {"seed": 0})
    assert base != key("values", {"model": "abc"}, np.zeros(3), {"seed": 1})
    assert base != key("sample", {"model": "abc"}, np.zeros(3), {"seed": 0})
    assert base != key("values", {"model": "abc"}, np.zeros((3, 1)), {"seed": 0})  # the shape counts
    assert code_version().startswith(("0.", "1.", "2."))  # hyperstat's version, then the sources' hash


def test_store_and_load(tmp_path):
    cache = Cache(tmp_path)
    k = key("stage", 1)
    assert cache.load("stage", k) is None and cache.misses == ["stage"]
    assert cache.store("stage", k, {"a": np.arange(3.0)})
    assert cache.load("stage", k)["a"].tolist() == [0.0, 1.0, 2.0] and cache.hits == ["stage"]
    assert not list(tmp_path.rglob(".tmp-*"))  # the temporary file was renamed


def _entry(tmp_path, stage="stage", value=1):
    cache = Cache(tmp_path)
    k = key(stage, value)
    cache.store(stage, k, {"v": value})
    (path,) = list((tmp_path / stage).rglob("*.json"))
    return cache, k, path


@pytest.mark.parametrize("damage", ["truncate", "flip", "header", "garbage", "empty"])
def test_a_damaged_entry_is_ignored_and_replaced(tmp_path, damage):
    cache, k, path = _entry(tmp_path)
    text = path.read_text()
    if damage == "truncate":
        path.write_text(text[: len(text) - 3])
    elif damage == "flip":  # same length, one digit of the payload changed: the digest does not match
        path.write_text(text[:-2] + ("2" if text[-2] != "2" else "3") + text[-1])
    elif damage == "header":
        path.write_text(text.replace(FORMAT, "hyperstat-cache-0"))
    elif damage == "garbage":
        path.write_bytes(os.urandom(64))
    else:
        path.write_text("")
    assert cache.load("stage", k) is None
    assert cache.store("stage", k, {"v": 1}) and cache.load("stage", k) == {"v": 1}


def test_a_foreign_entry_is_ignored(tmp_path):
    """An entry copied under another key (or another stage's file) is not taken for this one."""
    cache, k, path = _entry(tmp_path, value=1)
    other = key("stage", 2)
    target = tmp_path / "stage" / other[:2] / f"{other}.json"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(path.read_text())
    assert cache.load("stage", other) is None
    moved = tmp_path / "other" / k[:2] / f"{k}.json"
    moved.parent.mkdir(parents=True)
    moved.write_text(path.read_text())
    assert cache.load("other", k) is None


def test_an_unwritable_cache_costs_only_the_time(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    cache = Cache(blocker / "cache")
    assert cache.store("stage", key("stage"), 1) is False
    assert cache.load("stage", key("stage")) is None
    off = Cache(None)
    assert not off.enabled and off.store("stage", "k", 1) is False and off.load("stage", "k") is None


def test_the_folder_comes_from_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("HYPERSTAT_CACHE", str(tmp_path / "c"))
    assert default_directory() == tmp_path / "c"
    for off in ("off", "0", "none"):
        monkeypatch.setenv("HYPERSTAT_CACHE", off)
        assert default_directory() is None
    monkeypatch.delenv("HYPERSTAT_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_directory() == tmp_path / "xdg" / "hyperstat"


def test_a_process_computing_an_entry_makes_another_wait_then_read_it(tmp_path):
    """Two processes on one entry at once: the second waits for the first's lock, then reads what it stored (the
    same key computed once, e.g. FreeCAD's Analyse and a report of one model, or two test workers)."""
    import subprocess
    import sys
    import time

    store, k = Cache(tmp_path), key("values", {"model": "lock"})
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time\n"
        "from hyperstat.solver.cache import Cache\n"
        f"c = Cache({str(tmp_path)!r})\n"
        f"with c.computing('values', {k!r}):\n"
        "    print('locked', flush=True)\n"
        "    time.sleep(1.0)\n"
        f"    c.store('values', {k!r}, {{'x': 1}})\n")], stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "locked"
    t = time.monotonic()
    with store.computing("values", k):
        waited = time.monotonic() - t
        got = store.load("values", k)
    assert holder.wait(timeout=60) == 0
    assert got == {"x": 1} and waited > 0.3, (got, waited)
    with store.computing("values", k):  # a free lock is taken at once; the lock file is not an entry
        assert store.load("values", k) == {"x": 1}
    with Cache(None).computing("values", k):  # no folder, no lock
        pass
