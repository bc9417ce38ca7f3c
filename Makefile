# The two commands: `make demo` and `make test`. Both create/refresh .venv themselves.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
IVSLAM := $(VENV)/bin/ivslam
STAMP  := $(VENV)/.installed
OUT    := out

.PHONY: demo test bench venv clean sample-logs

venv: $(STAMP)

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --disable-pip-version-check --upgrade pip
	$(PY) -m pip install -q --disable-pip-version-check -e '.[dev]'
	@touch $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q

demo: $(STAMP)
	@bash scripts/demo.sh $(IVSLAM) $(OUT)

bench: $(STAMP)
	$(PY) -m bench

sample-logs: $(STAMP)
	@bash sample_logs/make_samples.sh $(IVSLAM)

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache .hypothesis
	find . -name __pycache__ -prune -exec rm -rf {} +
