# hyperstat: `make demo` runs the main job on the built-in default, `make test` runs the tests.
# Both set up everything they need on a fresh machine (Python venv + packages).

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: setup demo test images bench clean

TEMPLATE_NAMES := slider_crank tripteor_x7 triflex_ii scara hexapod

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

setup: $(STAMP)

demo: setup
	$(VENV)/bin/hyperstat analyze templates/slider_crank.py --verify --exact

test: setup
	$(PY) -m pytest -q

# Pictures of every template with its markers coloured by verdict (docs/img/, committed).
images: setup
	mkdir -p out docs/img
	for t in $(TEMPLATE_NAMES); do \
	  $(VENV)/bin/hyperstat analyze templates/$$t.py --json out/$$t.analysis.json --quiet && \
	  $(VENV)/bin/hyperstat view templates/$$t.py --analysis out/$$t.analysis.json --png docs/img/$$t.png || exit 1; \
	done

bench: setup
	$(PY) benchmarks/run.py

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis
