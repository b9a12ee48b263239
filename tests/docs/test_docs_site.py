"""The built documentation site (issue 38): every internal link resolves, every public name has
an API page, every ``pacam`` command a CLI page, and the pages render styled in a real browser.

``make docs`` builds the site with warnings as errors and then runs this file with
``PACAM_DOCS_HTML`` set to the build; without it (``make test``) these tests are skipped, since
the build takes about a minute. The browser checks use Debian's headless ``chromium``; they skip
where it is missing, except in CI (``CI`` set), where ``.ci/run`` installs it.
"""

from __future__ import annotations

import argparse
import importlib
import os
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "docs"))
import _generate  # noqa: E402  (docs/_generate.py: which page each public name is on)

SITE = os.environ.get("PACAM_DOCS_HTML")
pytestmark = pytest.mark.skipif(not SITE, reason="run by `make docs` on the built site")
HTML = (ROOT / SITE).resolve() if SITE else Path()
SHOTS = HTML.parent / "screenshots"


class _Page(HTMLParser):
    """The links (href, src) and the ids of one HTML page."""

    def __init__(self):
        super().__init__()
        self.links: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if attrs.get("id"):
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("name"):
            self.ids.add(attrs["name"])
        for key in ("href", "src"):
            if attrs.get(key) and not (tag == "link" and attrs.get("rel") == "preconnect"):
                self.links.append(attrs[key])


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(errors="replace"))
    return page


def _pages() -> list[Path]:
    return sorted(p for p in HTML.rglob("*.html") if "_static" not in p.parts)


def test_every_internal_link_resolves():
    parsed = {p: _parse(p) for p in _pages()}
    assert len(parsed) > 100
    broken = []
    for page, info in parsed.items():
        for link in info.links:
            parts = urlsplit(link)
            if parts.scheme or link.startswith(("//", "mailto:", "data:", "javascript:")):
                continue
            target = (page.parent / unquote(parts.path)).resolve() if parts.path else page
            if target.is_dir():
                target = target / "index.html"
            if not target.exists():
                broken.append(f"{page.relative_to(HTML)}: {link}")
            elif parts.fragment and target.suffix == ".html":
                ids = parsed[target].ids if target in parsed else _parse(target).ids
                if unquote(parts.fragment) not in ids:
                    broken.append(f"{page.relative_to(HTML)}: {link} (no such anchor)")
    assert not broken, "\n".join(broken[:40])


def _subpackages() -> dict[str, list[str]]:
    out = {}
    for path in sorted((ROOT / "pacam_render").iterdir()):
        if (path / "__init__.py").exists():
            module = importlib.import_module(f"pacam_render.{path.name}")
            if getattr(module, "__all__", None):
                out[module.__name__] = list(module.__all__)
    return out


def _api_page(full: str) -> Path:
    return HTML / "reference" / "api" / "generated" / f"{full}.html"


def test_every_public_name_has_an_api_page():
    missing = []
    for module, names in _subpackages().items():
        assert (HTML / "reference" / "api" / f"{module}.html").exists(), module
        for name in names:
            page = _api_page(f"{module}.{name}")
            if not page.exists() or f'id="{module}.{name}"' not in page.read_text():
                missing.append(f"{module}.{name}")
    top = (HTML / "reference" / "api" / "pacam_render.html").read_text()
    for name, full in _generate.canonical_names().items():
        page = _api_page(full)
        shown = name in top and f'href="generated/{full}.html' in top
        ids = (f'id="{full}"', f'id="module-{full}"')
        if not (shown and page.exists() and any(i in page.read_text() for i in ids)):
            missing.append(f"pacam_render.{name} ({full})")
    assert not missing, missing


def _commands() -> dict[str, argparse.ArgumentParser]:
    from pacam_render.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_every_command_has_a_cli_page_with_its_flags():
    commands = _commands()
    assert {"render", "sensor", "psf", "deconvolve", "study", "demo"} <= set(commands)
    for name, parser in commands.items():
        page = HTML / "reference" / "cli" / f"pacam-{name}.html"
        assert page.exists(), name
        text = page.read_text()
        for action in parser._actions:
            for flag in action.option_strings:
                if flag.startswith("--") and flag not in ("--help", "--version"):
                    assert flag in text, f"pacam {name}: {flag} missing from its page"


def _chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if not found:
        if os.environ.get("CI"):
            pytest.fail("headless chromium is missing (.ci/run installs Debian's package)")
        pytest.skip("no chromium here (apt-get install chromium)")
    return found


def _screenshot(page: Path, out: Path) -> np.ndarray:
    import matplotlib.image

    out.parent.mkdir(parents=True, exist_ok=True)
    out.unlink(missing_ok=True)
    cmd = [
        _chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
        "--window-size=1280,900", f"--screenshot={out}", page.resolve().as_uri(),
    ]  # fmt: skip
    subprocess.run(cmd, capture_output=True, timeout=120, check=False)
    assert out.exists(), f"chromium wrote no screenshot of {page}"
    return matplotlib.image.imread(out)[..., :3]


PAGES = {
    "landing": "index.html",
    "api": "reference/api/generated/pacam_render.model.CameraDesign.html",
    "study": "validation/studies.html",
}


@pytest.mark.parametrize("name", PAGES)
def test_pages_render_in_a_browser(name):
    """A page renders with content: not blank (a near-uniform screenshot) in Chromium."""
    shot = _screenshot(HTML / PAGES[name], SHOTS / f"{name}.png")
    assert shot.shape[:2] == (900, 1280)
    assert shot.std() > 0.05, f"the {name} page renders near-uniform (blank)"
    dark = (shot.mean(axis=2) < 0.5).mean()
    assert dark > 0.005, f"the {name} page shows almost no text"


def test_the_landing_page_is_styled_by_the_theme(tmp_path):
    """The theme's CSS is there and loads: the page differs from the same HTML without it."""
    index = HTML / "index.html"
    css = [h for h in _parse(index).links if h.endswith(".css") or ".css?" in h]
    theme = [h for h in css if "pydata-sphinx-theme" in h]
    assert theme, f"the landing page links no theme stylesheet: {css}"
    for href in theme:
        sheet = HTML / urlsplit(href).path
        assert sheet.exists() and sheet.stat().st_size > 10_000, href
    styled = _screenshot(index, SHOTS / "landing.png")
    bare = tmp_path / "index.html"
    bare.write_text(index.read_text())  # the same HTML, its _static/ out of reach
    unstyled = _screenshot(bare, tmp_path / "unstyled.png")
    assert np.abs(styled - unstyled).mean() > 0.02, "the landing page looks unstyled"
    # the theme's navigation bar: a coloured or shaded band across the top, not the bare page
    assert styled[:60].std() > 0.02


def test_api_summaries_are_our_words_and_whole_sentences():
    """Issue 46 (low): a re-exported constant's summary was its type's docstring ("Convert a
    string or number to a floating point number"), and "phi (Eq. 1)" was cut at "(Eq."."""
    import html
    import re

    builtin = [t.__doc__.strip().splitlines()[0].strip() for t in (float, int, str, tuple, dict)]
    row = re.compile(r'<tr class="row-(?:odd|even)"><td><p><a[^>]*>.*?</a></p></td>\s*'
                     r"<td><p>(.*?)</p></td>", re.S)  # fmt: skip
    bad = []
    for page in sorted((HTML / "reference" / "api").glob("*.html")):
        for m in row.finditer(page.read_text(errors="replace")):
            summary = html.unescape(re.sub(r"<[^>]+>", "", m.group(1))).strip()
            if any(summary.startswith(b[:30]) for b in builtin) or summary.endswith(
                ("(Eq.", "Eq.", "Sec.")
            ):
                bad.append(f"{page.name}: {summary[:60]}")
    assert not bad, bad
    assert (HTML / "reference" / "design_file.html").is_file()
