"""The Examples sections of the public API run as doctests: each example is real output."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = (
    "pacam_render.model.camera",
    "pacam_render.model.design_file",
    "pacam_render.model.modes",
    "pacam_render.psf.analytic",
    "pacam_render.psf.bitmap",
    "pacam_render.restore.metrics",
    "pacam_render.sensor.model",
    "pacam_render.study.spec",
)
"""Modules whose public functions carry Examples (each must have at least one)."""


@pytest.mark.parametrize("name", MODULES)
def test_examples_run(name):
    flags = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
    result = doctest.testmod(importlib.import_module(name), optionflags=flags, verbose=False)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0
