"""Stopping a run cleanly on SIGINT (Ctrl-C) or SIGTERM.

While a run is under :func:`stop_on_signals`, these signals only set a flag: Newton looks at it
between iterations and the stepping between steps, so the run ends at a step boundary with every
converged step committed and written, and says why. A third SIGINT restores Python's default and
raises KeyboardInterrupt at once (for a user who cannot wait for the current iteration).
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

NAMES: dict[int, str] = {int(signal.SIGINT): "SIGINT (Ctrl-C)", int(signal.SIGTERM): "SIGTERM"}
EXIT_CODES: dict[int, int] = {int(signal.SIGINT): 130, int(signal.SIGTERM): 143}  # 128 + signal number, as a shell reports


class StopRequest:
    """The first stop signal received (None: carry on)."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self.count = 0

    def __call__(self) -> bool:
        """True once a stop was requested."""
        return self.signum is not None

    @property
    def reason(self) -> str:
        return NAMES.get(self.signum, f"signal {self.signum}") if self.signum is not None else ""

    @property
    def exit_code(self) -> int:
        return EXIT_CODES.get(self.signum, 1) if self.signum is not None else 0


@contextmanager
def stop_on_signals() -> Iterator[StopRequest]:
    """Turn SIGINT and SIGTERM into a :class:`StopRequest` for the duration (main thread only; in
    another thread the request is never set and signals behave as before)."""
    request = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request
        return

    def handler(signum, frame):  # noqa: ARG001 (signal handler signature)
        request.count += 1
        if request.signum is None:
            request.signum = signum
        if request.count >= 3 and signum == signal.SIGINT:
            signal.signal(signal.SIGINT, signal.default_int_handler)
            raise KeyboardInterrupt

    previous = {s: signal.signal(s, handler) for s in NAMES}
    try:
        yield request
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
