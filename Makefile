# Two commands for users:  make demo   (set up, then run the live demo)
#                          make test   (set up, then run the whole test suite)
# For developers:          make check  (physics, engine and lint only: within 30 s)
#                          make tour   (the README's tour thumbnails, into docs/tour)
#                          make docs   (the documentation site, into out/docs/html)
# Setup is a .venv in the repo that is also an ament prefix for this package,
# so `ros2 run`-style lookups (lib/rigid_body_sim/<exe>, ament index) work in it.

VENV        ?= .venv
PY          := $(VENV)/bin/python
STAMP       := $(VENV)/.rigid_body_sim-installed
DEMO_DURATION ?= 40
DEMO_OUT    ?= out/demo
PYTEST_ARGS ?=
# Parallel test workers (pytest-xdist). Most ROS tests wait on real-time runs and node
# start-ups, so the suite leaves cores idle at four workers: beside other (niced) work on
# this 2-core machine, 10:15 at four and 8:26 at five, the niced work taking 44 % and 41 %
# of the CPU that the suite did not; each worker has its own ROS domain.
TEST_WORKERS ?= 5
SETUP_LOG   ?= out/setup.log
NODES       := simulator controller recorder replay viewer
# tf2_msgs and simulation_interfaces, built into the venv by .ci/build_interfaces.sh
INTERFACES  := $(wildcard interfaces/* interfaces/*/* interfaces/*/*/*)

.PHONY: demo test check venv bench clean tour ament-layout
.PHONY: docs bytecode kernels
.DEFAULT_GOAL := demo

demo: venv
	$(VENV)/bin/rigid-body-sim demo --duration $(DEMO_DURATION) --out $(DEMO_OUT)

# -v names each test as it ends, with its worker. --no-loadscope-reorder keeps the order of
# test/conftest.py (the files that took longest last time first, so that no minutes-long file
# is left for the end; a fresh clone, without .pytest_cache, by test/file_seconds.json).
# loadfile keeps a file on one worker, so a module-scoped fixture (the benchmark's run,
# colcon's build, the viewer's graph) runs once; xdist 3.8's loadgroup did not keep a
# module-level xdist_group together here.
#
# bytecode first: with PYTHONDONTWRITEBYTECODE set (as on these machines) no .pyc of the
# package is ever written, and each of the suite's ~400 node and CLI processes compiled
# ~100 modules from source again: 0.1 CPU-s of its 1.1 s start-up.
bytecode:
	@$(PY) -m compileall -q -j 0 rigid_body_sim test > /dev/null

#
# PYTHONDONTWRITEBYTECODE is cleared for pytest: it also stopped pytest from caching its
# assertion-rewritten test modules, so every worker parsed and rewrote all of test/ again
# (1.8 CPU-s a worker; collection 5.9 -> 3.7 CPU-s with the cache).
# kernels: the step kernels compiled and auto's costs calibrated for the sources as they are
# now (1 CPU-s when nothing changed). The venv's setup does it once; after a pull that changes
# a kernel, the suite's CLI processes would each recompile it and recalibrate inside their
# runs (a stale calibration is measured again where it is first needed).
kernels: venv
	@$(PY) -m rigid_body_sim.compiled > /dev/null

test: venv bytecode kernels
	PYTHONDONTWRITEBYTECODE= $(PY) -m pytest -v -n $(TEST_WORKERS) --dist loadfile \
	  --no-loadscope-reorder $(PYTEST_ARGS)

# Only the files that mark tests fast are collected (-m still picks the tests): collecting
# the ROS files too cost each worker 4 CPU-s of imports for tests it deselects.
CHECK_PATHS ?= $(shell grep -l 'mark\.fast' test/test_*.py)
check: venv bytecode
	PYTHONDONTWRITEBYTECODE= $(PY) -m pytest -q -n 2 -m 'fast and not slow' $(PYTEST_ARGS) $(CHECK_PATHS)

# The README's tour: one thumbnail per phenomenon of free rotation, into docs/tour.
tour: venv
	$(VENV)/bin/rigid-body-sim tour --out docs/tour

# The documentation (docs/, Sphinx + MyST) into out/docs: warnings are errors (-W), every
# internal reference must resolve (-n); the reference pages are generated from the code.
docs: venv
	$(PY) -m sphinx -b html -W --keep-going -n -q docs out/docs/html

bench: venv
	$(VENV)/bin/rigid-body-sim bench --out out/bench

venv: $(STAMP)

# Rebuilt only when a dependency pin, the package metadata or an interface definition
# changes; code is an editable install, and config/ and launch/ are linked, so edits need no
# reinstall. The interface build skips itself when its inputs are unchanged.
$(STAMP): requirements.txt requirements-peers.txt setup.py setup.cfg package.xml \
          .ci/make_venv.sh .ci/step.sh .ci/build_interfaces.sh .ci/wheel_cmake_paths.cmake $(INTERFACES)
	@echo "setting up $(VENV) (once; the details go to $(SETUP_LOG))"
	@rm -f $(SETUP_LOG)
	@sh .ci/step.sh $(SETUP_LOG) "setup 1/6: Python virtual environment" sh .ci/make_venv.sh $(VENV)
	@sh .ci/step.sh $(SETUP_LOG) "setup 2/6: dependencies (ROS 2 Jazzy wheels, numpy, scipy, numba, ...)" \
	  $(VENV)/bin/pip install --disable-pip-version-check -q -r requirements.txt
	@sh .ci/step.sh $(SETUP_LOG) "setup 3/6: the bench's peer (Basilisk, bsk; its pins clash with ours)" \
	  $(VENV)/bin/pip install --disable-pip-version-check -q --no-deps -r requirements-peers.txt
	@sh .ci/step.sh $(SETUP_LOG) "setup 4/6: this package (editable) and its ament layout" \
	  $(MAKE) --no-print-directory ament-layout
	@sh .ci/step.sh $(SETUP_LOG) "setup 5/6: message interfaces (tf2_msgs, simulation_interfaces)" \
	  sh .ci/build_interfaces.sh $(VENV)
	@sh .ci/step.sh $(SETUP_LOG) "setup 6/6: compiling the step kernels (numba, cached on disk)" \
	  $(PY) -m rigid_body_sim.compiled
	@touch $@

# Stage 3 of the setup: the editable install, and the venv as an ament prefix.
ament-layout:
	$(VENV)/bin/pip install --disable-pip-version-check -q --no-deps --no-build-isolation -e .
	$(PY) -m compileall -q -j 0 rigid_body_sim > /dev/null
	mkdir -p $(VENV)/share/ament_index/resource_index/packages $(VENV)/share/rigid_body_sim $(VENV)/lib/rigid_body_sim
	touch $(VENV)/share/ament_index/resource_index/packages/rigid_body_sim
	ln -sfn $(CURDIR)/package.xml $(VENV)/share/rigid_body_sim/package.xml
	ln -sfn $(CURDIR)/config $(VENV)/share/rigid_body_sim/config
	ln -sfn $(CURDIR)/launch $(VENV)/share/rigid_body_sim/launch
	for exe in $(NODES); do ln -sfn ../../bin/$$exe $(VENV)/lib/rigid_body_sim/$$exe; done

clean:
	rm -rf $(VENV) build install log
