# The two commands of the README. Both set everything up on a fresh machine first.
.PHONY: run test test-slow setup

setup:
	@./scripts/setup.sh

run: setup
	.venv/bin/drake-continuum reproduce --quick --no-second-dataset --no-observed --out results

# The suite on WORKERS processes (pytest-xdist): each test file on one worker, with its
# module fixtures; the files in the order tests/conftest.py gives, the longest first.
# WORKERS=0 runs it in one process.
WORKERS ?= 2

test: setup
	.venv/bin/python -m pytest -n $(WORKERS) --dist loadfile --no-loadscope-reorder

test-slow: setup
	.venv/bin/python -m pytest -m slow
