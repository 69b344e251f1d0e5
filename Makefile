# Two entry points for a fresh machine: `make paper` (main job) and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= out/paper

.PHONY: setup paper test bench bench-peer clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --upgrade --quiet pip
	$(BIN)/pip install --quiet -e ".[test,fast]"
	touch $(STAMP)

setup: $(STAMP)

paper: $(STAMP)
	$(BIN)/rockfrac paper --out $(OUT)

test: $(STAMP)
	$(BIN)/python -m mypy
	$(BIN)/python -m pytest

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py

# rockfrac against Akantu (installed into its own .venv-akantu by the script)
bench-peer: $(STAMP)
	$(BIN)/python benchmarks/peer.py

clean:
	rm -rf $(VENV) out

.PHONY: kernels scaling
kernels: $(STAMP)
	$(BIN)/python benchmarks/kernels.py

scaling: $(STAMP)
	$(BIN)/python benchmarks/scaling.py
