# Two-command quickstart: `make reproduce` (rebuild every table and figure) and `make test` (the unit
# tests); `make test-all` is the whole suite, as CI runs it.
# Both create the virtual environment in .venv when it is missing and install the project into it.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
CORES ?= all

.PHONY: setup reproduce quick scale future benchmark test test-all cluster-test mutants lint dryrun bench docs clean

$(BIN)/.installed: pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[dev]'
	touch $@

setup: $(BIN)/.installed

reproduce: setup  ## every table and figure on the paper's protocol, the scorecard and the HTML report
	$(BIN)/snakemake --cores $(CORES)
	$(BIN)/snakemake --report results/report.html

quick: setup  ## the same pipeline on the small protocol (config/quick.yaml), under results/quick/
	$(BIN)/snakemake --cores $(CORES) --configfile config/quick.yaml

scale: setup  ## extra targets beyond the paper: Table 2 on all 1000 training and all 3000 oil rows, Table 3 on every frame, CV selection on 1000 rows
	$(BIN)/snakemake --cores $(CORES) table2_full table2_all table3_full selection_full

future: setup  ## the paper's future work, not in the paper: robust data term, new rows, denoising
	$(BIN)/snakemake --cores $(CORES) robust out_of_sample denoising

benchmark: setup  ## not in the paper: our defaults against tuned peers on six data sets, MCAR/MAR/MNAR (REPRODUCTION.md#benchmark)
	$(BIN)/snakemake --cores $(CORES) benchmark

test: setup  ## the unit tests: no Snakemake run, no data files (a few minutes)
	$(BIN)/python -m pytest -m "not pipeline and not realdata"

test-all: setup  ## the whole suite: unit, pipeline (Snakemake on config/quick.yaml) and real-data tests; what CI runs
	$(BIN)/python -m pytest

cluster-test: setup  ## (root) table1 and table3 on a one-node SLURM started here, byte-compared with a local run
	NLDR_PYTHON=$(BIN)/python bash tests/cluster/run_slurm_test.sh

mutants: setup  ## put known faults into a scratch copy one at a time; report which the tests catch
	$(BIN)/python tests/mutants.py

lint: setup
	$(BIN)/ruff check .
	$(BIN)/snakemake --lint

dryrun: setup
	$(BIN)/snakemake -n

# bench: the routine speed check, BLAS on one thread. Writes to results/benchmarks/: closed_form.csv and
# closed_form_fraction.csv (closed form against eigh), solvers.csv (full against auto eigensolver),
# profile_table2.txt and profile_table3.txt (cProfile of one Table 2 and one Table 3 solve).
bench: setup  ## speed benchmarks, CSVs in results/benchmarks/ (docs/PERFORMANCE.md)
	OPENBLAS_NUM_THREADS=1 $(BIN)/python benchmarks/bench_closed_form.py
	OPENBLAS_NUM_THREADS=1 $(BIN)/python benchmarks/bench_solvers.py eigensolver
	OPENBLAS_NUM_THREADS=1 $(BIN)/python benchmarks/bench_solvers.py profile

docs: setup  ## the documentation site in site/ (API from the docstrings, notebooks); warnings are errors
	$(BIN)/mkdocs build --strict

clean:  ## remove generated results (not the data or the environment)
	rm -rf results/tables results/figures results/runs results/notebooks results/benchmarks results/logs \
		results/quick results/report.md results/report.html results/scorecard.csv results/scorecard.html site
