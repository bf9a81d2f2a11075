# Two commands set up and use structgen on a fresh machine (see README.md):
#   make run    create .venv, install structgen, run the main job (a short evolution run; prints its run folder)
#   make test   create .venv, install structgen with test and docs tools, lint, build the docs, run the whole suite
# For the edit loop: make test-fast (the suite without the tests marked slow), make format (ruff formats the code);
# make test-all also compiles with torch.compile's code generation (minutes more on a CPU).
PYTHON ?= $(shell command -v python3.11 || command -v python3.10 || command -v python3)
VENV ?= .venv
BIN := $(VENV)/bin
# Extra options for the main job, e.g. make run ARGS="--generations 10 --seed 3"
ARGS ?=

.PHONY: run test test-fast test-all lint docs format install clean results-check

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

# Installed once, and again when what it depends on changes (structgen itself is installed editable).
$(VENV)/.installed: $(BIN)/python pyproject.toml constraints.txt
	@echo "installing structgen, its test and docs tools into $(VENV) (a few minutes the first time)"
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[test,docs]'
	@echo "compiling the domains' numba kernels (numba keeps them; a few minutes the first time)"
	$(BIN)/python -c "from structgen.registry import compile_kernels; compile_kernels()"
	@touch $@

install: $(VENV)/.installed

run: install
	$(BIN)/structgen evolve $(ARGS)

lint: install
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

# The site is built into a scratch folder: the check is that it builds without a warning (strict; not --quiet, which
# hides the warnings from the count that strict fails on).
docs: install
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site

test: lint docs
	$(BIN)/python -m pytest -q -n 2 --dist loadgroup

test-all: lint
	$(BIN)/python -m pytest -q -n 2 --dist loadgroup --run-inductor

test-fast: install
	$(BIN)/python -m pytest -q -n 2 --dist loadgroup -m "not slow"

# The indexed results (docs/results/README.md) re-derived from the committed files at a reduced scale; CHEAP=1 runs
# the checks that take seconds (CI does).
results-check: install
	$(BIN)/python benchmarks/results_check.py $(if $(CHEAP),--cheap,)

format: install
	$(BIN)/ruff check --fix .
	$(BIN)/ruff format .

clean:
	rm -rf $(VENV) runs site
