# The two commands of the README: `make run` and `make test`. Both create .venv if missing.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip

.PHONY: run test lint bench clean

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip

$(VENV)/.installed: $(PY) pyproject.toml
	$(PIP) install -q -e .
	touch $@

$(VENV)/.installed-dev: $(PY) pyproject.toml
	$(PIP) install -q -e '.[dev]'
	touch $@ $(VENV)/.installed

run: $(VENV)/.installed
	$(VENV)/bin/wovenskin run

test: $(VENV)/.installed-dev
	$(VENV)/bin/ruff check wovenskin tests
	$(PY) -m pytest

lint: $(VENV)/.installed-dev
	$(VENV)/bin/ruff check wovenskin tests
	$(VENV)/bin/ruff format --check wovenskin tests

bench: $(VENV)/.installed
	$(VENV)/bin/wovenskin bench io

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache .hypothesis
