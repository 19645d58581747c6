# Development tasks. Works on a fresh machine with only python3 (PyPI reachable).
PYTHON ?= python3
VENV   := .venv
VPY    := $(VENV)/bin/python
# Reinstalled whenever the packaging metadata changes.
STAMP  := $(VENV)/.wallbot_sim-installed

.PHONY: venv test test-fast run bench clean

venv: $(STAMP)

$(STAMP): setup.py setup.cfg package.xml
	test -x $(VPY) || $(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install --upgrade pip
	$(VPY) -m pip install -e ".[ros,test]"
	touch $@

# Two workers (pytest-xdist), each a session of its own with its own DDS domain. Each test goes to
# whichever worker is free, but the tests sharing a module- or class-scoped fixture stay on one worker
# so that it runs once (test/conftest.py's scheduler, SHARED_FIXTURE_MODULES).
PYTEST := $(VPY) -m pytest -q -n 2 --dist loadgroup --durations=25

test: venv
	$(PYTEST) test

# The model and the units, no node processes (test/conftest.py FAST_MODULES).
test-fast: venv
	$(PYTEST) -m fast test

run: venv
	$(VENV)/bin/wallbot-sim run circle --constraints belt,non_lateral,nonslip --out runs/circle

bench: venv
	$(VPY) bench/bench_core.py

# Removes the venv and build products; keeps runs/ (simulation output).
clean:
	rm -rf $(VENV) build install log .pytest_cache *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
