# thrustwalk: two commands on a fresh machine with only Python:
#   make demo   -> .venv, install, limit cycles of the bundled 3-link robot and gait
#   make test   -> .venv, install with test dependencies, whole test suite
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test bench lint docs clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/thrustwalk limit-cycle three_link three_link_walk --thrust 0:-50:-2 --out out/demo

test: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python -m pytest -q
	$(BIN)/ruff check .

bench: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python bench/run.py

lint: $(STAMP)
	$(BIN)/ruff check .

docs: $(STAMP)
	$(BIN)/python -m thrustwalk_cli.docs README.md

clean:
	rm -rf $(VENV) out .pytest_cache
