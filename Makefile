# The two commands: `make demo` and `make test`. Both create/refresh .venv themselves.
# `make test` runs every test (CI); `make test-fast` is the developer's loop: the Hypothesis `dev`
# profile (a fifth of the examples, tests/helpers/hyp.py), no test marked `slow` and not the
# hostile-input corpus (tests/hostile: CLI processes under limits, ~2.5 min warm), on every core
# (pytest-xdist `-n auto`: ~45 s warm on 2 cores, ~70 s on one).
# PYTEST_ARGS passes more options to either, e.g. `make test-fast PYTEST_ARGS=-x`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
IVSLAM := $(VENV)/bin/ivslam
STAMP  := $(VENV)/.installed
OUT    := out
PYTEST_ARGS ?=

.PHONY: demo test test-fast bench venv clean sample-logs

venv: $(STAMP)

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check --upgrade pip
	$(PY) -m pip install -q --disable-pip-version-check -e '.[dev]'
	@touch $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q $(PYTEST_ARGS)

test-fast: $(STAMP)
	IVSLAM_HYPOTHESIS=dev $(PY) -m pytest -q -n auto -m "not slow and not hostile" $(PYTEST_ARGS)

demo: $(STAMP)
	@bash scripts/demo.sh $(IVSLAM) $(OUT)

bench: $(STAMP)
	$(PY) -m bench

sample-logs: $(STAMP)
	@bash sample_logs/make_samples.sh $(IVSLAM)

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache .hypothesis
	find . -name __pycache__ -prune -exec rm -rf {} +
