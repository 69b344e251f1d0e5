"""The errors rockfrac reports to its users (the bottom of the import graph: imports nothing)."""

from __future__ import annotations


class CaseError(ValueError):
    """A problem with an input (case, law, path, mesh or output folder), reported as one line per
    problem: 'file: [section] key: what is wrong; what is allowed'."""


class RunStopped(Exception):
    """A run ended before its program did, by request (SIGINT/SIGTERM): every converged step is kept.

    exit_code: what the command line returns (130 for SIGINT, 143 for SIGTERM, as a shell does).
    """

    def __init__(self, message: str, exit_code: int = 130):
        super().__init__(message)
        self.exit_code = exit_code
