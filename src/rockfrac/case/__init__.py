"""Case files: TOML schema (validated before anything runs) and the case -> Model build."""

from rockfrac.case.schema import Case, CaseError, load_case

__all__ = ["Case", "CaseError", "load_case"]
