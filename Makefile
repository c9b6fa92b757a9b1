# One entry point for a fresh machine: `make demo` (the main job) and `make test` (the suite).
# Setting up is part of both: a virtual environment with the CPU build of torch pinned for this
# machine (torch==2.13.0) and the package with its test extras, at the versions the suite was
# last run with (constraints.txt).
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= demo-output

.PHONY: setup demo test lint browser docs tables clean

setup: $(STAMP)

$(STAMP): pyproject.toml constraints.txt
	@echo "setup: a virtual environment in $(VENV) with torch 2.13.0 (CPU build, about 200 MB)"
	@echo "       and dualpixel with its test extras (about 2-4 minutes on a fresh machine)"
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet torch==2.13.0
	$(BIN)/python -m pip install --quiet -e ".[test]" -c constraints.txt
	touch $(STAMP)

# Synthesis + deblurring with the shipped model + evaluation, as an HTML report in $(OUT)/.
demo: $(STAMP)
	$(BIN)/dualpixel demo --output $(OUT)

# The report test opens the demo page in headless Chromium (Debian's package); install it where
# we may (root with apt), otherwise that one test is skipped and says why.
browser:
	@command -v chromium >/dev/null 2>&1 || echo "browser: installing Debian's chromium for the \
	  demo page's test (about a minute)"
	@command -v chromium >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
	  && (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium \
	  >/dev/null) || echo "chromium not installed: the browser test will be skipped"; }

# The API reference from the docstrings (mkdocs + mkdocstrings) into build/site/.
docs: $(STAMP)
	$(BIN)/mkdocs build --strict

lint: $(STAMP)
	$(BIN)/ruff check src tests hubconf.py $(wildcard benchmarks)

test: $(STAMP) lint browser
	@echo "test: the suite on 2 processes (about 8 minutes on 2 CPU cores)"
	$(BIN)/python -m pytest -n 2 -q --doctest-modules src/dualpixel tests

tables: $(STAMP)  # regenerate the README's and the model card's results tables
	$(BIN)/python -m dualpixel.evaluation.tables

clean:
	rm -rf $(VENV) $(OUT)
