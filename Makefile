# Two commands do all the set-up: `make run` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN     = $(VENV)/bin
STAMP   = $(VENV)/.installed

.PHONY: run test bench install clean sample kernels

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[test]'
	@touch $(STAMP)

install: kernels

# the compiled kernels' machine code, built once for the current sources (a no-op when up to date)
kernels: $(STAMP)
	$(BIN)/planner kernels build

run: kernels
	$(BIN)/planner run jobs/nightly.toml

test: kernels
	$(BIN)/python -m pytest -q -n 2

bench: kernels
	$(BIN)/python benchmarks/run_all.py

sample: $(STAMP)
	$(BIN)/python lines/sample/build.py

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis build *.egg-info planner/_aot
