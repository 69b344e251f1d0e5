"""The resolved text of a case (every key, its defaults filled in): what a run's case.toml holds and
what its checkpoints' digest is taken of; and whether a case.toml written by an older rockfrac is the
same case when read today."""

from __future__ import annotations

import tomllib

import tomli_w

from rockfrac.case.schema import Case, parse_case
from rockfrac.errors import CaseError


def resolved_text(case: Case) -> str:
    """The case as TOML, every key given (unset optional keys left out)."""
    return tomli_w.dumps(case.model_dump(mode="json", exclude_none=True))


def same_case(written: str, case_text: str) -> bool:
    """Whether ``written`` (a resolved case text, perhaps of an older rockfrac) read with today's schema
    resolves to ``case_text``: a key added since is filled in with its default on both sides, so a
    checkpoint written before the key existed still resumes where the key keeps its default."""
    try:
        old = parse_case(tomllib.loads(written))
    except (CaseError, tomllib.TOMLDecodeError):
        return False
    return resolved_text(old) == case_text
