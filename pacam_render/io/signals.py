"""Interrupts that wait for a safe point: SIGINT and SIGTERM are noted, and the loop that
renders (a capture's time steps, a PSF render's passes) saves its finished work before it stops,
so that an interrupt loses no rendering."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator


@contextlib.contextmanager
def deferred_signals() -> Iterator[dict]:
    """SIGINT and SIGTERM set ``flag["signal"]`` for the step loop to read after each step, so
    the finished steps can be saved; a second signal interrupts at once (KeyboardInterrupt).
    Outside the main thread, and where a signal is ignored (a background job), signals keep
    their handlers."""
    flag: dict = {"signal": None}
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return

    def handler(signum, frame):
        if flag["signal"] is not None:
            raise KeyboardInterrupt
        flag["signal"] = signum

    watched = [s for s in (signal.SIGINT, signal.SIGTERM) if signal.getsignal(s) != signal.SIG_IGN]
    old = {s: signal.signal(s, handler) for s in watched}  # an ignored signal stays ignored
    try:
        yield flag
    finally:
        for s, h in old.items():
            signal.signal(s, h)
