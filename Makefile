# The README's two commands. Each creates .venv with the machine's python3, installs what it needs, runs.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
# Where the command is after an install, as the README says (tests/test_readme.py runs that way).
ON_PATH := the cvstereo command is in $(BIN)/: run '. $(BIN)/activate' in each new shell, or call $(BIN)/cvstereo

.PHONY: demo test lint bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# Stamp files: reinstall only when pyproject.toml changes. After installing, `cvstereo warm-up` compiles every
# matcher's kernels into numba's cache, so that no later run (nor test) stalls compiling at its first match.
$(VENV)/.demo-installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e ".[viz,sweep]"
	$(BIN)/python -m cvstereo warm-up
	@echo "$(ON_PATH)"
	touch $@

$(VENV)/.test-installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	$(BIN)/python -m cvstereo warm-up
	@echo "$(ON_PATH)"
	touch $@

demo: $(VENV)/.demo-installed
	$(BIN)/python -m cvstereo demo

test: $(VENV)/.test-installed
	$(BIN)/python -m pytest -n 2 -q

lint: $(VENV)/.test-installed
	$(BIN)/ruff check .

bench: $(VENV)/.test-installed
	$(BIN)/python -m cvstereo bench -o bench

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache
