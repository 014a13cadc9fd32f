# The two commands of the README. Both set everything up on a fresh machine first.
.PHONY: run test test-slow setup

setup:
	@./scripts/setup.sh

run: setup
	.venv/bin/drake-continuum reproduce --quick --no-second-dataset --no-observed --out results

test: setup
	.venv/bin/python -m pytest

test-slow: setup
	.venv/bin/python -m pytest -m slow
