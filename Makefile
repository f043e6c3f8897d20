# One-command set-up on a fresh Linux machine with Python 3.11+ and gcc.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
# ecospy loads libtbb from the venv's lib folder; small dense algebra runs in loops: one BLAS thread.
export LD_LIBRARY_PATH := $(abspath $(VENV))/lib:$(LD_LIBRARY_PATH)
export OPENBLAS_NUM_THREADS := 1
export OMP_NUM_THREADS := 1
export MKL_NUM_THREADS := 1

.PHONY: run test bench lint clean

$(PY):
	$(PYTHON) -m venv $(VENV)

$(STAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

run: $(STAMP)
	$(VENV)/bin/excosim fmus build
	$(VENV)/bin/excosim run scenarios/paper-2020.toml

test: $(STAMP)
	$(VENV)/bin/excosim fmus build
	$(PY) -m pytest -q

bench: $(STAMP)
	$(VENV)/bin/excosim fmus build
	@for b in bench/*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

lint: $(STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf build dist *.egg-info .pytest_cache
