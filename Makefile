# Two commands for a fresh machine:
#   make run    set up the venv, install, run the main job on the default scene
#   make test   set up the venv, install, lint, type-check and pass the tests
# Everything runs from the venv in $(VENV); versions are pinned in constraints.txt.

VENV ?= .venv
PY := $(VENV)/bin/python
SCENE ?= default
# DDS stays on this machine; each run picks its own domain so parallel runs never meet.
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export ROS_DOMAIN_ID ?= $(shell python3 -c 'import random; print(random.randint(1, 100))')
export RMW_IMPLEMENTATION ?= rmw_fastrtps_cpp
# Fast DDS sockets on 127.0.0.1 only (config/fastdds_localhost.xml; README: across hosts).
export FASTRTPS_DEFAULT_PROFILES_FILE ?= $(CURDIR)/config/fastdds_localhost.xml
export FASTDDS_DEFAULT_PROFILES_FILE ?= $(FASTRTPS_DEFAULT_PROFILES_FILE)

.PHONY: setup run demo test lint typecheck pytest docs docs-reference docs-figure bench clean

setup: $(VENV)/.installed

$(VENV)/.installed: setup.py setup.cfg package.xml constraints.txt
	test -x $(PY) || python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c constraints.txt -e '.[ros,plots,peers,jit,identify,test,docs]'
	touch $@

run: setup
	$(VENV)/bin/pendulum_node --scene $(SCENE)

demo: setup
	$(VENV)/bin/pendulum_demo

test: setup lint typecheck pytest docs

lint: setup
	$(VENV)/bin/ruff check .

typecheck: setup
	$(VENV)/bin/mypy

pytest: setup
	$(VENV)/bin/pytest -q --durations=15

# The documentation, warnings (broken links and references included) as errors. The reference
# tables are written from the code first (docs/_ext/reftables.py), so they cannot go stale.
docs: setup
	$(VENV)/bin/sphinx-build -q -n -W --keep-going -b html docs docs/_build/html

docs-reference: setup
	$(PY) docs/_ext/reftables.py docs/reference/_generated

# The README's picture: the paper's Fig 3 (angle for n = 1..5) drawn by pendulum_report.
docs-figure: setup
	$(VENV)/bin/pendulum_report paper --out build/paper --force --no-progress
	cp build/paper/fig3_phi.png docs/_static/pendulum.png

# Each benchmark prints its figures and bench/record.py keeps them, with the machine and the
# date, in bench/results/<script>.txt (the docs include these files).
bench: setup
	$(PY) bench/record.py bench/bench_core.py
	$(PY) bench/record.py bench/bench_jit.py
	$(PY) bench/record.py bench/bench_sweep_jit.py
	$(PY) bench/record.py bench/bench_sweep_careful.py
	$(PY) bench/record.py bench/bench_node.py --duration 60
	$(PY) bench/record.py bench/bench_recording.py --seconds 10 --node
	$(PY) bench/record.py bench/bench_sync.py --seconds 10
	$(PY) bench/record.py bench/bench_parameter_storm.py --count 10000 --rate 1000
	$(PY) bench/record.py bench/bench_work_precision.py
	$(PY) bench/record.py bench/bench_work_precision_real_n.py
	$(PY) bench/record.py bench/bench_near_coulomb.py
	$(PY) bench/record.py bench/bench_grade_window.py
	$(PY) bench/record.py bench/bench_servo.py --png bench/results/servo_tracking.png
	$(PY) bench/record.py bench/bench_testbench.py
	$(PY) bench/record.py bench/bench_gym.py

clean:
	rm -rf $(VENV) build install log .pytest_cache .mypy_cache .ruff_cache docs/_build
