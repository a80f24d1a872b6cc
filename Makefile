# Everything a newcomer needs: `make demo` runs the demo, `make test` runs the tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
DEMO_STAMP := $(VENV)/.installed-cli
TEST_STAMP := $(VENV)/.installed-dev
#: Where `make dist` puts the sdist and the wheel.
DIST ?= dist
# Editable installs that type checkers see: setuptools' compat mode puts this directory on
# sys.path with a plain .pth line, which mypy and pyright read (its default mode installs an
# import hook they cannot follow). compat is setuptools' transitional mode, and setuptools
# says so on every install (silenced here): tests/packaging/test_packaging.py fails should it go.
PIP_EDITABLE := PYTHONWARNINGS='ignore:Compat editable installs' $(BIN)/python -m pip install \
	--quiet --disable-pip-version-check --config-settings editable_mode=compat -e

.PHONY: demo test lint bench dist clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

# The demo needs only the command line (the extra [cli]); the tests need the dev tools.
$(DEMO_STAMP): pyproject.toml Makefile | $(BIN)/python
	$(PIP_EDITABLE) '.[cli]'
	touch $@

$(TEST_STAMP): pyproject.toml Makefile | $(BIN)/python
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --upgrade pip
	$(PIP_EDITABLE) '.[dev]'
	touch $@ $(DEMO_STAMP)

demo: $(DEMO_STAMP)
	$(BIN)/galileo demo

# As root, .ci/setup installs the tests' real peers from Debian (ROS 1, Mosquitto, tmux, systemd;
# idempotent), and their tests must then run; elsewhere they are skipped with the reason.
test: $(TEST_STAMP)
	@if [ "$$(id -u)" = 0 ]; then .ci/setup; fi
	@if [ "$$(id -u)" = 0 ]; then export GALILEO_REQUIRE_PEERS=1; fi; $(BIN)/python -m pytest -q

lint: $(TEST_STAMP)
	$(BIN)/python -m ruff check galileo_async galileo_async_pytest.py tests examples benchmarks
	$(BIN)/python -m ruff format --check galileo_async galileo_async_pytest.py tests examples benchmarks
	$(BIN)/python -m mypy --strict galileo_async galileo_async_pytest.py

bench: $(TEST_STAMP)
	$(BIN)/python -m benchmarks

# The sdist and the wheel, built as an index would get them (python -m build, in an isolated
# environment): then `pip install '$(DIST)/galileo_async-VERSION-py3-none-any.whl[cli]'`.
dist: $(TEST_STAMP)
	rm -f $(DIST)/galileo_async-*.tar.gz $(DIST)/galileo_async-*.whl
	$(BIN)/python -m build --outdir $(DIST) .

clean:
	rm -rf $(VENV) build dist *.egg-info .pytest_cache .mypy_cache .ruff_cache
