"""Checkpoints of a run: the stepping position and every group's committed state, to resume from.

Groups name their committed-state attributes in ``checkpoint_attrs``; everything else of a group
is rebuilt from the case. A checkpoint is written to a temporary file and moved into place, so a
run stopped at any moment leaves the previous one intact.
"""

from __future__ import annotations

import os
import pickle
from pathlib import Path

from rockfrac.solve.stepping import Position

FILE = "checkpoint.pkl"


def save(folder: Path, position: Position, groups: list, run: dict, case_text: str) -> Path:
    """Write folder/checkpoint.pkl: position, groups' committed state, run counters, the case."""
    data = {
        "position": position,
        "groups": [{a: getattr(g, a) for a in getattr(g, "checkpoint_attrs", ())} for g in groups],
        "run": dict(run),
        "case": case_text,
    }
    path = Path(folder) / FILE
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as fh:
        pickle.dump(data, fh, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)
    return path


def load(folder: Path) -> dict | None:
    """The checkpoint in folder, or None if there is none."""
    path = Path(folder) / FILE
    if not path.exists():
        return None
    with open(path, "rb") as fh:
        return pickle.load(fh)


def restore(groups: list, states: list[dict]) -> None:
    """Put the saved committed states back into the model's groups (same case, same order)."""
    if len(groups) != len(states):
        raise ValueError("the checkpoint was written for a different model (number of element groups)")
    for g, st in zip(groups, states):
        for name, value in st.items():
            current = getattr(g, name)
            if hasattr(current, "shape") and hasattr(value, "shape") and current.shape != value.shape:
                raise ValueError(f"the checkpoint was written for a different model ({type(g).__name__}.{name})")
            setattr(g, name, value)
