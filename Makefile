# Set-up and the two jobs of the README. Only python3 (>= 3.10) is needed; the virtual
# environment is made on first use and filled with what each job needs: the demo the package
# and its plot extra, the tests the developer tools (the dependency group "test") as well.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
# The extension's sources: a change to any of them rebuilds it on the next job.
SOURCES := pyproject.toml setup.py $(wildcard src/diffdrive/backends/*.[ch]) \
	$(wildcard c/src/*.[ch]) $(wildcard c/include/diffdrive/*.h)

.PHONY: demo test test-all docs bench clean

# The tests marked slow (0.4 s or more each: subprocesses, real logs, the benchmarks' smoke
# runs, the firmware under QEMU) take 9 of the suite's 10 minutes on 2 cores. CI (CI set, as
# .ci/run sets it) and `make test-all` run them; elsewhere `make test` leaves them out and
# takes about 2 minutes.
SLOW ?= $(if $(CI),,-m "not slow")

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip  # 25.1 or later reads dependency groups

$(VENV)/.demo: $(SOURCES) | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[plot]'
	touch $@

$(VENV)/.test: $(SOURCES) | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[plot]' --group test
	touch $@

demo: $(VENV)/.demo               ## the main job on the built-in example
	$(BIN)/diffdrive

test: $(VENV)/.test               ## linter, type check, then the test suite (all of it in CI)
	$(BIN)/ruff check
	$(BIN)/ruff format --check
	$(BIN)/mypy
	# One BLAS thread a worker: the workers already fill the cores, and more threads fight.
	# Bytecode cached even where the environment says not to (PYTHONDONTWRITEBYTECODE): each
	# worker and subprocess would otherwise compile the package and rewrite the tests again
	# (collection 6 s instead of 2).
	PYTHONDONTWRITEBYTECODE= OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -n auto --maxprocesses 4 $(SLOW)

test-all:                         ## make test with the slow tests, as CI runs it
	$(MAKE) test SLOW=

$(VENV)/.docs: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --group docs
	touch $@

docs: $(VENV)/.docs               ## the documentation site, strict, into site/ (untracked)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

bench: $(VENV)/.test              ## benchmarks/, with numba and the peer libraries
	$(BIN)/python -m pip install --quiet -e '.[bench]'
	$(BIN)/python benchmarks/bench_simulate.py
	$(BIN)/python benchmarks/bench_odometry.py

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis .ruff_cache build site src/*.egg-info
