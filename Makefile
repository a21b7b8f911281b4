# The README's two commands: `make run` and `make test`. Both set up everything they need.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
PIP    := $(VENV)/bin/pip
STAMP  := $(VENV)/.installed
EXTRAS ?= dev,studies,iec61850,plots,docs

.PHONY: run test setup bench docs docs-serve clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --disable-pip-version-check --upgrade pip 2>&1 | grep -v "^WARNING: Location" || true
	$(PIP) install -q --disable-pip-version-check -e ".[$(EXTRAS)]" 2>&1 | grep -v "^WARNING: Location" || true
	$(PY) -c "import service, numba, cma, comtrade"
	touch $(STAMP)

setup: $(STAMP)

run: $(STAMP)
	$(PY) -m service.cli demo

test: $(STAMP)
	$(PY) -m pytest -q $(PYTEST_ARGS)

docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

docs-serve: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs serve --dev-addr 127.0.0.1:8001

bench: $(STAMP)
	$(PY) bench/fit_speed.py

clean:
	rm -rf $(VENV) var site
