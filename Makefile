# The README's two commands: `make demo` and `make test`. Each creates or reuses
# .venv, installs what it needs, and runs. Nothing else is assumed of the machine
# except python3 (>=3.10); missing system GL/EGL libraries are installed via apt
# when we are root (CI), see tools/ensure_system_deps.sh.

PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.stb_installed
OUT    ?= out
DEMO_FLAGS ?= --lighting stb --accumulate 16

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
	$(PY) -m pytest -q -p no:cacheprovider --durations=25

lint: $(STAMP)
	$(VENV)/bin/ruff check stb_hydra tests tools
	$(VENV)/bin/ruff format --check stb_hydra tests tools
	$(VENV)/bin/lint-imports
	$(VENV)/bin/mypy

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache .ruff_cache .hypothesis .mypy_cache .grimp_cache .import_linter_cache
