# Two entry points for a fresh machine: `make paper` (main job) and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= out/paper
MPI_VENV := .venv-mpi
MPI_STAMP := $(MPI_VENV)/.installed
PETSC_DIR ?= /usr/lib/petscdir/petsc3.18/x86_64-linux-gnu-real

.PHONY: setup paper test bench bench-peer clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --upgrade --quiet pip
	$(BIN)/pip install --quiet -e ".[test,fast]"
	touch $(STAMP)

setup: $(STAMP)

paper: $(STAMP)
	$(BIN)/rockfrac paper --out $(OUT)

# The kernels: the build step of a Numba package. `rockfrac compile` compiles every listed kernel on
# two processes into the kernel cache, once per version of the sources (a rule on every source
# file: an edit compiles them all again, as the cache's key does), not in each pytest worker and MPI
# rank (benchmarks/README.md, "The test suite's time"). Each venv has its own cache: .venv-mpi's
# NumPy 1 compiles its own.
SOURCES := $(shell find src/rockfrac -name '*.py') src/rockfrac/kernel_signatures.json
KERNELS := $(VENV)/.kernels
MPI_KERNELS := $(MPI_VENV)/.kernels

$(KERNELS): $(STAMP) $(SOURCES)
	$(BIN)/rockfrac compile
	touch $(KERNELS)

$(MPI_KERNELS): $(MPI_STAMP) $(SOURCES)
	PETSC_DIR=$(PETSC_DIR) NUMBA_CACHE_DIR=$(MPI_VENV)/numba-cache $(MPI_VENV)/bin/rockfrac compile
	touch $(MPI_KERNELS)

test: $(KERNELS) $(MPI_KERNELS)
	$(BIN)/python -m mypy
	$(BIN)/python -m pytest -n 2 --dist loadfile --no-loadscope-reorder
	PETSC_DIR=$(PETSC_DIR) NUMBA_CACHE_DIR=$(MPI_VENV)/numba-cache $(MPI_VENV)/bin/python -m pytest tests/mpi

# PETSc/MPI (issue 17): Debian's petsc4py (PETSc 3.18 with MUMPS, hypre) seen from a venv of Debian's
# own Python with its system site packages, NumPy < 2 (Debian's petsc4py is built against NumPy 1);
# the Debian packages are installed first where they are missing (a fresh machine of this kind).
# OpenBLAS (serial: the ranks share the cores) becomes the system BLAS and LAPACK that Debian's MUMPS
# and PETSc call: the reference BLAS they otherwise get made MUMPS 2.7x slower on a 3D joint
# (benchmarks/README.md, "The test suite's time"). The fast extra: PARDISO for the serial references.

$(MPI_STAMP): pyproject.toml
	(/usr/bin/python3 -c "import petsc4py, mpi4py, venv" 2>/dev/null && command -v mpiexec >/dev/null && \
		dpkg -s libopenblas0-serial >/dev/null 2>&1) || (apt-get update -qq && \
		DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv python3-petsc4py-real python3-mpi4py \
		openmpi-bin libopenblas0-serial)
	/usr/bin/python3 -m venv --system-site-packages $(MPI_VENV)
	$(MPI_VENV)/bin/pip install --quiet -e ".[test,fast]" "numpy>=1.26,<2" "scipy>=1.11,<1.15" "numba>=0.59" "llvmlite>=0.42"
	touch $(MPI_STAMP)

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py

# rockfrac against Akantu (installed into its own .venv-akantu by the script)
bench-peer: $(STAMP)
	$(BIN)/python benchmarks/peer.py

clean:
	rm -rf $(VENV) $(MPI_VENV) out

.PHONY: kernels scaling mpi-scaling
kernels: $(STAMP)
	$(BIN)/python benchmarks/kernels.py

scaling: $(STAMP)
	$(BIN)/python benchmarks/scaling.py

# MPI scaling on 1 and 2 ranks, 2D and 3D at 1e6 dofs (issue 17; benchmarks/README.md, "MPI scaling")
mpi-scaling: $(MPI_STAMP)
	PETSC_DIR=$(PETSC_DIR) NUMBA_CACHE_DIR=$(MPI_VENV)/numba-cache $(MPI_VENV)/bin/python benchmarks/mpi_scaling.py
