# Every target bootstraps .venv itself: a fresh machine needs only python3 (>= 3.11) and make.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: venv run test bench lint paper tune clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

run: venv
	$(BIN)/python -m tools.run_delivery

test: venv
	$(BIN)/python -m pytest -q

bench: venv
	$(BIN)/python -m tools.bench

lint: venv
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

paper: venv
	$(BIN)/python -m tools.paper_table

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache
