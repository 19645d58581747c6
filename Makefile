# Development tasks. Works on a fresh machine with only python3 (PyPI reachable).
PYTHON ?= python3
VENV   := .venv
VPY    := $(VENV)/bin/python
# Reinstalled whenever the packaging metadata changes.
STAMP  := $(VENV)/.wallbot_sim-installed

.PHONY: venv test run bench clean

venv: $(STAMP)

$(STAMP): setup.py setup.cfg package.xml
	test -x $(VPY) || $(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install --upgrade pip
	$(VPY) -m pip install -e ".[ros,test]"
	touch $@

test: venv
	$(VPY) -m pytest -q test

run: venv
	$(VENV)/bin/wallbot-sim run circle --constraints belt,non_lateral,nonslip --out runs/circle

bench: venv
	$(VPY) bench/bench_core.py

# Removes the venv and build products; keeps runs/ (simulation output).
clean:
	rm -rf $(VENV) build install log .pytest_cache *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
