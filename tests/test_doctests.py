"""The Examples sections of the public API run as doctests: each example is real output."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = (
    "pacam_render.model.camera",
    "pacam_render.model.design_file",
    "pacam_render.model.illumination",
    "pacam_render.model.modes",
    "pacam_render.psf.analytic",
    "pacam_render.psf.bitmap",
    "pacam_render.restore.metrics",
    "pacam_render.sensor.presets",
    "pacam_render.study.spec",
    "pacam_render.psf.combination",
    "pacam_render.psf.diffraction",
    "pacam_render.wave.defocus",
    "pacam_render.wave.edge_mtf",
    "pacam_render.wave.fraunhofer",
    "pacam_render.wave.image",
    "pacam_render.wave.patterns",
    "pacam_render.wave.reference",
    "pacam_render.wave.scale",
)
"""Modules whose public functions carry Examples (each must have at least one)."""


@pytest.mark.parametrize("name", MODULES)
def test_examples_run(name):
    flags = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
    result = doctest.testmod(importlib.import_module(name), optionflags=flags, verbose=False)
    assert result.attempted > 0, f"{name} has no examples"
    assert result.failed == 0
