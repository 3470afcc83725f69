# Set-up and everyday commands. `make demo` and `make test` each create the environment first.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install demo test lint bench accuracy clean

install: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/rig model curve --speed 60.8 --hoop-min 300 --hoop-max 5000 --points 200 --plot out/efficiency.png

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports

test: lint
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_curve.py
	$(BIN)/python benchmarks/bench_scene.py

accuracy: $(STAMP)
	$(BIN)/python benchmarks/accuracy_doc.py

clean:
	rm -rf $(VENV) out .pytest_cache .ruff_cache
