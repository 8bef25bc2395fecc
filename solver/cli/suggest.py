"""'Did you mean ...?' for mistyped commands, options and names (difflib's close matches).

Units: none.

:class:`SuggestingParser` is the ``hyperstat`` argument parser: a mistyped command
(``hyperstat analyse``) or option (``hyperstat report T --outt DIR``) is refused with the
usage of the command at fault and the closest valid word.  :func:`did_you_mean` serves the
same for other names (template parameters).

>>> did_you_mean("dpeth", ["depth", "stroke", "section"])
" (did you mean 'depth'?)"
>>> did_you_mean("zzz", ["depth"])
''
"""

from __future__ import annotations

import argparse
import difflib
import re
from typing import Iterable

__all__ = ["did_you_mean", "closest", "SuggestingParser"]


def closest(word: str, choices: Iterable[str]) -> str | None:
    """The valid word closest to ``word`` (case-insensitive ratio >= 0.6), or None."""
    choices = [str(c) for c in choices]
    lower = {c.lower(): c for c in choices}
    if word.lower() in lower:
        return lower[word.lower()]
    found = difflib.get_close_matches(word.lower(), list(lower), n=1, cutoff=0.6)
    return lower[found[0]] if found else None


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` for the closest valid word, or ``""`` when none is close."""
    match = closest(word, choices)
    return f" (did you mean '{match}'?)" if match is not None and match != word else ""


def _option_strings(parser: argparse.ArgumentParser) -> list[str]:
    return [s for a in parser._actions for s in a.option_strings if s.startswith("--")]


class SuggestingParser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` whose errors name the closest valid command or option.

    An unknown option is reported by the sub-command it was given to (its usage, not the
    top-level one), with the closest option of that sub-command.
    """

    def parse_args(self, args=None, namespace=None):  # noqa: D102 - argparse's
        ns, extras = self.parse_known_args(args, namespace)
        if extras:
            parser = self._chosen(ns)
            hint = ""
            for word in extras:
                if word.startswith("--"):
                    hint = did_you_mean(word.split("=", 1)[0], _option_strings(parser))
                    if hint:
                        break
            parser.error(f"unrecognized arguments: {' '.join(extras)}{hint}")
        return ns

    def _chosen(self, ns) -> argparse.ArgumentParser:
        """The sub-command's parser that ``ns`` was parsed by (this parser when there is none)."""
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                chosen = getattr(ns, action.dest, None)
                if chosen in action.choices:
                    return action.choices[chosen]
        return self

    def parse_known_args(self, args=None, namespace=None):  # noqa: D102 - argparse's
        import sys

        self._given = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def error(self, message: str):  # noqa: D102 - argparse's
        m = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if m:
            message += did_you_mean(m.group(1), re.findall(r"'([^']*)'", m.group(2)))
        elif "unrecognized arguments" not in message:  # e.g. '--out' required because '--outt' was typed
            known = _option_strings(self)
            for word in getattr(self, "_given", []):
                word = word.split("=", 1)[0]
                if word.startswith("--") and not any(k.startswith(word) for k in known):
                    hint = did_you_mean(word, known)
                    if hint:
                        message += f"; '{word}' is not an option{hint}"
                        break
        super().error(message)
