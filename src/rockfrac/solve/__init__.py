"""Solvers: linear backends, Newton-Raphson, load stepping with cutback."""
