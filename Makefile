# hyperstat: `make demo` runs the main job on the built-in default, `make test` runs the tests.
# Both set up everything they need on a fresh machine (Python venv + packages).

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: setup system-deps demo test images bench clean freecad-deps freecad-install freecad-screenshot freecad

# Debian packages the tests drive for real: headless Chromium (report screenshots and PDF),
# poppler-utils (pdftoppm / pdftotext: the printed report's pages), LinuxCNC (genhexkins, and halcompile +
# kinematics.h from linuxcnc-uspace-dev for the generated kinematics module). Installed only when missing;
# sudo when not root.
DEB_PACKAGES := chromium poppler-utils linuxcnc-uspace linuxcnc-uspace-dev
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)

# pip's and setuptools' own chatter goes to .venv/pip.log (shown only if the install fails).
PIPLOG := $(VENV)/pip.log
export PIP_DISABLE_PIP_VERSION_CHECK := 1

# The packages are installed by uv (PyPI 'uv', Astral's installer: parallel downloads, a cache of unpacked wheels,
# bytecode compiled on both cores): the same versions as pip resolves, in about 25 s instead of 54 s on a fresh
# 2-core machine. pip stays in the venv (`make bench`) and is the fallback when uv cannot be installed or fails
# (an index that only pip's configuration knows, for example).
$(STAMP): pyproject.toml
	@echo "setting up $(VENV) (Python packages; log in $(PIPLOG))"
	@$(PYTHON) -m venv $(VENV)
	@{ $(PY) -m pip install --quiet uv >$(PIPLOG) 2>&1 \
	   && $(VENV)/bin/uv pip install --python $(PY) --quiet --compile-bytecode -e '.[test]' >>$(PIPLOG) 2>&1; } \
	  || { echo "uv failed (see $(PIPLOG)); installing with pip" \
	       && $(PY) -m pip install --quiet -e '.[test]' >>$(PIPLOG) 2>&1; } \
	  || { cat $(PIPLOG); exit 1; }
	@touch $(STAMP)

setup: $(STAMP)

system-deps:
	@if ! command -v chromium >/dev/null || ! command -v pdftoppm >/dev/null || ! command -v halrun >/dev/null \
	    || ! command -v halcompile >/dev/null; then \
	  echo "installing Debian packages: $(DEB_PACKAGES)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(DEB_PACKAGES); \
	fi

# The main job on the built-in default: a simulated Tripteor X7 campaign (with an effect the
# rigid model does not know), then the tolerance report and the controller file.
demo: setup
	mkdir -p out/demo
	$(VENV)/bin/hyperstat simulate templates/tripteor_x7.py --effect backlash --out out/demo/measurements.csv \
	  --truth out/demo/truth.json --quiet
	$(VENV)/bin/hyperstat report templates/tripteor_x7.py --data out/demo/measurements.csv \
	  --validation out/demo/measurements.validation.csv --hypotheses templates/tripteor_x7.hypotheses.yaml --out out/demo
	$(VENV)/bin/hyperstat export-controller templates/tripteor_x7.py out/demo/measurements.csv \
	  --validation out/demo/measurements.validation.csv --diagnose --out out/demo/machine.json
	@echo "The report is out/demo/report.html (also report.md, report.json); the controller file out/demo/machine.json."

# The FreeCAD workbench tests run the real FreeCAD: HYPERSTAT_REQUIRE_FREECAD=1 makes them fail, not skip,
# if it is missing.
# -n 2 --dist loadgroup (pytest-xdist): the tests on both cores, a module's tests on one worker, the LinuxCNC tests
# on one worker, one at a time (tests/conftest.py).
test: setup system-deps freecad-deps
	HYPERSTAT_REQUIRE_FREECAD=1 $(PY) -m pytest -q --durations=15 -n 2 --dist loadgroup

# The README's and the docs' pictures (docs/img/, committed), drawn again by the real commands: the templates'
# skeleton drawings, the report's page 1 in Chromium, the accuracy maps (docs/make_images.py), and FreeCAD's
# screenshots (the clicking test). Each NAME.png has NAME.png.json, the command and the words it shows:
# tests/test_docs_images.py fails when a committed picture is stale (older words, or redrawn without its record).
images: setup system-deps
	$(PY) docs/make_images.py
	$(MAKE) freecad-screenshot

# Benchmarks with the peers (pinocchio, PyPI 'pin', in the optional 'bench' extra).
bench: setup
	$(PY) -m pip install --quiet -e '.[bench]'
	$(PY) benchmarks/run.py --markdown out/bench.md

# FreeCAD 0.20 (Debian freecad-python3: freecadcmd and the freecad GUI), Xvfb, and Qt's test module for
# FreeCAD's Python (python3-pyside2.qttest: the GUI tests click with QTest.mouseClick) for the workbench tests.
# Installed with apt-get only when something is missing (sudo when not root), so running it again is a no-op.
FREECAD_PACKAGES := freecad-python3 xvfb xauth python3-pyside2.qttest
freecad-deps:
	@if command -v freecadcmd >/dev/null 2>&1 && command -v freecad >/dev/null 2>&1 \
	    && command -v xvfb-run >/dev/null 2>&1 && command -v xauth >/dev/null 2>&1 \
	    && /usr/bin/python3 -c "from PySide2 import QtTest" >/dev/null 2>&1; then :; else \
	  if [ "$$(id -u)" = 0 ]; then SUDO=; else SUDO=sudo; fi; \
	  echo "installing $(FREECAD_PACKAGES) (apt-get, about a minute)"; \
	  $$SUDO apt-get update -q && \
	  $$SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends $(FREECAD_PACKAGES); \
	fi

# The workbench into FreeCAD's user Mod folder, with the path of .venv/bin/hyperstat recorded.
freecad-install: setup freecad-deps
	$(PY) cad_plugin/freecad/install.py

# FreeCAD's GUI with the workbench; as root, FreeCAD 0.20 dies at start in QtWebEngine's sandbox unless it is turned
# off (docs/freecad.md, "Starting FreeCAD"): only then is it
freecad: freecad-install
	@if [ "$$(id -u)" = 0 ]; then QTWEBENGINE_CHROMIUM_FLAGS=--no-sandbox freecad; else freecad; fi

# docs/img/freecad_*.png (with their records of the words they show): the screenshots of the clicking GUI test
# (FreeCAD under Xvfb, throwaway HOME).
freecad-screenshot: setup freecad-deps
	mkdir -p docs/img
	HYPERSTAT_REQUIRE_FREECAD=1 HYPERSTAT_SCREENSHOTS=$(CURDIR)/docs/img $(PY) -m pytest -q tests/cad_plugin/freecad/test_gui_clicks.py

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis
