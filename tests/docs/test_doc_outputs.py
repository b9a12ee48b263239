"""Every block of command output in the docs is either run by the tests or marked as an
excerpt with its commit and date (issue 46, item 8): a reader can tell a checked output from
a recorded one."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RUN_BY_TESTS = {  # document -> the test that runs its first command block
    "README.md": "tests/docs/test_readme_howto.py",
    "docs/howto/own_scene.md": "tests/docs/test_readme_howto.py",
    "docs/howto/lightfield.md": "tests/docs/test_readme_howto.py",
    "docs/howto/design_on_renders.md": "tests/docs/test_readme_howto.py",
    "docs/howto/own_camera.md": "tests/test_howto_own_camera.py",
    "docs/howto/scene_family.md": "tests/scenes/test_family.py",
}
MARK = re.compile(
    r"^\*Excerpt, not re-run by the tests: .*commit `[0-9a-f]{7,}` \(\d{4}-\d\d-\d\d\)"
)
GENERATED = ("_build", "jupyter_execute", "reference/api", "reference/cli")


def command_blocks(path: Path) -> list[tuple[int, list[str]]]:
    """(fence line, the lines before it) of each fenced block that shows a ``$ command``."""
    lines = path.read_text().splitlines()
    out, i = [], 0
    while i < len(lines):
        if not lines[i].startswith("```"):
            i += 1
            continue
        j = next((k for k in range(i + 1, len(lines)) if lines[k].startswith("```")), len(lines))
        if not lines[i].startswith("```{") and any(s.startswith("$ ") for s in lines[i + 1 : j]):
            out.append((i + 1, lines[:i]))
        i = j + 1
    return out


def _documents() -> list[Path]:
    docs = sorted((ROOT / "docs").rglob("*.md"))
    return [ROOT / "README.md", *(p for p in docs if not any(g in p.as_posix() for g in GENERATED))]


def test_every_command_output_is_run_or_marked_as_an_excerpt():
    unmarked = []
    for path in _documents():
        rel = path.relative_to(ROOT).as_posix()
        for n, (line, before) in enumerate(command_blocks(path)):
            if n == 0 and rel in RUN_BY_TESTS:
                continue
            last = next((s for s in reversed(before) if s.strip()), "")
            if not MARK.match(last):
                unmarked.append(f"{rel}:{line}")
    assert not unmarked, f"output blocks neither run by a test nor marked: {unmarked}"


def test_the_tests_named_exist_and_read_their_documents():
    for doc, test in RUN_BY_TESTS.items():
        text = (ROOT / test).read_text()
        assert Path(doc).name in text or doc == "README.md" and "README.md" in text, (doc, test)
