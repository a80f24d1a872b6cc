# Everything a newcomer needs: `make demo` runs the demo, `make test` runs the tests.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/galileo demo

# As root, .ci/setup installs the tests' real peers from Debian (ROS 1, Mosquitto, tmux;
# idempotent), and their tests must then run; elsewhere they are skipped with the reason.
test: $(STAMP)
	@if [ "$$(id -u)" = 0 ]; then .ci/setup; fi
	@if [ "$$(id -u)" = 0 ]; then export GALILEO_REQUIRE_PEERS=1; fi; $(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/python -m ruff check galileo_async tests examples benchmarks
	$(BIN)/python -m mypy --strict galileo_async

bench: $(STAMP)
	$(BIN)/python -m benchmarks

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache .mypy_cache .ruff_cache
