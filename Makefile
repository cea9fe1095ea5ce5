# The README's two commands: `make demo` (the main job) and `make test` (the fast test suite;
# `make test-all` runs every test, also those marked slow, as CI does).
# They create ./.venv and install meshrec with what it needs on first use.

PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
OUT    ?= out
SEED   ?= 24

.PHONY: install demo test test-all lint clean

$(BIN)/.meshrec-installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test,viz]"
	# An editable install writes no bytecode for meshrec (a regular one does); compiled
	# here so that a command where Python may not write it (PYTHONDONTWRITEBYTECODE)
	# does not compile meshrec's sources each time (about 0.3 s per command, measured).
	$(BIN)/python -m compileall -q meshrec
	touch $@

install: $(BIN)/.meshrec-installed

## demo: simulate a touch on a bundled model and recognise it among the paper's surfaces
demo: install
	mkdir -p $(OUT)
	$(BIN)/meshrec index --models models/surfaces
	$(BIN)/meshrec simulate models/surfaces/ellipsoid.stl -o $(OUT)/touch.csv \
		--truth $(OUT)/truth.json --seed $(SEED)
	$(BIN)/meshrec recognize $(OUT)/touch.csv --models models/surfaces

# The tests run in two processes (pytest-xdist), each test file in one of them (its
# module fixtures built once): 6.6 to 7.1 minutes for every test on the 2-core machine,
# against 11.0 in one process (clean clones' CI runs). JOBS=0 runs them in this process (no worker).
JOBS ?= 2
PYTEST := $(BIN)/python -m pytest -q -n $(JOBS) --dist loadfile

## test: lint and run the test suite without the tests marked slow
test: install lint
	$(PYTEST) -m "not slow"

## test-all: lint and run every test, the slow ones too (what CI runs)
test-all: install lint
	$(PYTEST)

lint: install
	$(BIN)/ruff check .

clean:
	rm -rf $(OUT) .pytest_cache .ruff_cache
