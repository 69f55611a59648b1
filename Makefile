# bb_friction_ros: `make test` and `make demo` are the only commands a newcomer needs; both set
# up .venv first when needed (tools/setup_venv.py, a fast no-op once set up).

PYTHON ?= python3.11
VENV := .venv

# A bootstrap guard inherited from another ROS-wheels venv would stop .venv's python from
# setting its own LD_LIBRARY_PATH.
unexport _ROS_WHEELS_BOOTSTRAP_COMPLETE

.PHONY: setup test demo clean distclean

setup:
	@command -v $(PYTHON) >/dev/null || { echo "make: $(PYTHON) not found: install" \
	  "CPython 3.11, or run make PYTHON=/path/to/python3.11 ..." >&2; exit 1; }
	@$(PYTHON) tools/setup_venv.py

test: setup
	$(VENV)/bin/python -m pytest -q test

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
