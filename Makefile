# Set-up is part of every target: a fresh machine with Python 3.11 and pip needs nothing else.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
BENCH := $(VENV)/bin/msvdd-bench
STAMP := $(VENV)/.installed

.PHONY: venv test lint demo bench ablations perf docs viewer-shots clean

venv: $(STAMP)

# torch is installed first and alone so that no other requirement can pull a CUDA build.
$(STAMP): pyproject.toml constraints.txt
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c constraints.txt torch==2.13.0
	$(PY) -m pip install --quiet -c constraints.txt -e '.[dev]'
	touch $(STAMP)

# One pytest worker per core (pytest-xdist); the tests that start Ray share one worker (xdist_group).
test: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy
	$(PY) -m pytest -n auto --dist loadgroup

lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy

demo: $(STAMP)
	$(BENCH) demo --out runs/demo --replace

# The paper preset as two datasets from different seeds, both audited: dev (where every choice a method
# makes is made) and eval (only reported); Table I is trained and scored on eval, then the fusion ablation of
# `context-net-frames` (`terms`: its audio and IMU terms alone) is written to runs/paper-terms/, and `make
# docs` writes the results pages. Hours on 2 cores: stopped, `make bench` again resumes (--resume reuses
# every model the stopped run finished; --reuse prints an audit already made of the same dataset with the
# same code instead of running it again).
bench: $(STAMP)
	test -d runs/paper-dev || $(BENCH) generate --preset paper --seed 1 --out runs/paper-dev
	test -d runs/paper-eval || $(BENCH) generate --preset paper --seed 2 --out runs/paper-eval
	$(BENCH) audit runs/paper-dev --out runs/paper-dev-audit --reuse
	$(BENCH) audit runs/paper-eval --out runs/paper-eval-audit --reuse
	$(BENCH) run --preset paper --data runs/paper-eval --dev runs/paper-dev --out runs/paper --resume
	$(BENCH) terms runs/paper/models/context-net-frames-seed* --data runs/paper-eval --no-progress \
		--md runs/paper-terms/context-net-frames.md --json runs/paper-terms/context-net-frames.json
	$(MAKE) docs

# The module, fusion and latent ablations on the eval dataset that `make bench` generated.
ablations: $(STAMP)
	$(BENCH) run --preset paper --data runs/paper-eval --dev runs/paper-dev --out runs/paper-ablations \
		--methods ablations --resume
	$(MAKE) docs

perf: $(STAMP)
	$(BENCH) perf --stage all --json runs/perf.json

# docs/results.md, the README's headline table and the method list of docs/detectors.md, from the results
# files there are, in this order: `make bench`'s run (the first gives the README's table), runs on fresh
# seeds (runs/paper-seed*), the ablation runs (runs/paper-ablations*, runs/paper-fusions*,
# runs/paper-latent*), `make demo`'s run, and the speed figures when present. Every figure of the pages
# comes from those files (`msvdd-bench docs --help`).
DOCS_FOLDERS ?= runs/paper runs/paper-seed* runs/paper-ablations* runs/paper-fusions* runs/paper-latent* runs/demo
DOCS_RUNS ?= $(foreach f,$(DOCS_FOLDERS),$(sort $(patsubst %/results.json,%,$(wildcard $(f)/results.json))))
DOCS_PERF ?= $(wildcard runs/perf.json)
DOCS_SWEEP ?= $(wildcard runs/sweep-severity/sweep.json)
docs: $(STAMP)
	$(BENCH) docs $(DOCS_RUNS) $(if $(DOCS_PERF),--perf $(DOCS_PERF)) $(if $(DOCS_SWEEP),--sweep $(dir $(DOCS_SWEEP)))

# Screenshots of the Rerun web viewer (headless Chromium, software rendering) of a collision and a fault
# episode of `make demo`'s run, at 1440x900 and 1920x1080, into assets/screenshots/. Needs Chromium
# (`apt-get install chromium`); one browser at a time, about a minute a shot. Not part of `make test` or CI.
SHOTS_DATA ?= runs/demo/dataset
SHOTS_MODEL ?= runs/demo/models/msvdd-seed0
SHOTS_EPISODES ?= test-collision-001 test-fault-001 test-fault-000
viewer-shots: $(STAMP)
	@test -d $(SHOTS_DATA) || { echo "no dataset at $(SHOTS_DATA): run make demo first"; exit 2; }
	$(PY) -m benchmarks.viz.shots --data $(SHOTS_DATA) --model $(SHOTS_MODEL) \
		$(foreach e,$(SHOTS_EPISODES),--episode $(e)) --out assets/screenshots

clean:
	rm -rf runs build *.egg-info
