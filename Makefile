# Quick start: `make demo` or `make test` on a fresh clone; each creates .venv if needed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-$(shell cksum < pyproject.toml | cut -d' ' -f1)
RAY_STAMP := $(VENV)/.ray-$(shell cksum < pyproject.toml | cut -d' ' -f1)

.PHONY: demo test test-fast lint bench clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	# The pinned CPU build first: with no torch installed, the project's own torch>=2.3
	# would pull a multi-GB CUDA build. (torch==2.13.0 is found on this machine's disk.)
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet -e '.[dev]'
	# The arms' control loop in C (the Python law runs where no compiler is).
	$(PY) -c 'import masspush.sim.pushers.compiled as c; c.main()'
	rm -f $(VENV)/.installed-* && touch $(STAMP)

# The tests also run the Ray paths (`--ray`) on a local cluster: the extra, for them only.
$(RAY_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[dev,ray]'
	rm -f $(VENV)/.ray-* && touch $(RAY_STAMP)

demo: $(STAMP)
	$(VENV)/bin/masspush demo

test: $(RAY_STAMP)
	$(PY) -m pytest -q

test-fast: $(RAY_STAMP)
	$(PY) -m pytest -q -m "not slow"

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests experiments
	$(VENV)/bin/ruff format --check src tests experiments

bench: $(STAMP)
	$(VENV)/bin/masspush bench sim

clean:
	rm -rf $(VENV) build src/*.egg-info .pytest_cache .ruff_cache
