# The two commands a user needs: `make demo` and `make test`. Both set everything up
# first (tools/setup.sh skips what is already done).
SHELL := /bin/bash
.DEFAULT_GOAL := help

.PHONY: help setup rostools bench-env demo test test-slow lint bench clean

help:  ## list the targets
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | sed -E 's/:.*## /\t/' | expand -t 12

setup:  ## create .venv, install pinned dependencies, build ros2_ws (idempotent)
	@tools/setup.sh all

rostools: setup  ## the test-only ros2 CLI and launch in .venv-rostools (idempotent)
	@tools/setup.sh rostools

bench-env:  ## the bench-only environment of peer models in .venv-bench (idempotent)
	@tools/setup.sh bench

demo: setup  ## run the main job: simulator + predictor + client, forecast vs truth
	@tools/with_env.sh tools/demo.sh

test:  ## quality gates and the default test suite (slow checks excluded)
	@tools/setup.sh test
	@tools/with_env.sh tools/run_tests.sh

test-slow:  ## only the slow checks (minutes each)
	@tools/setup.sh test
	@tools/with_env.sh tools/run_tests.sh --slow

lint: setup  ## quality gates only
	@tools/with_env.sh tools/run_tests.sh --lint-only

bench: setup  ## the benchmarks, JSON on stdout (the 10-minute soak: offline/bench.py soak; each suite's short form: offline/bench.py --quick SUITE, run by make test-slow)
	@for suite in sim convert forecast scale launch diagnose; do tools/with_env.sh python offline/bench.py $$suite; done

clean:  ## remove build products and the test-only tools (keeps .venv)
	rm -rf ros2_ws/build ros2_ws/install ros2_ws/log .pytest_cache .ruff_cache .venv-rostools .venv-bench
