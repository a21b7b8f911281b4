# The README's two commands: `make run` and `make test`. Both set up everything they need.
# `make run` installs the core only (no torch, no GPL IEC 61850 library); `make test` adds the
# extras the tests need (pyproject.toml [project.optional-dependencies], named in the README).
SHELL  := bash
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
PIP    := $(PY) -m pip install -q --disable-pip-version-check
CORE   := $(VENV)/.installed-core
FULL   := $(VENV)/.installed-test
TEST_EXTRAS ?= dev,studies,iec61850,docs,notify
RUN_ARGS ?=
# pytest-xdist workers: one per core. Each worker has its own scratch databases, ports (bound to
# port 0) and data directories (tmp_path), so the lanes run side by side.
PYTEST_N ?= auto

.PHONY: run test check setup bench docs docs-serve screenshots clean

$(PY):
	$(PYTHON) -m venv $(VENV)

# pip's "Location" warning (the venv's scripts dir is not on PATH) is expected: the README says so.
$(CORE): pyproject.toml | $(PY)
	$(PIP) -e . 2>&1 | grep -v "^WARNING: Location\|^WARNING: The script" ; test $${PIPESTATUS[0]} -eq 0
	$(PY) -c "import service.estimation.cmaes, numba, comtrade"
	touch $@

$(FULL): pyproject.toml | $(PY)
	$(PIP) -e ".[$(TEST_EXTRAS)]" 2>&1 | grep -v "^WARNING: Location\|^WARNING: The script" ; test $${PIPESTATUS[0]} -eq 0
	$(PY) -c "import service.estimation.cmaes, numba, comtrade, pytest, xdist"
	touch $(CORE) $@

setup: $(FULL)

run: $(CORE)
	$(PY) -m service.cli demo $(RUN_ARGS)

test: $(FULL)
	$(PY) -m pytest -q -n $(PYTEST_N) $(PYTEST_ARGS)

# The inner loop: the core lane alone (no PostgreSQL, Redis, browser or shared-data lane; no
# long study, end-to-end or 10,000-operation checks). `make test` runs them all.
check: $(FULL)
	HVCB_TEST_POSTGRES_URL= HVCB_TEST_REDIS_URL= HVCB_CHROMIUM=/nonexistent HVCB_SHARED_DIR=/nonexistent \
	  $(PY) -m pytest -q -n $(PYTEST_N) -m "not slow and not history10k and not integration" $(PYTEST_ARGS)

# The README's and docs' screenshots, taken by the browser tests from the demo's running chain.
screenshots: $(FULL)
	HVCB_WEB_SCREENSHOTS=docs/screenshots $(PY) -m pytest -q tests/web/test_engineer_pages.py tests/web/test_pages.py

docs: $(FULL)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

docs-serve: $(FULL)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs serve --dev-addr 127.0.0.1:8001

bench: $(CORE)
	$(PY) bench/fit_speed.py

clean:
	rm -rf $(VENV) var site
