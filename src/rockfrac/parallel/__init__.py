"""MPI-parallel runs on PETSc (issue 17): partitioned elements, distributed matrix and vectors.

Needs petsc4py and mpi4py (Debian's ``python3-petsc4py-real``, ``python3-mpi4py``; ``make test``
builds a venv that sees them, ``.venv-mpi``).
"""
