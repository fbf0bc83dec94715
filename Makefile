# torchrl-auv developer commands. Every target sets up .venv/ first (idempotent: re-installs only
# when requirements/lock.txt or pyproject.toml changed).
#   make demo   set up, then train the full framework on quick (recipes/diffusion_lac, runs/)
#   make table3 set up, then run the Table III tracking experiment (recipes/main.py, runs/)
#   make test   set up, then run the test suite (the command CI runs)
#   make bench  set up, then run every benchmark in benchmarks/
#   make docs   set up, then build the documentation site into docs/_build/html (warnings are errors)
#   make lint   ruff check + format check

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

# One torch thread: on the 2-core development machines two threads made torch 4-50x slower.
export OMP_NUM_THREADS ?= 1
export MKL_NUM_THREADS ?= 1
export WANDB_MODE ?= offline
# Test processes (pytest-xdist): one per core of the 2-core machines the suite is sized for; each
# test file runs whole in one process (its module fixtures are built once).
TEST_WORKERS ?= 2

.PHONY: setup demo table3 test test-all bench docs lint clean

setup: $(STAMP)

$(STAMP): requirements/lock.txt pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	# torch first, pinned, so no CUDA build is pulled in by a later resolver run
	$(PY) -m pip install --quiet torch==2.13.0
	$(PY) -m pip install --quiet torch==2.13.0 -r requirements/lock.txt
	$(PY) -m pip install --quiet --no-deps -e .
	touch $(STAMP)

demo: $(STAMP)
	$(PY) recipes/diffusion_lac/train.py --config-name=quick

table3: $(STAMP)
	$(PY) -m recipes.main

test: $(STAMP)
	$(PY) -m pytest -n $(TEST_WORKERS) --dist loadfile

test-all: $(STAMP)
	$(PY) -m pytest -n $(TEST_WORKERS) --dist loadfile --runslow

bench: $(STAMP)
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

docs: $(STAMP)
	rm -rf docs/api/_generated
	$(PY) -m sphinx -W --keep-going -b html docs docs/_build/html

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
