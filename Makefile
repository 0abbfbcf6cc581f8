# Two entry points (see README): `make demo` runs the main job, `make test` runs the tests.
# Each creates .venv with the interpreter found as $(PYTHON) and installs what it needs.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: demo test install bench notebooks clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

install: $(BIN)/python
	$(BIN)/python -m pip install --quiet -e ".[dev]"

demo: install
	$(BIN)/crane-planner demo --out demo-output

test: install
	$(BIN)/python -m pytest -q -n 2 --dist worksteal   # idle workers take queued tests: no tail

bench: install
	$(BIN)/python benchmarks/bench_model.py
	$(BIN)/python benchmarks/bench_dp_laws.py
	$(BIN)/python benchmarks/seed000_tables.py
	$(BIN)/python benchmarks/bench_nlp.py --energy 60
	$(BIN)/python benchmarks/seed002_table.py
	$(BIN)/python benchmarks/seed003_paths.py
	$(BIN)/python benchmarks/seed003_nlp.py
	cd benchmarks && ../$(BIN)/python bench_pareto.py
	$(BIN)/python benchmarks/bench_library.py
	$(BIN)/python benchmarks/bench_library.py --skip-full --skip-scaling --executors
	$(BIN)/python benchmarks/bench_library_warmstart.py
	$(BIN)/python benchmarks/bench_energy_rounds.py --moves 36
	$(BIN)/python benchmarks/bench_discrepancy.py
	$(BIN)/python benchmarks/bench_discrepancy_open.py
	$(BIN)/python benchmarks/bench_discrepancy_open.py --clean-only --scale 1.5 --duration 12
	$(BIN)/python benchmarks/bench_discrepancy_excite.py --seeds 3 --seed-base 600 --magnitude 0.2 1 --workers 2 --default-duration 15 --speed 0.15 0.35 --duration 60 --starts 3 --budget 30 --fitted --max-duration 240
	$(BIN)/python benchmarks/bench_discrepancy_structure.py --states 4000
	$(BIN)/python benchmarks/bench_discrepancy_exudyn.py --seeds 1 --duration 20
	$(BIN)/python benchmarks/bench_discrepancy_exudyn.py --dynamic --seeds 2
	$(BIN)/python benchmarks/bench_exudyn_library.py --executors processes:2,local:2
	$(BIN)/python benchmarks/bench_scaling.py
	$(BIN)/python benchmarks/bench_exudyn.py
	$(BIN)/python benchmarks/bench_exudyn_claims.py
	$(BIN)/python benchmarks/bench_exudyn_grapple.py
	$(BIN)/python benchmarks/bench_exudyn_energy_gap.py
	$(BIN)/python benchmarks/bench_exudyn_speed.py --repeat 3
	$(BIN)/python benchmarks/bench_faults.py
	$(BIN)/python benchmarks/dp_memory.py
	$(BIN)/python benchmarks/urdf_round_trip.py
	$(BIN)/python benchmarks/bench_peers.py
	$(BIN)/python benchmarks/bench_nlp_cache.py
	$(BIN)/crane-planner bench --out benchmarks/results/bench
	$(BIN)/python notebooks/run_notebooks.py --out build/notebooks
	$(BIN)/python -m pytest -q -n 2 -m slow   # the long studies kept out of `make test`

# the notebook studies: check each .ipynb is in step with its jupytext .py source, then run
# them with their full settings into build/notebooks (not in place)
notebooks: install
	$(BIN)/python notebooks/run_notebooks.py --check
	$(BIN)/python notebooks/run_notebooks.py --out build/notebooks

clean:
	rm -rf $(VENV) demo-output build *.egg-info
