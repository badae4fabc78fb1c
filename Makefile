# The DANAE book.
#   make book    -> creates .venv if missing, renders the notebooks' committed outputs (executes nothing),
#                   writes _build/html/index.html
#   make test    -> unit tests plus every notebook under nbmake (fast mode; DANAE_DATA when set) and
#                   again without data (tests/test_chapters_without_data.py), same venv; one torch
#                   thread per pytest worker (OMP_NUM_THREADS=1): $(JOBS) workers share the cores,
#                   each taking whole files, the run without data first, then the chapters
#                   (tests/conftest.py orders them)
#   make execute -> re-executes in place the chapters whose stored outputs are stale (ARGS=--all: every
#                   chapter; ARGS="--only 03_danae": that one; ARGS=--cold: every network trained anew),
#                   in full mode on real data, storing the outputs that `make book` renders
#                   (python -m tools.execute),
#                   with DANAE_JOBS (default: one worker process per core) parallel trainings and folds.
#                   It needs DANAE_DATA and refuses to run without it (or in fast mode) unless
#                   ARGS="--out DIR" writes the executed copies elsewhere.
# Real data: export DANAE_DATA=/path/to/data (holding oxiod/ and/or ucs/); otherwise the simulator stands in.

PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
JOBS   ?= 2
# worker processes for the chapters' independent trainings and folds (danae_lite.runtime.RunSettings)
EXEC_JOBS ?= $(shell nproc 2>/dev/null || echo 1)
ARGS   ?=
# Trained networks are shared between chapters and runs through the user's cache folder
# (~/.cache/danae_lite/full and /fast, capped; DANAE_CACHE=/path or off, DANAE_CACHE_GB: see
# danae_lite.runtime). make execute ARGS=--cold trains every network in a new empty cache instead.

.PHONY: book execute test unit lab bench clean

$(STAMP): requirements.txt pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11, 5) else "Python >= 3.11.5 is needed (some pinned packages require it); $(PYTHON) is " + sys.version.split()[0] + ": run make PYTHON=/path/to/python3.11")'
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements.txt
	$(BIN)/python -m pip install --quiet --no-deps -e .
	touch $(STAMP)

book: $(STAMP)
	rm -rf _build/html _build/.doctrees _build/jupyter_execute
	$(BIN)/jupyter-book build . -W -n --keep-going
	@echo "Book written to _build/html/index.html"

execute: $(STAMP)
	DANAE_JOBS=$${DANAE_JOBS:-$(EXEC_JOBS)} $(BIN)/python -m tools.execute $(ARGS)

test: $(STAMP)
	DANAE_FAST=$${DANAE_FAST:-1} OMP_NUM_THREADS=$${OMP_NUM_THREADS:-1} $(BIN)/python -m pytest -n $(JOBS) --dist loadfile --no-loadscope-reorder tests notebooks --nbmake --nbmake-timeout=600 --durations=15

unit: $(STAMP)
	OMP_NUM_THREADS=$${OMP_NUM_THREADS:-1} $(BIN)/python -m pytest -n $(JOBS) tests

lab: $(STAMP)
	$(BIN)/jupyter lab notebooks

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py --json _build/benchmarks.json

clean:
	rm -rf _build .pytest_cache .hypothesis
