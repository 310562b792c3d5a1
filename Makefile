# Two entry points (see README): `make demo` and `make test`. Both set up first.
VENV ?= .venv
PY := $(VENV)/bin/python
DEMO_OUT ?= runs/demo

.PHONY: setup demo test test-fast bench clean

setup:
	@bash scripts/setup.sh

demo: setup
	$(PY) -m mpcde fly data/scenarios/forest_swarm.yaml --mode comm --out $(DEMO_OUT) --seed 0 --video --overwrite

test: setup
	$(PY) -m pytest -q

test-fast: setup
	$(PY) -m pytest -q -m "not slow"

bench: setup
	$(PY) -m mpcde bench --out runs/bench --overwrite

clean:
	rm -rf runs .pytest_cache
