"""The ``pacam`` command and ``python -m pacam_render``.

Ctrl-C while the libraries load ends with one line and exit status 130, not a traceback. The
libraries load with SIGINT deferred: some (trimesh's optional imports) catch BaseException and
would swallow a KeyboardInterrupt raised inside them.
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Sequence


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``pacam`` (:func:`pacam_render.cli.main`); 130 on Ctrl-C before it takes over."""
    caught: list[int] = []
    old = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        # inside: the libraries load with SIGINT deferred (module docstring)
        from . import scenes  # noqa: F401  (trimesh, imported by the commands that render)
        from .cli import main as cli_main
    finally:
        signal.signal(signal.SIGINT, old)
    try:
        if caught:
            raise KeyboardInterrupt
        return cli_main(argv)
    except KeyboardInterrupt:
        print("pacam: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
