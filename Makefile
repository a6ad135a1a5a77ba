# Two entry points: `make run` (the demo crawl) and `make test` (the whole suite).
# Both set up everything from PyPI on a fresh machine; later runs reuse .venv and take seconds.
# `make run`'s venv holds what the demo needs (requirements.txt); `make test` adds the test and
# lint tools and the sweep extra (requirements-test.txt) to it without rebuilding anything.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
TEST_STAMP := $(VENV)/.installed-test
INSTALL_STAMP := install/.built
INTERFACES_STAMP := $(VENV)/.interfaces

# AMENT_PREFIX_PATH: the colcon install (for `ros2 run`-style lookup) and the venv (for .msg files).
export AMENT_PREFIX_PATH := $(CURDIR)/install/crawler_sim:$(CURDIR)/$(VENV)
export PYTHONPATH := $(CURDIR)
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export ROS_DISTRO := jazzy
export MPLBACKEND := Agg

.PHONY: run test venv build bench clean

run: build
	$(PY) -m crawler_sim.ros.demo

test: build $(TEST_STAMP)
	$(PY) -m pytest -q -p no:cacheprovider test

bench: build $(TEST_STAMP)
	$(PY) -m benchmarks.solvers --out bench_out

venv: $(STAMP)

$(STAMP): requirements.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	touch $(VENV)/COLCON_IGNORE
	$(PY) -m pip install --upgrade pip
	# --no-compile: no bytecode for modules nothing imports (~100 MB); Python writes it for the
	# ones it imports, on first use
	$(PY) -m pip install --no-compile -r requirements.txt
	touch $@

# added to the run venv; the colcon build does not depend on this stamp, so nothing recompiles
$(TEST_STAMP): $(STAMP) requirements-test.txt requirements-sweep.txt
	$(PY) -m pip install --no-compile -r requirements-test.txt
	touch $@

build: $(INSTALL_STAMP) $(INTERFACES_STAMP)

# simulation_interfaces and tf2_msgs (not on PyPI): built into the venv from interfaces/ when the
# environment lacks them (a Jazzy install has them: nothing is built); rebuilt when they change
$(INTERFACES_STAMP): $(STAMP) requirements-interfaces.txt tools/build_interfaces.py $(wildcard interfaces/*/* interfaces/*/*/*)
	$(PY) tools/build_interfaces.py
	touch $@

$(INSTALL_STAMP): $(STAMP) setup.py setup.cfg pyproject.toml package.xml $(wildcard config/*/* launch/*.py scripts/*) $(wildcard crawler_sim/*.py crawler_sim/*/*.py crawler_sim/*/*/*.py crawler_sim/*/*.pyx crawler_sim/*/*/*.pyx crawler_sim/*/*/*.pxd)
	source $(VENV)/bin/activate && colcon --log-base log build --paths . --build-base build --install-base install --symlink-install
	touch $@

clean:
	rm -rf build install log
