# `make demo`, `make test` and `make docs` each create .venv if it is missing and install the
# project into it (editable, with the extras they need).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-long lint docs bench clean

EXTRAS := .[test,xarray,distributed,docs]

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

# uv (from PyPI, into .venv) installs the same versions as pip, with their bytecode compiled as
# pip does: a fresh .venv in 28 s where pip took 63 s on 2 cores; pip if uv cannot be had
$(STAMP): pyproject.toml | $(BIN)/python
	($(BIN)/python -m pip install --quiet uv && \
	 $(BIN)/uv pip install --quiet --compile-bytecode --python $(BIN)/python -e '$(EXTRAS)') || \
	$(BIN)/python -m pip install --quiet -e '$(EXTRAS)'
	touch $(STAMP)

demo: $(STAMP)
	mkdir -p out
	$(BIN)/vmj table 1 --plot out/table1.png
	@echo "figure written to out/table1.png"

# lint, then the suite: it includes the documentation (every snippet runs, and
# `mkdocs build --strict`, tests/test_docs.py) and the wheel (tests/test_wheel.py); the examples
# and the long acceptance runs are in `make test-long`
test: lint
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m "not long"

# the long runs (50-seed law-set choices, exact coverage runs, the pendulum on 80P.txt, the
# examples, the heaviest fits tests): about two hours on 2 cores, of which the 50-seed law-set
# runs are about 100 minutes (1.2-4 minutes per 10 records; VMJ_PENDULUM_SEEDS=n runs fewer)
test-long: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m long

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

# the documentation site at http://127.0.0.1:8000, rebuilt on every change
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs serve

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py

clean:
	rm -rf $(VENV) out build
