# Quick start: `make run` (default job into output/) and `make test` (lint, types, whole suite
# on every core with its line coverage of src/ printed; PYTEST_WORKERS=0 runs it in one
# process; COV= runs it without coverage).
# The interpreter: CPython 3.13 when the machine has one (pyenv's on the 2-core machine),
# else python3 (3.11 or newer). On 3.13 the suite measures its line coverage through
# sys.monitoring (coverage's sysmon core; COV_CORE below), which costs about nothing where
# 3.11's trace function cost about a fifth of the suite's time: credible + report tests,
# same hour, helper niced beside: 3.11 90 s with coverage (74 s without); 3.13 70 s with
# (75 s without). The same pinned packages either way (constraints.txt).
PY313 := $(firstword $(wildcard $(PYENV_ROOT)/versions/3.13.*/bin/python3.13 \
	$(HOME)/.pyenv/versions/3.13.*/bin/python3.13) \
	$(shell python3.13 -c 'import sys; print(sys.executable)' 2>/dev/null))
PYTHON ?= $(or $(PY313),python3)
PYTEST_WORKERS ?= auto
# line coverage of src/ (pytest-cov), printed, no threshold. On Python 3.11 (trace
# function) it cost pytest 2 min 08 s -> 2 min 35 s on the 2-core machine (2026-11-26,
# quiet, warm numba cache); on 3.13 (sys.monitoring, COV_CORE) about nothing, and the
# same 93.4 % of lines (2026-11-27). numba compiles untraced (tests/numba_warmup.py). The table is printed by `coverage report` after the
# run: pytest-cov's own report parses every source file twice at the end of the run.
COV ?= --cov --cov-report=
# coverage's core: sys.monitoring on Python 3.12 or newer, the C trace function before
COV_CORE = $$($(BIN)/python -c 'import sys; print("sysmon" if sys.version_info >= (3, 12) else "ctrace")')
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test coverage bench lint lint-warm clean

# The packages are installed by uv (pinned in constraints.txt; pip installs uv itself into
# the new venv first): 20 s -> 6 s on a fresh machine (2-core machine, 2026-11-27, cold uv
# cache; pip, same minute: 19.6 s), the same pinned versions. Like pip's --no-compile
# before, uv does not compile the installed modules to bytecode (with pip that was about
# half of a fresh install: 41 s -> 21 s). Nothing compiles them all afterwards either
# (compileall on 2 cores: 13 s for everything, 6.5 s without the packages' own tests, pip,
# setuptools): each module is compiled when first imported (mypy's and the numba warm-up's
# imports, beside each other, then pytest's), which is a fraction of the files. That needs
# bytecode to be written: PYTHONDONTWRITEBYTECODE is taken out of the recipes' environment,
# else every process would compile numpy, scipy, matplotlib again on import.
unexport PYTHONDONTWRITEBYTECODE
UV := $(BIN)/uv pip install -q --python $(BIN)/python -c constraints.txt

# The build backend goes in first and the project is built without an isolated build
# environment (an isolated one would install hatchling into it again: 2 s).
# (a new venv each time: one made by another interpreter would keep its packages)
$(STAMP): pyproject.toml constraints.txt
	rm -rf $(VENV)
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --no-compile -c constraints.txt uv
	$(UV) hatchling editables
	$(UV) --no-build-isolation -e '.[test,distributed]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/sensorgap run --out output

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/ruff format --check src tests benchmarks
	$(BIN)/mypy src

# lint for the suite: mypy beside the numba warm-up (tests/numba_warmup.py, only when the
# kernel cache is cold: a fresh clone), each on one core (fresh clone, 2 cores: mypy 14 s,
# warm-up 26 s). The warm-up is not waited for: pytest starts after mypy, its workers start
# and collect meanwhile and wait for the warm-up's lock before their first test
# (tests/conftest.py), which overlapped the last 12 s of the warm-up with their 9 s start.
lint-warm: $(STAMP)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/ruff format --check src tests benchmarks
	$(BIN)/python -m tests.numba_warmup --if-cold > /dev/null 2>&1 & \
	$(BIN)/mypy src

# -n: pytest-xdist workers, one per core; --dist loadgroup keeps the tests of a file (or of a
# folder sharing session fixtures, tests/conftest.py) on one worker. Coverage: report only.
# While working: .venv/bin/pytest -q -m "not slow" tests/<area> skips the long end-to-end runs.
test: lint-warm
	COVERAGE_CORE=$(COV_CORE) $(BIN)/pytest -q -n $(PYTEST_WORKERS) --dist loadgroup $(COV); status=$$?; \
	$(if $(COV),$(BIN)/coverage report;) exit $$status

coverage: lint-warm
	COVERAGE_CORE=$(COV_CORE) $(BIN)/pytest -q -n $(PYTEST_WORKERS) --dist loadgroup --cov --cov-report=; status=$$?; \
	$(BIN)/coverage report --show-missing; exit $$status

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py

clean:
	rm -rf $(VENV) output/*/ .pytest_cache .mypy_cache .ruff_cache .coverage .coverage.*
