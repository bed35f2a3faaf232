# Set-up: `make report` (the main job) and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# the default tier runs on every core (at most 4 worker processes, pytest-xdist); PYTEST_JOBS= runs it in one
PYTEST_JOBS ?= -n auto --maxprocesses=4

.PHONY: venv test lint test-slow report bench clean

$(STAMP): pyproject.toml
	test -d $(VENV) || $(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e ".[all]"
	touch $(STAMP)

venv: $(STAMP)

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q $(PYTEST_JOBS) --durations=15
	OPENBLAS_NUM_THREADS=1 DTTMM_BENCH_QUICK=1 $(BIN)/python -m pytest -q benchmarks --benchmark-disable

lint: $(STAMP)
	$(BIN)/ruff check --fix .
	$(BIN)/ruff format .

test-slow: $(STAMP)
	OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q -m slow

clean:
	rm -rf $(VENV) build *.egg-info

report: $(STAMP)
	OPENBLAS_NUM_THREADS=1 $(BIN)/dttmm report --quick --out out/report --prune-cache

bench: $(STAMP)
	mkdir -p data/bench
	OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest benchmarks -q --benchmark-only \
		--benchmark-json=data/bench/bench-$$(date +%Y%m%d-%H%M%S).json
