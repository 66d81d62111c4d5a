# flex-twin developer entry points. Every target that runs project code first makes sure
# .venv exists and is current (scripts/bootstrap.sh is a no-op when its stamp matches).
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := help

ROOT := $(patsubst %/,%,$(dir $(abspath $(lastword $(MAKEFILE_LIST)))))
ENV := source $(ROOT)/scripts/env.sh
# Test roots that exist right now (src/*/test are optional per package; studies/test: the
# one-off studies beside the packages).
TEST_DIRS = $(wildcard test src/*/test studies/test)
PYTEST_ARGS ?=
# pytest-xdist workers (one per core of the 2-core CI machine; TEST_WORKERS=0: one process)
TEST_WORKERS ?= 2
DEMO_ARGS ?=

.PHONY: help venv test demo bench clean distclean

help:
	@echo "make venv    create/refresh .venv (pinned by constraints.txt)"
	@echo "make test    run the test suite (PYTEST_ARGS='-k foo' to narrow, TEST_WORKERS=2)"
	@echo "make demo    the twin demo over ROS: 'flex-twin twin-demo' (DEMO_ARGS='...')"
	@echo "make bench   run bench/run_all.py if present"
	@echo "make clean   remove build/test artefacts (keeps .venv); distclean also removes .venv"

venv:
	bash $(ROOT)/scripts/bootstrap.sh

test: venv
	cd $(ROOT) && $(ENV) && ROS_PYTHON_CHECK_FIELDS=1 \
	    python -m pytest -n $(TEST_WORKERS) --dist loadfile $(PYTEST_ARGS) $(TEST_DIRS)

# NUMBA_OPT unset: the demo compiles its kernels at LLVM -O1 into the tests' cache, as
# conftest.py does (a third less compile time on a fresh clone, the same numbers; the demo's
# loop is bound by its recorder, not the kernel: docs/development.md, fast feedback).
# bootstrap.sh --demo: the demo's in-loop kernels start compiling (into that cache, hence
# the exports first) as soon as the wheels are in, beside the rest of the bootstrap; the
# demo needs neither tf2_msgs nor control_msgs: their build (bootstrap step 5) runs behind
# the demo at the lowest priority (nice 19); the last bootstrap.sh waits for it (and fails
# if it failed).
demo:
	cd $(ROOT) && if [ -z "$${NUMBA_OPT:-}" ]; then export NUMBA_OPT=1 \
	    NUMBA_CACHE_DIR="$${NUMBA_CACHE_DIR:-$(ROOT)/.numba_test_cache}"; fi \
	    && bash $(ROOT)/scripts/bootstrap.sh --demo && $(ENV) \
	    && status=0 && { flex-twin twin-demo $(DEMO_ARGS) || status=$$?; } \
	    && bash $(ROOT)/scripts/bootstrap.sh && exit $$status

bench: venv
	@cd $(ROOT) && if [ -f bench/run_all.py ]; then $(ENV) && python bench/run_all.py; \
	else echo "bench/run_all.py not present; nothing to run"; fi

clean:
	cd $(ROOT) && rm -rf build install log ros2_ws/build ros2_ws/install ros2_ws/log \
	    .pytest_cache src/*/*.egg-info src/*/build
	cd $(ROOT) && find . \( -name .git -o -name '.venv*' -o -name ros2_ws \) -prune -o \
	    -type d -name __pycache__ -exec rm -rf {} +

distclean: clean
	rm -rf $(ROOT)/.venv $(ROOT)/.venv.lock
