# One-command set-up on a fresh Linux machine with Python 3.11+ and gcc.
# Installs come from the lock (requirements/*.txt: exact versions with hashes, nothing else):
# `make run` installs what running needs, `make test` and `make bench` add the test extra.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip install --quiet --no-deps --require-hashes
RUN_STAMP := $(VENV)/.run-installed
TEST_STAMP := $(VENV)/.test-installed
# ecospy loads libtbb from the venv's lib folder; small dense algebra runs in loops: one BLAS thread.
export LD_LIBRARY_PATH := $(abspath $(VENV))/lib:$(LD_LIBRARY_PATH)
export OPENBLAS_NUM_THREADS := 1
export OMP_NUM_THREADS := 1
export MKL_NUM_THREADS := 1

.PHONY: run test test-all bench lint docs lock clean

$(PY):
	$(PYTHON) -m venv $(VENV)

# The project itself: editable, built with the locked setuptools (no build isolation, which would
# fetch whatever setuptools is newest that day), with no dependency resolution of its own;
# setup.py compiles the FMUs and native libraries into fmus/_built/ (gcc is needed here only):
# after an edit of what they are compiled from, the install runs again (and recompiles that).
NATIVE_SOURCES := $(wildcard fmus/*/*.[ch] fmus/*/variables.toml fmus/shared/*/*.[ch] \
    planner/native/*.c orchestrator/*/native/*.c) $(addprefix fmus/,builder.py codegen.py \
    codegen3.py table.py toolchain.py shared_library.py prebuild.py)
$(RUN_STAMP): pyproject.toml setup.py $(NATIVE_SOURCES) requirements/run.txt | $(PY)
	$(PIP) -r requirements/run.txt
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	$(PY) -m pip check
	touch $@

$(TEST_STAMP): $(RUN_STAMP) requirements/test.txt
	$(PIP) -r requirements/test.txt
	$(PY) -m pip check
	touch $@

run: $(RUN_STAMP)
	$(VENV)/bin/excosim fmus build
	$(VENV)/bin/excosim run scenarios/paper-2020.toml

# The fast set (tests not marked slow: minutes on 2 cores); test-all runs everything (CI does).
test: $(TEST_STAMP)
	$(VENV)/bin/excosim fmus build
	$(PY) -m pytest -q -m "not slow"

test-all: $(TEST_STAMP)
	$(VENV)/bin/excosim fmus build
	$(PY) -m pytest -q

bench: $(TEST_STAMP)
	$(VENV)/bin/excosim fmus build
	@for b in bench/*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

lint: $(TEST_STAMP)
	$(VENV)/bin/ruff check .

# The documentation site (docs/, mkdocs.yml) into site/; the reference pages are generated from
# the code (docs/gen_reference.py) as it builds. Warnings are errors, as in the suite.
docs: $(TEST_STAMP)
	$(VENV)/bin/mkdocs build --strict

# Refresh the lock to the newest versions that pyproject.toml's ranges allow (docs/guide/development.md: "The lock").
UV_VERSION := 0.13.8
lock:
	$(PYTHON) -m venv .venv-lock
	.venv-lock/bin/python -m pip install --quiet uv==$(UV_VERSION)
	.venv-lock/bin/uv pip compile --quiet --upgrade --generate-hashes --extra test --extra docs \
	    pyproject.toml requirements/build.in -o requirements/test.txt
	.venv-lock/bin/uv pip compile --quiet --upgrade --generate-hashes -c requirements/test.txt \
	    pyproject.toml requirements/build.in -o requirements/run.txt

clean:
	rm -rf build dist *.egg-info .pytest_cache .venv-lock
