# rod_sim developer tasks. `make test` is what CI runs (through .ci/run).
# The virtual environment is created from scratch when missing; the package (with its ROS 2
# Jazzy wheels and every optional extra) is reinstalled only when setup.py changes.

PYTHON ?= python3
VENV ?= .venv
VPY = $(VENV)/bin/python
STAMP = $(VENV)/.installed
WARM = $(VENV)/.jit-warm

# Tests that start a ROS graph pick their own ROS_DOMAIN_ID; this default keeps everything else
# off the common domain 0. Discovery never leaves the machine.
ROS_DOMAIN_ID ?= 42
ROS_ENV = ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=$(ROS_DOMAIN_ID)

PYTEST_ARGS ?=

.PHONY: venv warm test demo bench bench-report clean

venv: $(STAMP) $(WARM)

$(VPY):
	$(PYTHON) -m venv $(VENV)

$(STAMP): setup.py | $(VPY)
	$(VPY) -m pip install -q --upgrade pip
	$(VPY) -m pip install -q -e '.[ros,test,plot,peer,sweep,view]'
	touch $(STAMP)

# Compile every registered model x integrator (and the hinge drivers) into numba's cache, so
# that the first command does not wait ~20 s for it; again whenever a module of rod_sim/core
# that holds compiled code changes (rod_sim/core/jit.py: the modules that name njit).
warm: $(WARM)

$(WARM): $(STAMP) $(shell grep -l njit rod_sim/core/*.py)
	$(VPY) -m rod_sim.tools.jit_warm
	touch $(WARM)

test: venv
	$(ROS_ENV) $(VPY) -m pytest $(PYTEST_ARGS)

# The mission end to end: Table 1; the ROS 2 node (reduced model) with the hinge PD controller
# over topics, in lockstep (one control period per command: the same log on any machine, loaded
# or not), recorded to out/demo.mcap; then the log re-run through the full model: verdict, table
# and plot out/demo_compare.png. Drop --sync for the real-time pace.
demo: venv
	$(VENV)/bin/rod-sim table1
	mkdir -p out
	$(ROS_ENV) $(VPY) -m rod_sim.ros.demo --out out/demo.mcap --duration 3 --sync --force
	rm -f out/demo_compare.png
	$(VENV)/bin/rod-sim compare out/demo.mcap --plot out/demo_compare.png

bench: venv
	$(VENV)/bin/rod-sim bench

# Regenerates docs/bench/ (results.md, bench.json, work-precision and scaling plots); ~40 min.
bench-report: venv
	$(VENV)/bin/rod-sim bench --out docs/bench

clean:
	rm -rf build install log out .pytest_cache *.egg-info
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -exec rm -rf {} +
