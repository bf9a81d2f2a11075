# Two commands set up and use structgen on a fresh machine (see README.md):
#   make run    create .venv, install structgen, run the main job
#   make test   create .venv, install structgen with test extras, run the test suite
PYTHON ?= $(shell command -v python3.11 || command -v python3.10 || command -v python3)
VENV ?= .venv
BIN := $(VENV)/bin
RUN_DIR ?= out

.PHONY: run test install clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

install: $(BIN)/python
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[test]'

run: install
	$(BIN)/structgen grow --seed 0 -o $(RUN_DIR)/structure.json
	$(BIN)/structgen export $(RUN_DIR)/structure.json $(RUN_DIR)/structure.glb
	$(BIN)/structgen info $(RUN_DIR)/structure.json

test: install
	$(BIN)/python -m pytest -q

clean:
	rm -rf $(VENV) $(RUN_DIR)
