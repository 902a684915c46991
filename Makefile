# rod_sim developer tasks. `make test` is what CI runs (through .ci/run).
# The virtual environment is created from scratch when missing; the package (with its ROS 2
# Jazzy wheels and every optional extra) is reinstalled only when setup.py changes.

PYTHON ?= python3
VENV ?= .venv
VPY = $(VENV)/bin/python
STAMP = $(VENV)/.installed

# Tests that start a ROS graph pick their own ROS_DOMAIN_ID; this default keeps everything else
# off the common domain 0. Discovery never leaves the machine (SPEC section 7).
ROS_DOMAIN_ID ?= 42
ROS_ENV = ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_DOMAIN_ID=$(ROS_DOMAIN_ID)

PYTEST_ARGS ?=

.PHONY: venv test demo bench bench-report clean

venv: $(STAMP)

$(VPY):
	$(PYTHON) -m venv $(VENV)

$(STAMP): setup.py | $(VPY)
	$(VPY) -m pip install --upgrade pip
	$(VPY) -m pip install -e '.[ros,test,plot,peer,sweep]'
	touch $(STAMP)

test: venv
	$(ROS_ENV) $(VPY) -m pytest $(PYTEST_ARGS)

demo: venv
	$(VENV)/bin/rod-sim table1
	mkdir -p out
	rm -f out/paper_example_reduced.mcap
	$(VENV)/bin/rod-sim simulate config/paper_example.yaml --model reduced --t-end 2 \
		--out out/paper_example_reduced.mcap

bench: venv
	$(VENV)/bin/rod-sim bench

# Regenerates docs/bench/ (results.md, bench.json, work-precision and scaling plots); ~30 min.
bench-report: venv
	$(VENV)/bin/rod-sim bench --out docs/bench

clean:
	rm -rf build install log out .pytest_cache *.egg-info
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -exec rm -rf {} +
