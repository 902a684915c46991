# rod_sim developer tasks. `make test` (the quick suite) and `make test-slow` (the tests marked
# slow) are what CI runs, both (through .ci/run); `make flake` hunts flaky tests under load.
# The virtual environment is created from scratch when missing; the package (with its ROS 2
# Jazzy wheels and every optional extra) is reinstalled only when setup.py changes.

PYTHON ?= python3
VENV ?= .venv
VPY = $(VENV)/bin/python
STAMP = $(VENV)/.installed
STAMP_DEMO = $(VENV)/.installed-demo
ALL_EXTRAS = ros,test,plot,peer,sweep,view
DEMO_EXTRAS = ros,plot
WARM = $(VENV)/.jit-warm
WARM_DEMO = $(VENV)/.jit-warm-demo

# Tests that start a ROS graph take their ROS_DOMAIN_IDs from test/ros_domains.py (from
# ROD_SIM_TEST_DOMAIN_BASE when set, else from a block of ids each test process claims, so that
# runs side by side do not meet: docs/testing.md); this default keeps everything else off the
# common domain 0. Discovery never leaves the machine.
ROS_DOMAIN_ID ?= 42
ROS_ENV = ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=$(ROS_DOMAIN_ID)

PYTEST_ARGS ?=
# make flake: repeats of the ros- and timing-marked tests beside one busy loop per core
N ?= 20
FLAKE_ARGS ?=

.PHONY: venv warm warm-demo test test-slow flake demo bench bench-report clean

venv: $(STAMP)

$(VPY):
	$(PYTHON) -m venv $(VENV)

# pip -q is silent for a minute or more: heartbeat.py says every 8 s that it is still at work
HEARTBEAT = $(VPY) rod_sim/tools/heartbeat.py

# `make demo` installs what it runs (the ROS 2 wheels and matplotlib: ~21 s from pip's cache
# against ~65 s with the test and peer extras); every other target installs everything.
# $(call install,EXTRAS,WHAT): pip upgraded, then rod_sim with EXTRAS (WHAT says it in words)
define install
	$(HEARTBEAT) "upgrading pip in $(VENV)" -- $(VPY) -m pip install -q --upgrade pip
	$(HEARTBEAT) "installing rod_sim, the ROS 2 Jazzy wheels and $(2) into $(VENV)" -- \
		$(VPY) -m pip install -q -e '.[$(1)]'
endef

$(STAMP_DEMO): setup.py | $(VPY)
	$(call install,$(DEMO_EXTRAS),matplotlib)
	touch $(STAMP_DEMO)

$(STAMP): setup.py | $(VPY)
	$(call install,$(ALL_EXTRAS),the extras)
	touch $(STAMP) $(STAMP_DEMO)

# Compile drivers into numba's cache ahead of use, in 2 processes, with a line at least every
# 10 s; again whenever a module of rod_sim/core that holds compiled code changes
# (rod_sim/core/jit.py: the modules that name njit). `make demo` compiles only what it runs
# (warm-demo: 50 s cold at load ~1.3, 96 s of CPU); `make test` every registered model x
# integrator (warm: 258 s cold at load ~1.4, 417 s of CPU). Anything not compiled ahead compiles on first use, with a notice saying what, why
# and how long (docs/install.md; measured times: docs/benchmarks.md).
COMPILED = $(shell grep -l njit rod_sim/core/*.py)

# rod_sim's bytecode, written ahead: Python caches it by itself unless PYTHONDONTWRITEBYTECODE
# is set (as on this project's CI machine), and then every process compiled rod_sim's modules
# again (a warm 10 ms `rod-sim simulate` of the paper example, alternating: 1.7-2.7 s without,
# 1.6-2.3 s with the bytecode, faster in 8 of 9 pairs at load 0.2-1; 2.8-2.9 s against 2.0-2.2 s
# beside a CI run). compileall writes it whatever that variable says;
# imports read it; a module edited since is compiled in memory until the next `make`.
BYTECODE = $(VENV)/.bytecode
SOURCES = $(shell find rod_sim -name '*.py')
$(BYTECODE): $(SOURCES) | $(VPY)
	$(VPY) -m compileall -q rod_sim
	touch $(BYTECODE)

warm: $(WARM)

warm-demo: $(WARM_DEMO)

$(WARM): $(STAMP) $(COMPILED)
	$(VPY) -m rod_sim.tools.jit_warm
	touch $(WARM) $(WARM_DEMO)

$(WARM_DEMO): $(STAMP_DEMO) $(COMPILED)
	$(VPY) -m rod_sim.tools.jit_warm --demo
	touch $(WARM_DEMO)

# Every test not marked slow (docs/testing.md; the time it takes: docs/benchmarks.md); test-slow
# runs the rest.
test: venv $(WARM) $(BYTECODE)
	$(ROS_ENV) $(VPY) -m pytest -m "not slow" $(PYTEST_ARGS)

test-slow: venv $(WARM) $(BYTECODE)
	$(ROS_ENV) $(VPY) -m pytest -m slow $(PYTEST_ARGS)

# Each test marked ros or timing N times beside one busy loop per core: its failure rate in a
# table (reports in out/flake/); exit 1 if any failed. Not part of `make test`.
flake: venv $(WARM) $(BYTECODE)
	$(ROS_ENV) $(VPY) test/flake_hunt.py --repeats $(N) $(FLAKE_ARGS)

# The mission end to end: Table 1; the ROS 2 node (reduced model) with the hinge PD controller
# over topics, in lockstep (one control period per command: the same log on any machine, loaded
# or not), recorded to out/demo.mcap; then the log re-run through the full model: verdict, table
# and plot out/demo_compare.png. Drop --sync for the real-time pace.
demo: $(STAMP_DEMO) $(WARM_DEMO) $(BYTECODE)
	$(VENV)/bin/rod-sim table1
	mkdir -p out
	$(ROS_ENV) $(VPY) -m rod_sim.ros.demo --out out/demo.mcap --duration 3 --sync --force
	rm -f out/demo_compare.png
	$(VENV)/bin/rod-sim compare out/demo.mcap --plot out/demo_compare.png

bench: venv $(WARM) $(BYTECODE)
	$(VENV)/bin/rod-sim bench

# Regenerates docs/bench/ (results.md, bench.json, work-precision and scaling plots); ~40 min.
bench-report: venv $(WARM) $(BYTECODE)
	$(VENV)/bin/rod-sim bench --out docs/bench

clean:
	rm -rf build install log out .pytest_cache *.egg-info
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -exec rm -rf {} +
