# Two commands on a fresh machine: `make demo` and `make test`. Each creates and fills .venv as needed.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
export OPENBLAS_NUM_THREADS := 1
export MAVLINK20 := 1
export MAVLINK_DIALECT := ardupilotmega

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test]'
	touch $@

$(VENV)/.installed-dev: $(VENV)/.installed
	$(PY) -m pip install -q -e '.[dev]'
	touch $@

$(VENV)/.installed-bench: $(VENV)/.installed
	$(PY) -m pip install -q -e '.[test,bench]'
	touch $@

.PHONY: demo test test-slow test-browser bench lint install chromium
install: $(VENV)/.installed

demo: $(VENV)/.installed
	$(VENV)/bin/gcs-monitor demo

test: $(VENV)/.installed
	$(PY) -m pytest

test-slow: $(VENV)/.installed chromium
	$(PY) -m pytest -m slow

test-browser: $(VENV)/.installed chromium
	$(PY) -m pytest -m browser

# Debian's chromium renders the Rerun web viewer for the dashboard screenshot test.
chromium:
	@command -v chromium >/dev/null 2>&1 || (apt-get update -q && apt-get install -y -q chromium)

bench: $(VENV)/.installed-bench
	$(PY) benchmarks/run_all.py

# ruff, mypy strict and the import-linter layer contracts with the project's rules (pyproject
# [tool.ruff], [tool.mypy], [tool.importlinter]); the contracts also run in `make test`
lint: $(VENV)/.installed-dev
	$(VENV)/bin/ruff check gcs_monitor sim_vehicle dashboards benchmarks tests
	$(VENV)/bin/mypy
	$(VENV)/bin/lint-imports
