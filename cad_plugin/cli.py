"""The ``hyperstat`` console script: the solver's commands plus CAD sources and commands.

Units: lengths in mm, angles in rad.
"""

from __future__ import annotations

import sys
from pathlib import Path

from solver import cli as solver_cli
from solver.model import Mechanism

__all__ = ["main"]


def _load_template(path: Path, overrides: list[str]) -> tuple[Mechanism, dict]:
    from .templates import build_template

    skeleton = build_template(path, overrides)
    mech = skeleton.mechanism()
    return mech, {"source": str(path), "kind": "template", "parameters": mech.metadata.get("parameters", {})}


solver_cli.register_source(".py", _load_template)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``hyperstat`` command."""
    parser = solver_cli.build_parser()
    return solver_cli.main(argv, parser)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
