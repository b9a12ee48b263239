"""The commands a document shows, and the lines it shows them printing: what the tests that
run documents verbatim (the README's how-to, docs/howto/*.md) compare against."""

from __future__ import annotations

import re
from pathlib import Path

NUMBER = re.compile(r"[-+]?\d+(\.\d+)?(e[+-]?\d+)?")
"""A number in a printed line (masked before comparing: timings and noise vary)."""


def shown_commands(doc: Path, fence: str) -> list[tuple[str, list[str]]]:
    """(command, the lines shown after it) from the first ```` ```fence ```` block of ``doc``:
    lines starting ``$ `` are commands."""
    block = doc.read_text().split(f"```{fence}\n", 1)[1].split("```", 1)[0]
    out: list[tuple[str, list[str]]] = []
    for line in block.splitlines():
        if line.startswith("$ "):
            out.append((line[2:], []))
        elif out:
            out[-1][1].append(line)
    return out
