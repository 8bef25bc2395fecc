"""Install the Hyperstat workbench into FreeCAD's user module folder (``make freecad-install``).

Units: none.

Run with any Python 3 (the Makefile uses the project's venv)::

    python cad_plugin/freecad/install.py [--freecadcmd freecadcmd] [--cli .venv/bin/hyperstat] [--start-in-workbench]

It asks FreeCAD itself where its user data live (``FreeCAD.getUserAppDataDir()``,
``~/.local/share/FreeCAD/`` on Debian's 0.20), copies the workbench to
``<that>/Mod/Hyperstat`` and records the absolute paths of the ``hyperstat`` command
line and of the templates folder in ``hyperstat_freecad/install.json``, which the
workbench reads when neither ``HYPERSTAT_CLI`` nor the preference is set.  The copy
is staged next to the destination and swapped in with renames, so running it again
replaces a previous install and an interrupted run leaves the previous one intact.
Exit code 2 with one sentence on a user error.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
NAME = "Hyperstat"
#: what goes into the installed workbench (install.py and tools/ stay in the checkout)
CONTENT = ["Init.py", "InitGui.py", "package.xml", "TestHyperstatWorkbench.py", "hyperstat_freecad", "Resources",
           "hyperstat_palette.py", "classes.json"]

_PROBE = """import FreeCAD, sys
if {autoload!r}:
    FreeCAD.ParamGet("User parameter:BaseApp/Preferences/General").SetString("AutoloadModule", {autoload!r})
    FreeCAD.saveParameter()
with open({out!r}, "w", encoding="utf-8") as fh:
    fh.write(FreeCAD.getUserAppDataDir())
sys.exit(0)
"""


class InstallError(Exception):
    """A user-facing installation error (one sentence)."""


def user_app_data_dir(freecadcmd: str, env: dict[str, str] | None = None, autoload: str = "") -> Path:
    """``FreeCAD.getUserAppDataDir()`` as the given ``freecadcmd`` reports it (in environment ``env``).

    With ``autoload`` (a workbench class name), also make FreeCAD start in that workbench.
    """
    exe = shutil.which(freecadcmd)
    if exe is None:
        raise InstallError(f"'{freecadcmd}' not found: install FreeCAD (Debian: apt-get install freecad-python3).")
    with tempfile.TemporaryDirectory(prefix="hyperstat-fc-install-") as tmp:
        out, script = Path(tmp) / "dir.txt", Path(tmp) / "probe.py"
        script.write_text(_PROBE.format(out=str(out), autoload=autoload), encoding="utf-8")
        proc = subprocess.run([exe, str(script)], capture_output=True, text=True, timeout=120, env=env)
        if proc.returncode != 0 or not out.is_file():
            raise InstallError(f"'{exe}' did not report its user data folder (exit code {proc.returncode}).")
        return Path(out.read_text(encoding="utf-8").strip())


def install(mod_dir: Path, cli: Path, templates: Path) -> Path:
    """Copy the workbench to ``mod_dir/Hyperstat`` and write its ``install.json``; return the folder."""
    mod_dir.mkdir(parents=True, exist_ok=True)
    dest = mod_dir / NAME
    stage = Path(tempfile.mkdtemp(prefix=f".{NAME}.", dir=mod_dir))
    try:
        for item in CONTENT:
            src = HERE / item
            if src.is_dir():
                shutil.copytree(src, stage / item, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "install.json"))
            else:
                shutil.copy2(src, stage / item)
        record = {"cli": str(cli), "templates": str(templates), "checkout": str(ROOT),
                  "units": {"length": "mm", "angle": "rad"}}
        (stage / "hyperstat_freecad" / "install.json").write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
        os.chmod(stage, 0o755)
        old = None
        if dest.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{NAME}.old.", dir=mod_dir))
            os.replace(dest, old / NAME)
        os.replace(stage, dest)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    return dest


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Install the Hyperstat FreeCAD workbench.")
    parser.add_argument("--freecadcmd", default=os.environ.get("FREECADCMD", "freecadcmd"),
                        help="FreeCAD's command-line executable (default: freecadcmd)")
    parser.add_argument("--cli", default=str(ROOT / ".venv" / "bin" / "hyperstat"),
                        help="the hyperstat command line to record (default: .venv/bin/hyperstat of this checkout)")
    parser.add_argument("--templates", default=str(ROOT / "templates"), help="templates folder to record")
    parser.add_argument("--start-in-workbench", action="store_true",
                        help="also make FreeCAD start in the Hyperstat workbench (preference AutoloadModule)")
    args = parser.parse_args(argv)
    try:
        cli = Path(args.cli).resolve()
        if not (cli.is_file() and os.access(cli, os.X_OK)):
            raise InstallError(f"{args.cli}: no hyperstat command line there; run 'make setup' first.")
        templates = Path(args.templates).resolve()
        if not templates.is_dir():
            raise InstallError(f"{args.templates}: no such templates folder.")
        autoload = "HyperstatWorkbench" if args.start_in_workbench else ""
        dest = install(user_app_data_dir(args.freecadcmd, autoload=autoload) / "Mod", cli, templates)
    except InstallError as exc:
        sys.stderr.write(f"freecad-install: error: {exc}\n")
        return 2
    print(f"installed the Hyperstat workbench in {dest} (hyperstat command line: {cli})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
