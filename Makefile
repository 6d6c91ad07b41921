# Two entry points (see README): `make demo` and `make test`. Both create .venv on first use.
# `make bench` runs the benchmarks in their own .venv-bench (the peers they compare against, mink
# and placo, pin other versions of our dependencies: placo requires pin == 3.8.0) and writes
# benchmarks/RESULTS.md.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
BENCH_VENV  := .venv-bench
BENCH_STAMP := $(BENCH_VENV)/.installed

.PHONY: demo test bench mutate clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,cluster]'
	touch $(STAMP)

$(BENCH_STAMP): pyproject.toml
	$(PYTHON) -m venv $(BENCH_VENV)
	$(BENCH_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(BENCH_VENV)/bin/python -m pip install --quiet -e '.[bench]'
	touch $(BENCH_STAMP)

demo: $(STAMP)
	$(BIN)/robot-ctrl drawer --robot talos --distance 2.0 --slot front_left --out runs/drawer

# The physics tests in two processes; the ones that keep wall-clock time after them, alone.
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 -m "not realtime"
	$(BIN)/python -m pytest -q -m realtime

bench: $(BENCH_STAMP)
	$(BENCH_VENV)/bin/python benchmarks/run_all.py

# Mutation testing of the reports and the hardware-safety code with the fast tests ([tool.mutmut] in
# pyproject.toml; docs/testing.md). Not part of `make test` or CI.
mutate: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[dev,cluster,mutate]'
	$(BIN)/mutmut run --max-children 2
	$(BIN)/mutmut results

clean:
	rm -rf $(VENV) $(BENCH_VENV) runs mutants
