# bb_friction_ros: `make test` and `make demo` are the only commands a newcomer needs; both set
# up .venv first when needed (tools/setup_venv.py, a fast no-op once set up).

PYTHON ?= python3.11
VENV := .venv

# A bootstrap guard inherited from another ROS-wheels venv would stop .venv's python from
# setting its own LD_LIBRARY_PATH.
unexport _ROS_WHEELS_BOOTSTRAP_COMPLETE

.PHONY: setup test colcon-test demo clean distclean

setup:
	@command -v $(PYTHON) >/dev/null || { echo "make: $(PYTHON) not found: install" \
	  "CPython 3.11, or run make PYTHON=/path/to/python3.11 ..." >&2; exit 1; }
	@$(PYTHON) tools/setup_venv.py

# The suite runs on TEST_WORKERS pytest-xdist workers (2: the cores of the machines it is
# measured on; 0 runs it in the pytest process itself). Each worker is a session of its own: its own
# ROS_DOMAIN_ID (test/conftest.py), its own temporary directories.
TEST_WORKERS ?= 2

test: setup
	$(VENV)/bin/python -m pytest -q -n $(TEST_WORKERS) test

# A ROS 2 workspace as a user lays it out (README, "Building in a ROS 2 workspace"): the
# repository and the link to its interface package under build/ws/src, built and tested by
# colcon (pinned in requirements.txt) over the venv's ROS wheels. Fails on any test failure.
WS := build/ws
VENV_ABS := $(CURDIR)/$(VENV)
COLCON_ENV := PATH="$(VENV_ABS)/bin:$$PATH" VIRTUAL_ENV="$(VENV_ABS)" \
	AMENT_PREFIX_PATH="$(VENV_ABS)" CMAKE_PREFIX_PATH="$(VENV_ABS)" COLCON_HOME="$(CURDIR)/$(WS)/.colcon"

colcon-test: setup
	rm -rf $(WS)
	mkdir -p $(WS)/src
	ln -s $(CURDIR) $(WS)/src/bb_friction_ros
	ln -s bb_friction_ros/msg_defs/bb_friction_msgs $(WS)/src/bb_friction_msgs
	cd $(WS) && $(COLCON_ENV) colcon build --event-handlers console_cohesion+ \
		--cmake-args -DPython3_EXECUTABLE=$(VENV_ABS)/bin/python -DCMAKE_BUILD_TYPE=Release
	cd $(WS) && $(COLCON_ENV) colcon test --return-code-on-test-failure \
		--event-handlers console_cohesion+ --pytest-args -q -n $(TEST_WORKERS)
	cd $(WS) && $(COLCON_ENV) colcon test-result --verbose

demo: setup
	$(VENV)/bin/bb-friction reproduce --out out/reproduce
	$(VENV)/bin/bb-friction demo --out out/demo
	$(VENV)/bin/bb-friction discrepancy out/demo/demo_bag --out out/discrepancy --no-progress
	$(VENV)/bin/bb-friction replay out/demo/demo_bag --config out/discrepancy/augmented.yaml \
		--out out/demo/replay_augmented --no-progress

# Build products and outputs; keeps .venv (see distclean).
clean:
	rm -rf build out .pytest_cache *.egg-info
	find . -path ./.venv -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +

# Everything generated, including .venv: the next make test sets up from scratch.
distclean: clean
	rm -rf $(VENV)
