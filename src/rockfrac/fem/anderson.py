"""Anderson acceleration of a fixed-point iteration x <- G(x) (type II, Walker & Ni 2011).

Used for the nested RP multipliers (:mod:`rockfrac.elements.cse_nested`): there x is lambda, G the
tractions of the converged displacement solve at that lambda, and the plain update x := G(x)
contracts slowly along a few modes (e.g. a viscous pair held shut on a loop round a node, whose
overstress relaxes by the Duvaut-Lions blend only, 1 - dt / (eta + dt) per update). The next x is
the combination of the last ``depth`` + 1 values of G whose residuals G - x combine to the least
(weighted) norm; with no history, G(x) itself. The fixed point is the same: only the path to it
changes, and convergence is judged on the residual G(x) - x of the last iterate, as without it.

The norm is weighted (``weight``, per entry), and the iterates may be split over MPI ranks: ``reduce``
sums the inner products over them.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


class AndersonMixing:
    """Anderson mixing of depth m over flat vectors; ``reduce`` sums an array over the MPI ranks (serial:
    the identity)."""

    def __init__(self, depth: int, reduce: Callable[[np.ndarray], np.ndarray] = lambda a: a):
        if depth < 0:
            raise ValueError(f"depth must be >= 0, got {depth}")
        self.depth = depth
        self.reduce = reduce
        self.reset()

    def reset(self) -> None:
        """Forget the history (a new fixed-point problem: a new load step)."""
        self._f: np.ndarray | None = None
        self._g: np.ndarray | None = None
        self._df: list[np.ndarray] = []
        self._dg: list[np.ndarray] = []

    def next(self, x: np.ndarray, g: np.ndarray, weight: np.ndarray) -> np.ndarray:
        """The next iterate from x and G(x); ``weight`` (n,) >= 0 weighs each entry's square in the norm
        the residual's combination is least in."""
        f = g - x
        if self._f is not None and self._g is not None and self.depth:
            self._df.append(f - self._f)
            self._dg.append(g - self._g)
            del self._df[:-self.depth], self._dg[:-self.depth]
        self._f, self._g = f.copy(), g.copy()
        if not self._df:
            return g.copy()
        df = np.stack(self._df)
        gram = self.reduce(df @ (weight * df).T)  # (k, k), every rank alike
        rhs = self.reduce(df @ (weight * f))
        gamma = np.linalg.lstsq(gram, rhs, rcond=1e-12)[0]
        return g - gamma @ np.stack(self._dg)
