"""What every element group gives the model: its evaluation, and its committed state as arrays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Evaluation:
    """Element vectors fe (n_el, nd), blocks ke (n_el, nd, nd); ok False if a local solve failed."""

    fe: np.ndarray
    ke: np.ndarray
    ok: bool = True
    n_switched: int = 0
    message: str = ""
    local_residual: float = 0.0  # relative residual of element-level equations (condensed unknowns)


class Checkpointed:
    """A group whose committed state is the arrays named in ``checkpoint_attrs`` (plain numbers)."""

    checkpoint_attrs: tuple[str, ...] = ()

    def checkpoint_state(self) -> dict[str, np.ndarray]:
        """The committed state as named arrays (copies)."""
        return {a: np.array(getattr(self, a)) for a in self.checkpoint_attrs}

    def restore_checkpoint(self, saved: dict[str, np.ndarray]) -> None:
        """Put a :meth:`checkpoint_state` back (same model); ValueError if it does not fit."""
        restore_arrays(self, saved, self.checkpoint_attrs, type(self).__name__)


def restore_arrays(owner: object, saved: dict[str, np.ndarray], names: tuple[str, ...], what: str) -> None:
    """Copy the saved arrays ``names`` into ``owner``'s arrays of the same names, in place; ValueError
    if one is missing or differs in shape or kind (a checkpoint of another model)."""
    for name in names:
        if name not in saved:
            raise ValueError(f"the checkpoint has no {what}.{name}: it was written for a different model")
        current = getattr(owner, name)
        value = saved[name]
        if isinstance(current, np.ndarray):
            if current.shape != value.shape or current.dtype.kind != value.dtype.kind:
                raise ValueError(f"the checkpoint was written for a different model ({what}.{name}: "
                                 f"{value.shape} {value.dtype} here {current.shape} {current.dtype})")
            current[...] = value
        else:
            setattr(owner, name, type(current)(value.item()))
