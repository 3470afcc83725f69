# Set-up and everyday commands. `make demo` and `make test` each create the environment first.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
COMPILED := $(VENV)/.compiled

.PHONY: install demo test suite lint-log test-caches test-kernel test-asserts lint typecheck bench accuracy clean

install: $(STAMP) $(COMPILED)

# PYTHONWARNINGS: setuptools' notice that a folder named like the package may shadow it is
# expected here, where rig/ is the package.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	PYTHONWARNINGS='ignore:Editable installation' $(BIN)/python -m pip install --quiet --no-compile -e '.[dev]'
	touch $(STAMP)

# The installed packages' bytecode, on every core (pip would compile them on one: ~14 s of a ~30 s
# install). `make test` does without: its processes keep their bytecode in .venv/pycache (TEST_ENV).
$(COMPILED): $(STAMP)
	$(BIN)/python -m compileall -q -j 0 $$($(BIN)/python -c 'import sysconfig; print(sysconfig.get_path("purelib"))')
	touch $(COMPILED)

# A simulated NCAA BBCOR certification of the sample bat (lab scene), then its certificate.
# `rig certify` exits 1 for a FAIL verdict, which is a result, not an error of the demo.
demo: $(STAMP) $(COMPILED)
	mkdir -p out
	$(BIN)/rig certify --procedure bbcor --bat protocols/examples/sample-bat.toml --sim lab \
		--db out/demo.db; test $$? -le 1
	$(BIN)/rig report last --db out/demo.db --format md --output out/certificate.md --figures out/figures
	$(BIN)/rig report last --db out/demo.db --format html --output out/certificate.html --figures out/figures
	$(BIN)/rig verify --db out/demo.db
	@echo "certificate: out/certificate.md (and .html); records: out/demo.db"
	@echo "the rig command is in .venv/bin: run . .venv/bin/activate, then rig runs --db out/demo.db"
	@echo "(or, without activating: .venv/bin/rig runs --db out/demo.db)"

# ruff, the import contracts and mypy (strict on the lower floors; [tool.mypy] in pyproject.toml)
# mypy keeps its incremental cache in the user's cache folder, shared by every checkout of the
# project on this machine (a fresh clone, as CI's, then checks in ~1 s what takes ~22 s cold; mypy
# rechecks whatever changed, by content); .mypy_cache in the checkout where that folder cannot be made.
MYPY_CACHE := $(shell d="$${XDG_CACHE_HOME:-$$HOME/.cache}/rig-lab/mypy"; mkdir -p "$$d" 2>/dev/null && [ -w "$$d" ] && echo "$$d" || echo .mypy_cache)
MYPY = $(BIN)/mypy --cache-dir "$(MYPY_CACHE)"
LINT = $(BIN)/ruff check . && $(BIN)/lint-imports && $(MYPY)
lint: $(STAMP)
	$(LINT)

# mypy alone
typecheck: $(STAMP)
	$(MYPY)

# the suite on every core plus one (pytest-xdist; many tests wait on sockets and child processes, and
# on a quiet 2-core machine 3 workers took 315 s against 351 s for 2), at most 8; TEST_WORKERS=1 for
# one process, or a number; --dist loadfile keeps a file's tests (and its module fixtures) in one worker
TEST_WORKERS ?= $(shell n=$$(nproc 2>/dev/null || echo 1); echo $$(( n < 8 ? n + 1 : 8 )))
# Bytecode is written (even where PYTHONDONTWRITEBYTECODE is set) but into .venv/pycache, not the
# checkout: otherwise every worker and each of the hundreds of rig commands the tests start compiles
# rig from source, and every worker rewrites the asserts of all 200 test files (~6 s each time).
TEST_ENV := PYTHONDONTWRITEBYTECODE= PYTHONPYCACHEPREFIX=$(CURDIR)/$(VENV)/pycache
# Lint runs beside the suite, in the time its workers wait on sockets and child processes, its output
# kept in $(VENV)/lint.log and shown after the suite's; either failing fails `make test`.
test: $(STAMP)
	$(MAKE) --no-print-directory -j2 test-kernel test-asserts
	$(MAKE) --no-print-directory -j2 lint-log suite; status=$$?; cat $(VENV)/lint.log; exit $$status

# lint into its log, which ends with its outcome
lint-log: $(STAMP)
	($(LINT)) > $(VENV)/lint.log 2>&1; s=$$?; [ $$s = 0 ] && r=ok || r=FAILED; \
		echo "lint (beside the suite): $$r" >> $(VENV)/lint.log; exit $$s

suite: $(STAMP)
	$(TEST_ENV) $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile

# Before the suite, one core each: numba compiles the collision kernel once (~9 s; in a fresh
# checkout each worker and each rig command would compile it at the same time), and the test files'
# asserts are rewritten once, into the bytecode cache above.
test-caches: test-kernel test-asserts

test-kernel: $(STAMP)
	$(TEST_ENV) $(BIN)/python -c 'from rig.physics import fast; fast.warm_up()'

test-asserts: $(STAMP)
	$(TEST_ENV) $(BIN)/python -m pytest -q --collect-only -p no:cacheprovider > /dev/null

bench: $(STAMP) $(COMPILED)
	$(BIN)/python benchmarks/bench_startup.py
	$(BIN)/python benchmarks/bench_curve.py
	$(BIN)/python benchmarks/bench_scene.py
	$(BIN)/python benchmarks/bench_certify.py
	$(BIN)/python benchmarks/bench_serve.py --repeat 2
	$(BIN)/python benchmarks/bench_crosscheck.py --populations 5
	$(BIN)/python benchmarks/bench_calibrate.py
	$(BIN)/python benchmarks/bench_lab_store.py
	$(BIN)/python benchmarks/bench_ball_truth.py --bats 40
	$(BIN)/python benchmarks/bench_fit_ball.py --seeds 40
	$(BIN)/python benchmarks/bench_instruments.py --repeat 3
	$(BIN)/python benchmarks/bench_modal.py --speed

accuracy: $(STAMP) $(COMPILED)
	$(BIN)/python benchmarks/accuracy_doc.py

clean:
	rm -rf $(VENV) out .pytest_cache .ruff_cache .mypy_cache
