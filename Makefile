# Two commands set up and use structgen on a fresh machine (see README.md):
#   make run    create .venv, install structgen, run the main job (a short evolution run; prints its run folder)
#   make test   create .venv, install structgen with test tools, run the test suite
PYTHON ?= $(shell command -v python3.11 || command -v python3.10 || command -v python3)
VENV ?= .venv
BIN := $(VENV)/bin
# Extra options for the main job, e.g. make run ARGS="--generations 10 --seed 3"
ARGS ?=

.PHONY: run test install clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

install: $(BIN)/python
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[test]'

run: install
	$(BIN)/structgen evolve $(ARGS)

test: install
	$(BIN)/python -m pytest -q

clean:
	rm -rf $(VENV) runs
