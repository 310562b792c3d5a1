# Two entry points (see README): `make demo` and `make test`. Both set up first.
VENV ?= .venv
PY := $(VENV)/bin/python
DEMO_OUT ?= runs/demo

.PHONY: setup demo test test-fast bench bench-peer clean

setup:
	@bash scripts/setup.sh

demo: setup
	$(PY) -m mpcde fly data/scenarios/forest_swarm.yaml --mode comm --out $(DEMO_OUT) --seed 0 --video --overwrite

test: setup
	$(PY) -m pytest -q --durations=20

test-fast: setup
	$(PY) -m pytest -q -m "not slow"

bench: setup
	$(PY) -m mpcde bench --out runs/bench --overwrite

# The PyFlyt peer row of benchmarks/bench_sim.py. PyFlyt 0.29.0 (its newest release) declares numpy<2 and the
# lock pins numpy 2.4.6, so pip cannot resolve it as an extra; its core runs on numpy 2, so it is installed
# here without its declared dependencies (gymnasium is the one it imports). `pip check` will name the pin.
bench-peer: setup
	$(PY) -m pip install -q --no-deps PyFlyt==0.29.0 gymnasium==1.4.0 farama-notifications==0.0.6
	$(PY) benchmarks/bench_sim.py --only-rtf

clean:
	rm -rf runs .pytest_cache
