# One entry point for a fresh machine: `make demo` (the main job) and `make test` (the suite).
# Setting up is part of both: a virtual environment with the CPU build of torch pinned for this
# machine (torch==2.13.0) and the package with its test extras.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= demo-output

.PHONY: setup demo test lint clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet torch==2.13.0
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/dualpixel psf --output $(OUT)/psf_figure.png --save $(OUT)/psf_kernels.npz
	$(BIN)/dualpixel scenes --output $(OUT)/scenes --sequences 2 --frames 4 --size 320x240 --seed 0
	$(BIN)/dualpixel synth --input $(OUT)/scenes --format rgbd --output $(OUT)/dataset --workers 2
	$(BIN)/dualpixel preview --dataset $(OUT)/dataset --output $(OUT)/dataset_preview.png --rows 5

lint: $(STAMP)
	$(BIN)/ruff check src tests $(wildcard benchmarks)

test: $(STAMP) lint
	$(BIN)/python -m pytest -n 2 -q tests

clean:
	rm -rf $(VENV) $(OUT)
