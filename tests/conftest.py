"""Test-suite configuration: the ``render`` marker.

A test that ray-traces (any ``mi.render``, directly or through a capture, a PSF render, the demo
or a regression image) carries ``@pytest.mark.render``; whole modules that do little else are
marked here. ``make test-fast`` runs ``-m "not render"``; ``make test`` runs everything.
"""

from __future__ import annotations

import os
import tempfile

import pytest

RENDER_MODULES = {
    "test_aperture_camera",
    "test_capture",
    "test_demo",
    "test_psf_render",
    "test_regression_images",
    "test_tutorial",
}
RENDER_FIXTURES = {"quick_dir", "renderer", "mi", "store"}  # fixtures of tests that render


def pytest_configure(config):
    # the suite's renders go in a history of their own, not the user's (exposure.render_time)
    if not os.environ.get("PACAM_RENDER_TIMES"):
        folder = tempfile.mkdtemp(prefix="pacam-test-times-")
        os.environ["PACAM_RENDER_TIMES"] = os.path.join(folder, "render_times.jsonl")
    config.addinivalue_line(
        "markers", "render: the test ray-traces with Mitsuba (left out by make test-fast)"
    )


def pytest_collection_modifyitems(config, items):
    for item in items:
        module = item.module.__name__.rsplit(".", 1)[-1]
        if module in RENDER_MODULES or RENDER_FIXTURES & set(item.fixturenames):
            item.add_marker(pytest.mark.render)
