# Set-up and the two jobs of the README. Only python3 (>= 3.10) is needed; the virtual
# environment is made and filled on first use.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin

.PHONY: demo test bench clean

$(BIN)/diffdrive: pyproject.toml setup.py src/diffdrive/backends/_odometry.c
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

demo: $(BIN)/diffdrive            ## the main job on the built-in example
	$(BIN)/diffdrive

test: $(BIN)/diffdrive            ## linter, type check, then the whole test suite
	$(BIN)/ruff check
	$(BIN)/ruff format --check
	$(BIN)/mypy
	$(BIN)/python -m pytest

bench: $(BIN)/diffdrive           ## benchmarks/, with numba and the peer libraries
	$(BIN)/python -m pip install --quiet -e '.[bench]'
	$(BIN)/python benchmarks/bench_simulate.py
	$(BIN)/python benchmarks/bench_odometry.py

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis .ruff_cache build src/*.egg-info
