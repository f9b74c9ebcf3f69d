# The README's two commands: `make demo` and `make test`. Each creates or reuses
# .venv, installs what it needs, and runs. Nothing else is assumed of the machine
# except python3 (>=3.10); missing system GL/EGL libraries are installed via apt
# when we are root (CI), see tools/ensure_system_deps.sh.

# Python's bytecode cache stays on for these runs even where the environment turns it
# off (PYTHONDONTWRITEBYTECODE=1, as this machine's image does): otherwise every test
# process, CLI subprocess, Ray worker and render child compiles stb_hydra's modules from
# source again (a CLI start 0.9 -> 0.64 s), and each pytest worker rewrites the asserts
# of every test module again (~5 s a worker). __pycache__/ is git-ignored;
# docs/TESTING.md, "Bytecode".
unexport PYTHONDONTWRITEBYTECODE

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.stb_installed
OUT    ?= out
DEMO_FLAGS ?= --lighting stb --accumulate 16
# `make test` runs pytest on pytest-xdist workers, whole modules per worker: by default
# (auto) one per core, at most 2 (the machine measured, docs/TESTING.md); PYTEST_XDIST=N
# runs N, PYTEST_XDIST=0 runs serially in one process.
PYTEST_XDIST ?= auto
PYTEST_WORKERS := $(if $(filter auto,$(PYTEST_XDIST)),$(shell n=$$(nproc 2>/dev/null || echo 1); [ $$n -gt 2 ] && n=2; echo $$n),$(PYTEST_XDIST))
# --no-loadscope-reorder: xdist would hand out modules by test count (most first), which
# put the long one-test modules last while the other worker idled; tests/conftest.py
# orders them (long modules first) and this keeps that order (docs/TESTING.md).
PYTEST_PAR := $(if $(filter-out 0 1,$(PYTEST_WORKERS)),-n $(PYTEST_WORKERS) --dist loadfile --no-loadscope-reorder)

.PHONY: demo test lint bench clean sysdeps

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev,reference,ray,preview]'
	@touch $(STAMP)

sysdeps:
	@sh tools/ensure_system_deps.sh

demo: sysdeps $(STAMP)
	@mkdir -p $(OUT)
	$(VENV)/bin/stb render usd_scenes/default.usda $(OUT)/default.exr --width 745 --height 360 $(DEMO_FLAGS) --verbose
	$(VENV)/bin/stb render usd_scenes/default.usda $(OUT)/default.png --width 745 --height 360 $(DEMO_FLAGS)

test: sysdeps $(STAMP)
	$(VENV)/bin/ruff check stb_hydra tests tools
	$(VENV)/bin/ruff format --check stb_hydra tests tools
	$(VENV)/bin/lint-imports
	$(VENV)/bin/mypy
	$(PY) -m pytest -q -p no:cacheprovider --durations=25 $(PYTEST_PAR)

lint: $(STAMP)
	$(VENV)/bin/ruff check stb_hydra tests tools
	$(VENV)/bin/ruff format --check stb_hydra tests tools
	$(VENV)/bin/lint-imports
	$(VENV)/bin/mypy

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache .ruff_cache .hypothesis .mypy_cache .grimp_cache .import_linter_cache
