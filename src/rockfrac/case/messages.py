"""Validation errors as one line per problem: 'file: [section] key: what is wrong (got ...)'.

Pydantic locates an error by a path through the schema that also holds the tags of union members
and validators (``('c_p', 'float')``); here the path is walked along the schema's annotations so
that only what the user wrote remains: sections, keys, list positions (1-based) and dict keys.
Errors at the same key (one per member of a union) are merged into one line.
"""

from __future__ import annotations

import types
import typing
from typing import Any

from pydantic import BaseModel, ValidationError

from rockfrac.errors import CaseError

SECTIONS = ("mesh", "bulk", "materials", "cohesive", "embedded", "loading", "solver", "output", "law", "material",
            "stress", "stages", "boundary", "initial_stress", "monitors")


def _unwrap(ann: Any) -> Any:
    """Annotated[X, ...] -> X."""
    while typing.get_origin(ann) is typing.Annotated:
        ann = typing.get_args(ann)[0]
    return ann


def _members(ann: Any) -> list[Any]:
    """The non-None members of a union annotation (or [ann])."""
    ann = _unwrap(ann)
    if typing.get_origin(ann) in (typing.Union, types.UnionType):
        return [_unwrap(a) for a in typing.get_args(ann) if a is not type(None)]
    return [ann]


def _is_model(ann: Any) -> bool:
    return isinstance(ann, type) and issubclass(ann, BaseModel)


def _step(ann: Any, part: Any) -> tuple[bool, Any]:
    """(whether ``part`` is something the user wrote, the annotation below it)."""
    for m in _members(ann):
        origin = typing.get_origin(m)
        if _is_model(m) and isinstance(part, str) and part in m.model_fields:
            return True, m.model_fields[part].annotation
        if origin is list and isinstance(part, int):
            return True, typing.get_args(m)[0]
        if origin is dict and isinstance(part, str) and not _looks_like_tag(part):
            return True, typing.get_args(m)[1]
    return False, ann  # a union member's or a validator's tag


def _looks_like_tag(part: str) -> bool:
    return part.startswith(("function-", "literal[", "list[", "dict[", "tagged-union[")) or part in (
        "float", "int", "str", "bool", "constrained-float", "constrained-int")


def user_path(root: type[BaseModel], loc: tuple[Any, ...], keep_last: bool = False) -> tuple[Any, ...]:
    """The part of pydantic's ``loc`` that names what the user wrote (keep_last: an unknown key)."""
    ann: Any = root
    out = []
    for i, part in enumerate(loc):
        keep, ann = _step(ann, part)
        if keep or (keep_last and i == len(loc) - 1):
            out.append(part)
    return tuple(out)


def location(path: tuple[Any, ...], arrays: frozenset = frozenset()) -> str:
    """'[section] key', '[section N] key' (N 1-based) for a section given as an array of tables,
    'key.sub' below it, '[N]' for list items."""
    if not path:
        return "(top level)"
    head, rest = str(path[0]), list(path[1:])
    if rest and isinstance(rest[0], int):
        head = f"{head} {rest[0] + 1}" if head in arrays else head  # one [table] read as a list of one
        rest = rest[1:]
    if not rest:
        return f"[{head}]" if str(path[0]) in SECTIONS else head
    key = ""
    for p in rest:
        key += f"[{p + 1}]" if isinstance(p, int) else (f".{p}" if key else str(p))
    return f"[{head}] {key}"


def _allowed_keys(root: type[BaseModel], path: tuple[Any, ...]) -> str:
    ann: Any = root
    for part in path:
        _, ann = _step(ann, part)
    models = [m for m in _members(ann) if _is_model(m)]
    return ", ".join(models[0].model_fields) if models else "(none)"


def _got(value: Any) -> str:
    if isinstance(value, (dict, list)):
        return ""
    text = repr(value)
    return f" (got {text if len(text) <= 60 else text[:57] + '...'})"


def format_errors(path: str, err: ValidationError, root: type[BaseModel],
                  arrays: frozenset = frozenset()) -> str:
    """One line per problem: file, section and key, what is wrong and what is allowed."""
    merged: dict[tuple, list[str]] = {}
    got: dict[tuple, str] = {}
    errors = [(e, user_path(root, e["loc"], keep_last=e["type"] == "extra_forbidden")) for e in err.errors()]
    paths = [w for _, w in errors]
    for e, where in errors:
        extra = e["type"] == "extra_forbidden"
        deeper = any(len(p) > len(where) and p[: len(where)] == where for p in paths)
        if deeper and e["type"].endswith("_type"):
            continue  # a union member of another type (the input matched a container member)
        if extra:
            msg = f"unknown key; allowed keys: {_allowed_keys(root, where[:-1])}"
        elif e["type"] == "missing" and len(where) == 1 and isinstance(where[0], str):
            msg = "missing section (required)" if where[0] in SECTIONS else "missing (required)"
        elif e["type"] == "missing":
            msg = "missing (required)"
        else:
            msg = e["msg"].removeprefix("Value error, ")
            got.setdefault(where, _got(e.get("input")))
        if msg not in merged.setdefault(where, []):
            merged[where].append(msg)
    lines = []
    for where, msgs in merged.items():
        if msgs == ["missing section (required)"]:
            lines.append(f"{path}: missing section [{where[0]}]")
            continue
        lines.append(f"{path}: {location(where, arrays)}: {' or '.join(msgs)}{got.get(where, '')}")
    return "\n".join(lines)


def require(names, available, what: str, key: str, path: str) -> None:
    """CaseError naming the key if a name is not among ``available``."""
    missing = [n for n in names if n not in available]
    if missing:
        raise CaseError(f"{path}: {key}: {what} {', '.join(repr(n) for n in missing)} not in the mesh; "
                        f"its {what}s: {', '.join(sorted(available)) or '(none)'}")
