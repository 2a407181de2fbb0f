# Two commands for a fresh machine (README):  make demo   |   make test
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: install demo test test-fast bench lint clean chromium compiler

# setuptools says "Editable installation ... be careful with folders named as your
# package" on every editable install (an InformationOnly note, a UserWarning): silenced
# here only. tests/test_packaging.py builds the wheel with warnings on and fails on a
# real packaging warning.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	PYTHONWARNINGS=ignore::UserWarning $(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/sixplus3 demo

# The MeshCat playback test renders a page in Debian's headless Chromium.
chromium:
	@command -v chromium >/dev/null 2>&1 || { \
	  echo "installing Debian's chromium for the playback test"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; }

# The planner compiles its constraint functions with gcc (dynamics/codegen.py); a test
# checks the compiled library, so make sure a C compiler is there.
compiler:
	@command -v gcc >/dev/null 2>&1 || command -v cc >/dev/null 2>&1 || { \
	  echo "installing Debian's gcc for the planner's compiled functions"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gcc >/dev/null; }

# ruff, mypy (over the installed namespace, scripts/typecheck.py) and the layers contract
# (import-linter, scripts/importlint.py) run with the tests.
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python scripts/typecheck.py
	$(BIN)/python scripts/importlint.py

test: $(STAMP) chromium compiler lint
	$(BIN)/python -m pytest -q

# The developer's loop: the unit-level tests (no planner solve, no MuJoCo run), under two
# minutes here; `make test` runs everything (tests/conftest.py marks the slow ones).
test-fast: $(STAMP) compiler
	$(BIN)/python -m pytest -q -m "not slow"

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_leg.py
	$(BIN)/python benchmarks/bench_robot.py
	$(BIN)/python benchmarks/bench_design.py
	$(BIN)/python benchmarks/bench_codegen.py
	$(BIN)/python benchmarks/bench_planner.py
	$(BIN)/python benchmarks/bench_planner_random.py
	$(BIN)/python benchmarks/bench_planner_random.py --locked
	$(BIN)/python benchmarks/toppra_convergence.py

clean:
	rm -rf $(VENV) .pytest_cache
