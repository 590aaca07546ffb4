# ssbench — the two commands: `make report` (main job) and `make test`. Both bootstrap what they need.
PY          ?= python3
VENV        ?= .venv
TORCH_SPEC  ?= torch==2.13.0
PYTHON      := $(VENV)/bin/python
PIP         := $(VENV)/bin/pip
STAMP       := $(VENV)/.ssbench-installed
DEV_STAMP   := $(VENV)/.ssbench-dev-installed
LESSONS_STAMP := $(VENV)/.ssbench-lessons-installed
REPORT_ARGS ?=
PYTEST_ARGS ?=
# test workers (pytest-xdist; an idle worker takes tests queued for the other; 0: all in this process)
TEST_WORKERS ?= 2
XDIST       := -n $(TEST_WORKERS) --dist worksteal
JUPYTER_ARGS ?=

.PHONY: setup setup-dev llvm browser test test-fast report info bench gpu-check lessons lessons-sync clean

## setup: create .venv, install CPU torch first (override TORCH_SPEC), then the project (what `make report` needs)
setup: $(STAMP) llvm

## setup-dev: setup plus the test extras (pytest, notebook execution) that `make test` needs
setup-dev: $(DEV_STAMP) llvm

$(STAMP): pyproject.toml
	test -x $(PYTHON) || $(PY) -m venv $(VENV)
	$(PIP) install -q "$(TORCH_SPEC)"
	$(PIP) install -q -e .
	touch $(STAMP)

$(DEV_STAMP): $(STAMP)
	$(PIP) install -q -e ".[dev]"
	touch $(DEV_STAMP)

## llvm: make sure Dr.Jit has a working libLLVM (installs Debian's libllvm19 when apt is usable)
llvm:
	@sh scripts/ensure_llvm.sh

## browser: make sure a headless Chromium exists for the report's browser test (installs Debian's chromium when apt is usable)
browser:
	@sh scripts/ensure_chromium.sh

## test: the whole suite (slow tests included, as in CI)
test: setup-dev browser
	MPLBACKEND=Agg $(PYTHON) -m pytest $(XDIST) $(PYTEST_ARGS)

## test-fast: skip the slow (rendering / subprocess) tests
test-fast: setup-dev
	MPLBACKEND=Agg $(PYTHON) -m pytest $(XDIST) -m "not slow" $(PYTEST_ARGS)

## report: the main job — reference renders of the built-in scenes into reports/latest/index.html
report: setup
	MPLBACKEND=Agg $(PYTHON) -m ssbench report --out reports $(REPORT_ARGS)

info: setup
	$(PYTHON) -m ssbench info

## lessons: open the step-through notebooks (lessons/) in JupyterLab; installs the lessons extra first
lessons: $(LESSONS_STAMP) llvm
	cd lessons && "$(abspath $(VENV))/bin/jupyter" lab $(JUPYTER_ARGS)

$(LESSONS_STAMP): $(STAMP)
	$(PIP) install -q -e ".[dev,lessons]"
	touch $(LESSONS_STAMP)

## lessons-sync: rebuild every lessons/NN_*.ipynb from its .py source (no outputs); tests/lessons checks the pairs
lessons-sync: $(DEV_STAMP)
	$(PYTHON) lessons/_sync.py

## bench: every AO/SSR pass x {320x240, 640x360, 1920x1080} against both floors (ms, ns/px, peak MiB), G-buffer
## timing, implicit evaluators (torch vs Dr.Jit) and marchers (prints numbers; not a test). BENCH_ARGS adds options.
bench: setup
	$(PYTHON) benchmarks/bench_passes.py $(BENCH_ARGS)
	$(PYTHON) benchmarks/bench_ao_reference.py
	$(PYTHON) benchmarks/bench_gbuffer.py
	$(PYTHON) benchmarks/bench_implicit.py

## gpu-check: every AO and SSR pass once on CUDA and once on the CPU: times and agreement (needs a CUDA torch)
gpu-check: setup
	$(PYTHON) scripts/gpu_check.py

clean:
	rm -rf $(VENV) reports/2* reports/latest .pytest_cache
