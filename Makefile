# thrustwalk: two commands on a fresh machine with only Python:
#   make demo   -> .venv, install, the one-time compile of the simulation kernel, limit
#                  cycles of the bundled 3-link robot and gait
#   make test   -> .venv, install with the test dependencies (and MuJoCo) while the
#                  simulation kernel compiles once for this checkout's tests (with a message),
#                  the whole test suite on every core (pytest-xdist)
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
BASE   := $(VENV)/.installed
STAMP  := $(VENV)/.installed-test
# pytest-xdist workers: one more than the cores, since about a third of the suite's time is
# spent waiting on the processes tests start (CLI runs, worker pools, Dask clusters);
# `make test TEST_WORKERS=0` runs in one process
TEST_WORKERS ?= $(shell echo $$(( $$(nproc 2>/dev/null || echo 1) + 1 )))

.PHONY: demo test bench lint docs figures golden clean

# what the simulation kernel needs to compile (the specifiers of pyproject.toml's dependencies;
# tests/test_packaging.py checks that they are the same)
KERNEL_DEPS := "numpy>=1.24" "scipy>=1.10" "numba>=0.59" "pyyaml>=6.0"

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# The package's bytecode is compiled once here: an editable install leaves it to the first
# import, which cannot keep it where PYTHONDONTWRITEBYTECODE is set (as on this build machine), so every
# process (each command, test worker and sweep worker) would compile the package's ~45,000 lines
# again (about 0.9 s of CPU each); pip compiles the dependencies' bytecode itself.
PYC := $(BIN)/python -m compileall -q thrustwalk_cli tests

$(BASE): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	$(PYC)
	touch $(BASE)

# The test set-up installs without compiling the dependencies' bytecode (pip would compile all
# of it, ~11,000 files and 40 s of CPU, their test suites included); the bytecode of what the
# tests import is written as they import it, once (PYTHONDONTWRITEBYTECODE emptied for the set-up
# and the test run, whatever the machine sets): here by the kernel's compile and by collecting
# the tests (which imports every test module, rewritten by pytest, and what they import), the
# rest by the first test process that imports it. `make bench` writes it too, so that the
# processes it times import from bytecode as a user's do.
WRITE_PYC := PYTHONDONTWRITEBYTECODE=

# the kernel's own dependencies first; then, while pip installs the package and the test
# dependencies and the tests are collected, the simulation kernel compiles for the tests from
# the source tree (once per checkout, into .pytest_cache/thrustwalk-kernel; tests/kernel_cache.py
# says so)
$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --no-compile $(KERNEL_DEPS)
	$(PYC)
	$(WRITE_PYC) PYTHONPATH=$(CURDIR) $(BIN)/python tests/kernel_cache.py & kernel=$$!; \
	$(BIN)/python -m pip install --quiet --no-compile -e '.[test,mujoco]' && \
	$(WRITE_PYC) MPLBACKEND=Agg $(BIN)/python -m pytest -q --collect-only -p no:xdist > /dev/null; \
	status=$$?; wait $$kernel; exit $$status
	touch $(BASE) $(STAMP)

# `thrustwalk compile` compiles the simulation kernel into the user's cache if this machine
# has not (saying so, ~30 s), so that the first `thrustwalk simulate` starts at once
demo: $(BASE)
	$(BIN)/thrustwalk compile three_link
	$(BIN)/thrustwalk limit-cycle three_link three_link_walk --thrust 0:-50:-2 --out out/demo

# each test to the next free worker, slow ones first; the tests of a module with a
# module-scoped fixture stay in one worker (tests/conftest.py)
test: $(STAMP)
	$(PYC)
	$(WRITE_PYC) MPLBACKEND=Agg $(BIN)/python -m pytest -q -n $(TEST_WORKERS)
	$(BIN)/ruff check .

bench: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[bench]' || echo "bench extra (pin) not installed: the Pinocchio comparison prints 'skipped'"
	$(WRITE_PYC) MPLBACKEND=Agg $(BIN)/python bench/run.py

lint: $(STAMP)
	$(BIN)/ruff check .

docs: $(STAMP)
	$(BIN)/python -m thrustwalk_cli.files.schema_docs docs/files.md

# the golden documents of tests/test_golden.py, after a change meant to change results
golden: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python tests/golden_cases.py --update

# ---------------------------------------------------------------------------- figures
# `make figures` (or `make -j2 figures`) runs thrustwalk commands into $(FIG); each result
# depends on the robot and gait files it uses (and the tool's code), so editing a gait
# rebuilds only the figures made from it.
# Sweep settings can be overridden (the test suite runs a reduced pipeline this way).
FIG        ?= figures
TW         ?= $(BIN)/thrustwalk
TW_DEP     ?= $(BASE)
R3         := robots/three_link.yaml
G3         := gaits/three_link_walk.yaml
LC_THRUST  ?= 0:-50:-2
SHAPE_K    ?= 0:50:2
FIELD_K    ?= 60

FEAS_THRUST ?= 0:-50:-10
SIM_STEPS  ?= 30
SIM_THRUST ?= 0:-50:-2

# results depend on the tool's code too: editing it rebuilds every figure
CODE       := $(shell find thrustwalk_cli -name "*.py" -o -name "*.mplstyle")

FIGURE_JSON = $(FIG)/limit_cycle/limit_cycles.json $(FIG)/shape/shape.json \
	$(FIG)/feasibility/feasibility.json $(FIG)/simulate/simulation.json

# The figures' result files record the time of the last commit of the robot and gait files
# instead of the clock, so rerunning the pipeline on unchanged inputs rewrites every file byte
# for byte and leaves `git status` clean.
figures: export SOURCE_DATE_EPOCH ?= $(shell git log -1 --format=%ct -- robots gaits 2>/dev/null)
figures: $(FIG)/index.md

$(FIG)/index.md: $(FIGURE_JSON)
	$(TW) report $(FIG) --title "thrustwalk: figures of the paper and beyond" -q

$(FIG)/limit_cycle/limit_cycles.json: $(R3) $(G3) $(CODE) | $(TW_DEP)
	$(TW) limit-cycle $(R3) $(G3) --thrust $(LC_THRUST) --out $(FIG)/limit_cycle -q

$(FIG)/shape/shape.json: $(R3) $(G3) $(CODE) | $(TW_DEP)
	$(TW) shape $(R3) $(G3) --pattern 'k*(j-2)' --k $(SHAPE_K) --field-k $(FIELD_K) \
		--out $(FIG)/shape -q

$(FIG)/feasibility/feasibility.json: $(R3) $(G3) $(CODE) | $(TW_DEP)
	$(TW) feasibility $(R3) $(G3) --thrust $(FEAS_THRUST) --mu 0.7 --out $(FIG)/feasibility -q

$(FIG)/simulate/simulation.json: $(R3) $(G3) $(CODE) | $(TW_DEP)
	$(TW) simulate $(R3) $(G3) --steps $(SIM_STEPS) --thrust-model second-order \
		--thrust $(SIM_THRUST) --wn 2 --xi 1 --out $(FIG)/simulate -q

clean:
	rm -rf $(VENV) out .pytest_cache
