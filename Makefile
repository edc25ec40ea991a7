# iTaSC-ROS2 developer entry points. `make help` lists them.
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := help
ROOT := $(abspath $(dir $(lastword $(MAKEFILE_LIST))))

# The default application of `make demo`.
DEMO_APP ?= approach_object
DEMO_ARGS ?= --duration 20
APP ?=
ARGS ?=
MCAP ?=
PYTEST_ARGS ?=

# Run a command inside the environment (venv + colcon overlay); `$(RUN) <exe> ...` runs an
# executable of itasc_bringup like `ros2 run itasc_bringup <exe> ...` would.
ENV := cd "$(ROOT)" && source "$(ROOT)/scripts/env.sh"
RUN := $(ENV) && ros2run itasc_bringup

.PHONY: help setup demo run test bench plot graph clean distclean

help:
	@echo "make setup                      create .venv (Python 3.12, pinned ROS 2 Jazzy wheels) and colcon build into install/"
	@echo "make demo                       setup, then run the default application ($(DEMO_APP) $(DEMO_ARGS))"
	@echo "make run APP=<name|path> ARGS=  run an application through itasc_bringup's bootstrap"
	@echo "make test [PYTEST_ARGS=...]     setup, then pytest on test/"
	@echo "make bench                      setup + requirements/bench.txt, then every bench/*.py"
	@echo "make plot MCAP=run.mcap         plot a recorded run (itasc-plot)"
	@echo "make graph APP=<name|path>      draw an application's composition graph (itasc-graph)"
	@echo "make clean | distclean          remove build/ install/ log/ out/ (distclean: also .venv/)"

setup:
	@bash "$(ROOT)/scripts/setup.sh"

demo: setup
	$(RUN) bootstrap $(DEMO_APP) $(DEMO_ARGS)

run: setup
	@if [ -z "$(APP)" ]; then echo 'usage: make run APP=<name-or-path> [ARGS="..."]' >&2; exit 2; fi
	$(RUN) bootstrap $(APP) $(ARGS)

test: setup
	@$(ENV) && rc=0 && python -m pytest $(PYTEST_ARGS) || rc=$$?; \
	  if [ $$rc -eq 5 ]; then echo "make test: FAILED, pytest collected no tests (exit code 5)" >&2; fi; \
	  exit $$rc

bench: setup
	@bash "$(ROOT)/scripts/setup.sh" --bench
	@$(ENV) && shopt -s nullglob && files=(bench/bench_*.py) && \
	  if [ $${#files[@]} -eq 0 ]; then echo "no bench/bench_*.py yet"; exit 0; fi && \
	  for f in "$${files[@]}"; do echo "=== $$f"; python "$$f"; done

plot: setup
	@if [ -z "$(MCAP)" ]; then echo 'usage: make plot MCAP=<run.mcap> [ARGS="..."]' >&2; exit 2; fi
	$(RUN) itasc-plot "$(abspath $(MCAP))" $(ARGS)

graph: setup
	@if [ -z "$(APP)" ]; then echo 'usage: make graph APP=<name-or-path> [ARGS="..."]' >&2; exit 2; fi
	$(RUN) itasc-graph $(APP) $(ARGS)

clean:
	rm -rf "$(ROOT)/build" "$(ROOT)/install" "$(ROOT)/log" "$(ROOT)/out" "$(ROOT)/.pytest_cache"
	find "$(ROOT)/src" "$(ROOT)/bringup" "$(ROOT)/test" -name __pycache__ -type d -prune -exec rm -rf {} + 2>/dev/null || true

distclean: clean
	rm -rf "$(ROOT)/.venv"
