"""YAML and JSON read strictly: a key declared twice is an error, not "the last one wins".

Units: none (text to Python values).

``yaml.safe_load`` and ``json.loads`` keep the last of two equal keys without a word, so a
file that declares a joint, a reflector prior or a defect twice would be read as one of
them.  These readers refuse it in one sentence naming the file, the key and (for YAML) the
line; JSON's ``NaN`` and ``Infinity`` (not JSON, but accepted by Python's reader) are
refused too.  YAML is read with the safe loader only: no tag constructs an object.

Examples
--------
>>> load_yaml("a: 1\\nb: 2\\na: 3\\n", "t.yaml")
Traceback (most recent call last):
...
hyperstat.solver.errors.DataError: t.yaml: key 'a' is declared twice (line 3).
>>> load_yaml("a: \x1f", "t.yaml")
Traceback (most recent call last):
...
hyperstat.solver.errors.DataError: t.yaml: not valid YAML (unacceptable character #x001f: special characters are not allowed).
>>> load_json('{"x": 1, "x": 2}', "c.json")
Traceback (most recent call last):
...
hyperstat.solver.errors.DataError: c.json: key 'x' is declared twice in one object.
>>> load_json('{"x": 1' + 400 * '0' + '}', "c.json")
Traceback (most recent call last):
...
hyperstat.solver.errors.DataError: c.json: the integer 100000000000...000000 is too large to be a number hyperstat reads.
"""

from __future__ import annotations

import json
from typing import Any

import yaml

from hyperstat.solver.errors import DataError

__all__ = ["load_yaml", "load_json"]


class _UniqueKeyLoader(yaml.SafeLoader):
    """The safe loader, refusing a mapping that repeats a key."""


def _mapping(loader: _UniqueKeyLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    loader.flatten_mapping(node)
    seen: set = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:  # an unhashable key: the base constructor reports it
            break
        if duplicate:
            raise _Duplicate(key, key_node.start_mark.line + 1)
        seen.add(key)
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


def _integer(loader: _UniqueKeyLoader, node: yaml.ScalarNode) -> int:
    value = yaml.SafeLoader.construct_yaml_int(loader, node)
    if abs(value) > LARGEST_INTEGER:
        raise _TooLarge(node.value, node.start_mark.line + 1)
    return value


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping)
_UniqueKeyLoader.add_constructor("tag:yaml.org,2002:int", _integer)
#: integers beyond this are refused when read (a float could not hold them; every number is used as a float)
LARGEST_INTEGER = 2**63


class _TooLarge(Exception):
    def __init__(self, text: str, line: int) -> None:
        super().__init__(text, line)
        self.text, self.line = text, line

    def sentence(self, source: str) -> str:
        shown = self.text if len(self.text) <= 24 else self.text[:12] + "..." + self.text[-6:]
        where = f" (line {self.line})" if self.line else ""
        return f"{source}: the integer {shown} is too large to be a number hyperstat reads{where}."


class _Duplicate(Exception):
    def __init__(self, key: Any, line: int) -> None:
        super().__init__(key, line)
        self.key, self.line = key, line


def load_yaml(text: str, source: str, error: type = DataError) -> Any:
    """Python values of YAML ``text``; refuses invalid YAML and repeated keys, naming ``source``."""
    loader = None
    try:
        loader = _UniqueKeyLoader(text)  # a SafeLoader: no tag constructs an object; it reads the text at once
        return loader.get_single_data()
    except _Duplicate as dup:
        raise error(f"{source}: key {dup.key!r} is declared twice (line {dup.line}).") from None
    except _TooLarge as big:
        raise error(big.sentence(source)) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        first = str(exc).splitlines()[0] if str(exc) else ""
        where = f" (line {mark.line + 1})" if mark is not None else f" ({first})" if first else ""
        raise error(f"{source}: not valid YAML{where}.") from None
    except (ValueError, TypeError, OverflowError) as exc:  # e.g. a timestamp out of range, an unhashable key
        raise error(f"{source}: not valid YAML ({exc.__class__.__name__}: {exc}).") from None
    finally:
        if loader is not None:
            loader.dispose()


def _unique(pairs: list) -> dict:
    out = dict(pairs)
    if len(out) < len(pairs):
        seen: set = set()
        raise _Duplicate(next(k for k, _ in pairs if k in seen or seen.add(k)), 0)
    return out


def _constant(name: str) -> float:
    raise ValueError(f"{name} is not a JSON number")


def _json_integer(text: str) -> int:
    value = int(text)
    if abs(value) > LARGEST_INTEGER:
        raise _TooLarge(text, 0)
    return value


def load_json(text: str, source: str, error: type = DataError) -> Any:
    """Python values of JSON ``text``; refuses invalid JSON, repeated keys, NaN and Infinity."""
    try:
        return json.loads(text, object_pairs_hook=_unique, parse_constant=_constant, parse_int=_json_integer)
    except _Duplicate as dup:
        raise error(f"{source}: key {dup.key!r} is declared twice in one object.") from None
    except _TooLarge as big:
        raise error(big.sentence(source)) from None
    except json.JSONDecodeError as exc:
        raise error(f"{source}: not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg}).") from None
    except ValueError as exc:
        raise error(f"{source}: not valid JSON ({exc}).") from None
    except RecursionError:
        raise error(f"{source}: not valid JSON (nested too deeply).") from None
