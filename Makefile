# Entry points (see README): `make quickstart` and `make test` (then `make test-slow`). All set up .venv first.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: setup bytecode quickstart test test-slow bench clean

# setuptools tells every editable install whose packages map folders (plugins/ -> fusionkit_plugins) that
# folders named like a package in the working directory may shadow it: information only (InformationOnly), a
# dozen lines on every first make; the filter matches that message alone.
$(STAMP): pyproject.toml setup.py
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	PYTHONWARNINGS="ignore:Editable installation" $(BIN)/pip install --quiet -e '.[test]'
	touch $(STAMP)

setup: $(STAMP)

# Every `fusionkit` command imports the package; where the environment sets PYTHONDONTWRITEBYTECODE (as CI
# machines and containers often do) Python would compile its 20k lines anew in each process (about 1 s).
# compileall writes the bytecode once (files already up to date are skipped).
bytecode: $(STAMP)
	$(BIN)/python -m compileall -q fusionkit plugins benchmarks research examples

quickstart: bytecode
	$(BIN)/fusionkit run configs/quickstart.yaml --out out/quickstart

# the tests but the slow tier (pytest marker `slow`: end-to-end runs of 3 s or more), then that tier
test: bytecode
	$(BIN)/python -m pytest -q -n 2 --dist worksteal -m "not slow"

test-slow: bytecode
	$(BIN)/python -m pytest -q -n 2 --dist worksteal -m slow

bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py --quick

clean:
	rm -rf $(VENV) out
