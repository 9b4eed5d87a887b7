# gyro_tdc developer entry points. Everything runs from the repository's .venv.
#
#   make venv    create/refresh .venv (ROS 2 Jazzy wheels, deps, dev tools, editable gyro_tdc)
#   make test    run the test suite on TEST_WORKERS (3) xdist workers (own ROS_DOMAIN_ID per
#                worker, loopback discovery only; a test fails after pytest.ini's timeout)
#   make test-stress  run the whole suite STRESS_RUNS (2) times in a row beside a process that
#                keeps one core busy (a CPU hog), stopping at the first failing run; the hog is
#                killed on exit. Finds the tests whose result depends on the load (long)
#   make lint    flake8 + pep257 + copyright on gyro_tdc/, test/, bench/, tools/, setup.py (and
#                flake8 + pep257 on the docs' conf.py and extensions)
#   make demo    end-to-end demo into out/demo
#   make bench   run every bench/*.py (each prints its figures)
#   make docs    the documentation site (doc/, Sphinx, warnings are errors) into build/docs/html
#   make rosdoc2 the site as the ROS documentation index builds it (rosdoc2) into build/rosdoc2
#   make readme-check  run every command block of README.md and doc/, in order, in a fresh
#                clone (long)
#   make test-apt-versions  the tests in .venv-apt, with Ubuntu 24.04's apt numpy, scipy,
#                matplotlib and PyYAML and requirements-apt.txt (the robot recipe; not in `test`)
#   make clean   remove out/ (every README output) and build/test artefacts (keeps .venv;
#                `make distclean` removes it too)

SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := test

# DDS stays on loopback for every target (tests, demo and benches all may start nodes).
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST

PYTHON ?= python3
VENV := .venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.gyro_tdc-installed
PIP_FLAGS ?= --disable-pip-version-check
LINT_PATHS = $(wildcard gyro_tdc test bench tools setup.py doc/conf.py doc/_ext)

# Each run gets its own ROS_DOMAIN_ID (1..101, from the shell's PID) unless one is set, so
# parallel runs on one machine do not discover each other's nodes.
DOMAIN := if [ -z "$${ROS_DOMAIN_ID:-}" ]; then export ROS_DOMAIN_ID=$$(( $$$$ % 101 + 1 )); fi

# `make test` runs the suite on TEST_WORKERS pytest-xdist workers (TEST_WORKERS=0: in one
# process), one test file per worker at a time (--dist loadfile: a module's fixtures are built
# once). The run's ROS_DOMAIN_ID is the base: worker gwN takes (base - 1 + 20 (N + 1)) % 101 + 1,
# never the base, or the next id along that stride that no other live pytest process holds
# (a lock in /tmp per id, test/conftest.py), so neither two workers nor two runs share one.
# Tests marked `serial` (their result depends on the load) run with no other test beside them.
TEST_WORKERS ?= 3

.PHONY: venv test test-stress lint demo bench docs rosdoc2 readme-check test-apt-versions clean distclean

venv: $(STAMP)

$(STAMP): requirements.txt requirements-dev.txt setup.py setup.cfg package.xml
	@test -x $(VPY) || { echo "creating $(VENV) with $$($(PYTHON) --version)"; \
		$(PYTHON) -m venv $(VENV); }
	$(VPY) -m pip install $(PIP_FLAGS) -q -r requirements.txt -r requirements-dev.txt
	@# gyro_tdc itself, built by the venv's setuptools and wheel (pip's isolated build would
	@# download setuptools again every time); pip's isolated build if that setuptools is too old.
	$(VPY) -m pip install $(PIP_FLAGS) -q -e . --no-deps --no-build-isolation --use-pep517 \
		2>/dev/null || { echo "make venv: building gyro_tdc in pip's isolated environment"; \
		$(VPY) -m pip install $(PIP_FLAGS) -q -e . --no-deps; }
	@touch $@

