# Two commands for users:  make demo   (set up, then run the live demo)
#                          make test   (set up, then run the whole test suite)
# For developers:          make check  (physics, engine and lint only: under a minute)
# Setup is a .venv in the repo that is also an ament prefix for this package,
# so `ros2 run`-style lookups (lib/rigid_body_sim/<exe>, ament index) work in it.

VENV        ?= .venv
PY          := $(VENV)/bin/python
STAMP       := $(VENV)/.rigid_body_sim-installed
DEMO_DURATION ?= 30
DEMO_OUT    ?= out/demo
PYTEST_ARGS ?=
NODES       := simulator controller recorder replay viewer
# tf2_msgs and simulation_interfaces, built into the venv by .ci/build_interfaces.sh
INTERFACES  := $(wildcard interfaces/* interfaces/*/* interfaces/*/*/*)

.PHONY: demo test check venv bench clean
.DEFAULT_GOAL := demo

demo: venv
	$(VENV)/bin/rigid-body-sim demo --duration $(DEMO_DURATION) --out $(DEMO_OUT)

# -v names each test as it starts, so a long one (the benchmark) shows where the run is.
test: venv
	$(PY) -m pytest -v $(PYTEST_ARGS)

check: venv
	$(PY) -m pytest -q -m fast $(PYTEST_ARGS)

bench: venv
	$(VENV)/bin/rigid-body-sim bench --out out/bench

venv: $(STAMP)

# Rebuilt only when a dependency pin, the package metadata or an interface definition
# changes; code is an editable install, and config/ and launch/ are linked, so edits need no
# reinstall. The interface build skips itself when its inputs are unchanged.
$(STAMP): requirements.txt setup.py setup.cfg package.xml .ci/make_venv.sh \
          .ci/build_interfaces.sh .ci/wheel_cmake_paths.cmake $(INTERFACES)
	sh .ci/make_venv.sh $(VENV)
	$(VENV)/bin/pip install --disable-pip-version-check -q -r requirements.txt
	$(VENV)/bin/pip install --disable-pip-version-check -q --no-deps --no-build-isolation -e .
	mkdir -p $(VENV)/share/ament_index/resource_index/packages $(VENV)/share/rigid_body_sim $(VENV)/lib/rigid_body_sim
	touch $(VENV)/share/ament_index/resource_index/packages/rigid_body_sim
	ln -sfn $(CURDIR)/package.xml $(VENV)/share/rigid_body_sim/package.xml
	ln -sfn $(CURDIR)/config $(VENV)/share/rigid_body_sim/config
	ln -sfn $(CURDIR)/launch $(VENV)/share/rigid_body_sim/launch
	for exe in $(NODES); do ln -sfn ../../bin/$$exe $(VENV)/lib/rigid_body_sim/$$exe; done
	sh .ci/build_interfaces.sh $(VENV)
	@echo "compiling the step kernels (numba, cached on disk; once)"
	$(PY) -m rigid_body_sim.compiled
	touch $@

clean:
	rm -rf $(VENV) build install log
