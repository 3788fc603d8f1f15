# Every target bootstraps .venv itself: a fresh machine needs only python3 (>= 3.11) and make.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: venv run run-fleet test bench encounters lint paper interop screenshot clean

# The first setup takes about 1.5 min (pip ~1 min, then the kernel compile ~35 s in two processes); it says what it does.
# MAVProxy (interop tests) comes without its GUI dependencies: --no-deps, its console's needs listed with it.
INTEROP_REQUIREMENTS := tests/interop_clients/requirements.txt
$(STAMP): pyproject.toml $(INTEROP_REQUIREMENTS)
	@echo "[setup] creating $(VENV) and installing quadsitl with its dependencies (pip, about 1 min the first time)..."
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,campaign]'
	$(BIN)/python -m pip install --quiet --no-deps -r $(INTEROP_REQUIREMENTS)
	touch $(STAMP)
	@echo "[setup] packages installed"

# numba caches compiled kernels on disk, in a directory keyed by every kernel source (docs/performance.md);
# compiling them here (~35 s the first time or after an edit to a kernel source, ~2 s when cached) keeps the first
# compile out of the lockstep loop. The project's own modules are byte-compiled here too (under a second): where
# PYTHONDONTWRITEBYTECODE is set (as on the CI machine) Python never writes them itself, and every process a test
# run starts (hundreds) would compile them again, 0.5 s of CPU each. Python still reads the files, and ignores a
# stale one (an edited source).
venv: $(STAMP)
	@PYTHONDONTWRITEBYTECODE= $(BIN)/python -m compileall -q autopilot sim mavlink_bridge tools quadsitl_cli.py
	@$(BIN)/python -m tools.warm_jit

run: venv
	$(BIN)/python -m tools.run --world missions/delivery.yaml --speed max

# A fleet end to end: missions/depot_fleet.yaml (four x500s from one depot, crossing routes, a helicopter), one
# simulator, one autopilot per vehicle, the ground station flying all of them (docs/traffic.md).
run-fleet: venv
	$(BIN)/python -m tools.run --world missions/depot_fleet.yaml --speed max

# Two pytest workers (pytest-xdist), one per core: a lockstep flight is a ping-pong between two processes that
# keeps about one core busy, so two test files fly side by side (docs/testing.md has the timings). Each file runs
# whole on one worker (--dist loadfile: a module's shared fixture is built once).
test: venv
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=10

bench: venv
	$(BIN)/python -m tools.benchmarks

# The encounter Monte Carlo (issue 28, docs/traffic.md): both campaigns about 3 h on 2 cores when the VM is fast,
# up to 10 h when it is slow, so they are flown over several sittings into the folders committed in
# bench/campaigns/: each run flies only the cases they have no row for yet (Ctrl-C loses only the cases in flight),
# then prints the keys and whether every row was flown by the flight code at HEAD (after a change to it:
# rm -r bench/campaigns/encounters*, and fly them again). A campaign's exit status 1 (some cases failed: most
# warn-only ones lose separation) is what they measure; any other failure (usage, Ctrl-C) stops here.
ENCOUNTERS := bench/campaigns
encounters: venv
	@for c in encounters encounters_warn_only; do \
	  resume=; [ -f $(ENCOUNTERS)/$$c/campaign.yaml ] && resume=--resume; \
	  $(BIN)/python -m tools.campaign.cli missions/campaigns/$$c.yaml --out $(ENCOUNTERS)/$$c $$resume; \
	  rc=$$?; [ $$rc -eq 0 ] || [ $$rc -eq 1 ] || exit $$rc; \
	done
	$(BIN)/python -m tools.benchmarks.encounters --avoid-dir $(ENCOUNTERS)/encounters \
	  --warn-dir $(ENCOUNTERS)/encounters_warn_only

lint: venv
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

paper: venv
	$(BIN)/python -m tools.research.paper_table

# Third-party GCS interoperability (MAVProxy, MAVSDK-Python, dev dependencies): only their tests (`make test` runs
# them too).
interop: venv
	$(BIN)/python -m pytest -q tests/sitl/test_interop_mavproxy.py tests/sitl/test_interop_mavsdk.py

# Refresh docs/recording_web_viewer.png: fly the city-block delivery and screenshot its recording in Rerun's
# web viewer with headless Chromium (software rendering, no GPU). Needs Chromium, which `make test` does not:
#   apt-get update && apt-get install -y chromium
screenshot: venv
	$(BIN)/python -m tools.screenshot

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .ruff_cache
	find sim autopilot mavlink_bridge tools -name '*.nbi' -delete -o -name '*.nbc' -delete
	rm -rf "$${XDG_CACHE_HOME:-$$HOME/.cache}/quadsitl/numba"