test: venv
	@$(DOMAIN); \
	echo "ROS_DOMAIN_ID=$$ROS_DOMAIN_ID ROS_AUTOMATIC_DISCOVERY_RANGE=$$ROS_AUTOMATIC_DISCOVERY_RANGE"; \
	rc=0; $(VPY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile test || rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test: pytest collected no tests" >&2; exit 1; fi; \
	exit $$rc

# The suite again and again beside a CPU hog (one core spinning in a child python), as CI
# runs it when other jobs share the machine: a flake shows as a failing run. Each run takes
# its own ROS_DOMAIN_ID (as `make test`); the hog is killed on any exit, Ctrl-C included.
STRESS_RUNS ?= 2
test-stress: venv
	@if ! [[ "$(STRESS_RUNS)" =~ ^[1-9][0-9]*$$ ]]; then \
		echo "make test-stress: STRESS_RUNS must be a positive integer, got '$(STRESS_RUNS)'" >&2; \
		exit 2; fi; \
	$(DOMAIN); \
	$(VPY) -c 'while True: pass' & hog=$$!; \
	trap 'kill $$hog 2>/dev/null; wait $$hog 2>/dev/null || true' EXIT; \
	trap 'exit 130' INT TERM; \
	for run in $$(seq 1 $(STRESS_RUNS)); do \
		echo "=== make test-stress: run $$run of $(STRESS_RUNS), CPU hog pid $$hog," \
			"ROS_DOMAIN_ID=$$ROS_DOMAIN_ID"; \
		rc=0; $(VPY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile test || rc=$$?; \
		if [ $$rc -ne 0 ]; then \
			echo "make test-stress: run $$run of $(STRESS_RUNS) failed (pytest exit $$rc)" >&2; \
			exit 1; fi; \
	done; \
	echo "make test-stress: $(STRESS_RUNS) runs passed beside a CPU hog"

# All three checks run; the target fails at the end if any of them failed.
lint: venv
	@rc=0; \
	echo '--- flake8 (setup.cfg = ament_flake8 settings)'; \
	$(VENV)/bin/flake8 $(LINT_PATHS) || rc=1; \
	echo '--- ament_pep257'; \
	out=$$($(VENV)/bin/ament_pep257 $(LINT_PATHS) 2>&1) || rc=1; \
	grep -v '^checking ' <<<"$$out" || true; \
	echo '--- copyright (HEADER.txt)'; \
	$(VPY) -m pytest -q -p no:cacheprovider test/system/test_copyright.py || rc=1; \
	exit $$rc

demo: venv
	@$(DOMAIN); $(VPY) -m gyro_tdc demo --out out/demo

bench: venv
	@$(DOMAIN); \
	shopt -s nullglob; scripts=(bench/*.py); \
	if [ $${#scripts[@]} -eq 0 ]; then echo "make bench: no bench/*.py scripts" >&2; exit 1; fi; \
	failed=(); \
	for script in "$${scripts[@]}"; do \
		echo "=== $$script (ROS_DOMAIN_ID=$$ROS_DOMAIN_ID)"; \
		$(VPY) "$$script" || failed+=("$$script"); \
	done; \
	if [ $${#failed[@]} -gt 0 ]; then echo "make bench: failed: $${failed[*]}" >&2; exit 1; fi

# The documentation site: doc/ with the reference pages generated from the code (doc/_ext).
# -W --keep-going: every warning is reported, and any fails the build.
DOCS_OUT := build/docs
docs: venv
	$(VENV)/bin/sphinx-build -W --keep-going -b html doc $(DOCS_OUT)/html
	@echo "make docs: $(DOCS_OUT)/html/index.html"

# The same site built by rosdoc2, as the ROS documentation index builds a package (its own
# conf.py runs doc/conf.py; sphinx-apidoc must be on PATH). rosdoc2 does not stop on a Sphinx
# warning, so this target fails when its log has one.
ROSDOC2_OUT := build/rosdoc2
rosdoc2: venv
	@rm -rf $(ROSDOC2_OUT); mkdir -p $(ROSDOC2_OUT)
	PATH="$(abspath $(VENV))/bin:$$PATH" $(VENV)/bin/rosdoc2 build --package-path . \
		--doc-build-directory $(ROSDOC2_OUT)/docs_build \
		--cross-reference-directory $(ROSDOC2_OUT)/cross_reference \
		--output-directory $(ROSDOC2_OUT)/docs_output 2>&1 | tee $(ROSDOC2_OUT)/build.log
	@if grep -E 'WARNING|ERROR' $(ROSDOC2_OUT)/build.log; then \
		echo "make rosdoc2: warnings above (log: $(ROSDOC2_OUT)/build.log)" >&2; exit 1; fi
	@echo "make rosdoc2: $(ROSDOC2_OUT)/docs_output/gyro_tdc/index.html"

# Every ```bash block of README.md, then of the doc/ pages in the site's reading order, in a
# fresh clone of HEAD with its own .venv; stops at the first failing command, named by page and
# line (test/support/readme_check.py: standard library only, no venv needed).
readme-check:
	@$(DOMAIN); $(PYTHON) test/support/readme_check.py

# A robot with apt-installed Jazzy has numpy, scipy, matplotlib and PyYAML from apt (Ubuntu
# 24.04's versions below) and pip-installs only requirements-apt.txt into a venv that sees them.
# This builds that set in .venv-apt: the apt versions first (as apt would), then
# requirements-apt.txt as the robot recipe runs it; it fails if pip replaced an apt version,
# then runs APT_TESTS (default: the whole suite) there. Not part of `make test` (CI time).
APT_VENV := .venv-apt
APT_VERSIONS := numpy==1.26.4 scipy==1.11.4 matplotlib==3.6.3 PyYAML==6.0.1
APT_TESTS ?= test
APT_CHECK := import importlib.metadata as m, sys; \
	want = dict(a.split('==') for a in sys.argv[1:]); \
	got = {k: m.version(k) for k in want}; \
	print('apt versions in $(APT_VENV):', ', '.join(f'{k} {v}' for k, v in got.items())); \
	sys.exit(0 if got == want else f'pip replaced an apt version: {got} instead of {want}')

test-apt-versions:
	@test -x $(APT_VENV)/bin/python || { echo "creating $(APT_VENV) with $$($(PYTHON) --version)"; \
		$(PYTHON) -m venv $(APT_VENV); }
	grep -E '^ros-jazzy-' requirements.txt > $(APT_VENV)/ros-wheels.txt
	$(APT_VENV)/bin/python -m pip install $(PIP_FLAGS) -q $(APT_VERSIONS) -r $(APT_VENV)/ros-wheels.txt
	$(APT_VENV)/bin/python -m pip install $(PIP_FLAGS) -q -r requirements-apt.txt
	$(APT_VENV)/bin/python -m pip install $(PIP_FLAGS) -q -r requirements-dev.txt
	$(APT_VENV)/bin/python -m pip install $(PIP_FLAGS) -q -e . --no-deps
	@$(APT_VENV)/bin/python -c "$(APT_CHECK)" $(APT_VERSIONS)
	@$(DOMAIN); \
	echo "ROS_DOMAIN_ID=$$ROS_DOMAIN_ID ROS_AUTOMATIC_DISCOVERY_RANGE=$$ROS_AUTOMATIC_DISCOVERY_RANGE"; \
	$(APT_VENV)/bin/python -m pytest -q $(APT_TESTS)

clean:
	rm -rf build install log out report .pytest_cache *.egg-info
	find gyro_tdc test $(wildcard bench tools) -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV) $(APT_VENV)
