# Every target bootstraps .venv itself: a fresh machine needs only python3 (>= 3.11) and make.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: venv run test bench lint paper interop clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

# numba caches compiled kernels on disk; compiling them here (~1 min the first time, ~2 s when cached
# or after an edit to one kernel file) keeps the first compile out of the lockstep loop.
venv: $(STAMP)
	$(BIN)/python -m tools.warm_jit

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

# Third-party GCS interoperability (MAVProxy, MAVSDK-Python): installs the clients, runs their tests.
interop: venv
	$(BIN)/python -m pip install --quiet -e '.[dev,interop]'
	$(BIN)/python -m pytest -q tests/test_interop_mavproxy.py tests/test_interop_mavsdk.py

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache
	find sim autopilot mavlink_bridge tools -name '*.nbi' -delete -o -name '*.nbc' -delete
