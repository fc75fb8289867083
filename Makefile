# Motion Studio — two commands do all set-up on a fresh machine:
#   make studio   install if needed, then serve http://127.0.0.1:8080 with the default robot
#   make test     install if needed (and Debian's chromium for the browser tests), run every test
#   make typecheck  mypy over engine/ and studio/ (part of make test)
#   make test-fast  the development tier: unit, property and fuzz tests, without the `slow` (long runs: walks,
#                   training, Ray, whole CLI runs) and `e2e` (browser) tiers, on one pytest-xdist worker per
#                   core (at most 4; FAST_WORKERS=N to choose, FAST_WORKERS=0 for one process)

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
SUDO   := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
PYTEST_ARGS ?=

.PHONY: setup studio test test-fast typecheck chromium bench clean-cache

setup: $(STAMP)

# torch first, pinned to the CPU wheel on this disk, so nothing pulls a multi-GB CUDA build.
$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q torch==2.13.0
	$(PY) -m pip install -q -e '.[test]'
	# the control stack's compiled kernels (numba): compiled once here and cached on disk, not in the first walk
	$(PY) -c "from engine.compiled_kernels import warm_up; warm_up()"
	@touch $(STAMP)

studio: setup
	$(VENV)/bin/studio serve

chromium:
	@command -v chromium >/dev/null 2>&1 || { $(SUDO) apt-get update -qq && $(SUDO) apt-get install -y -qq chromium; }

# every test: the fast tier, `slow` and `e2e`
test: setup chromium typecheck
	$(PY) -m pytest -q $(PYTEST_ARGS)

# the type checker over engine/ and studio/ (settings in pyproject.toml [tool.mypy]): zero errors
typecheck: setup
	$(PY) -m mypy

# pytest-xdist: `auto` = the physical cores, capped by --maxprocesses (each worker holds ≈ 1 GB: torch, pinocchio,
# MuJoCo, the robot models); worksteal: tests go out one by one and an idle worker takes queued tests from the
# busy one, which matters with tests of 5 ms next to tests of 35 s (figures in the README, Tests and speed).
FAST_WORKERS ?= auto
test-fast: setup
	$(PY) -m pytest -q -m "not slow and not e2e" -n $(FAST_WORKERS) --maxprocesses 4 --dist worksteal $(PYTEST_ARGS)

bench: setup
	$(VENV)/bin/studio bench

clean-cache:
	rm -rf "$${XDG_CACHE_HOME:-$$HOME/.cache}/motion-studio"
