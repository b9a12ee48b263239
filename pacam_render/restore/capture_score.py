"""A capture as its scorers see it: its layers in white = 1 units (flat-fielded), the kernel it
is restored with, and its restoration. One owner for the study, ``pacam deconvolve`` and the
rendered-objective optimiser, so the three score a capture alike."""

from __future__ import annotations

import numpy as np

from ..capture.kernels import analytic_psf
from ..model.illumination import flat_field
from .deconvolve import SIGMA_METHODS, deconvolve, nonnegative_for
from .flat_field import RI_LAYER, flat_field_sigma
from .object_score import edge_px

STILL_KERNEL_MODES = ("normal", "short")
"""Modes restored with a delta kernel: denoised, not deblurred (see :func:`kernel`)."""


def radiance(cap, layer: np.ndarray) -> np.ndarray:
    """A capture layer in white = 1 units, flat-fielded by the capture's relative-illumination
    map when it has one (irradiance -> radiance, as a camera pipeline does and as the sharp
    layer and the kernels are)."""

    return flat_field(layer / cap.record.light_factor, cap.extra_layers.get(RI_LAYER))


def flat_sigma(cap, sigma: float) -> float:
    """A noise sigma of the capture, after :func:`radiance` (RMS over the window)."""

    m = cap.extra_layers.get(RI_LAYER)
    return sigma if m is None else flat_field_sigma(sigma, m)


def edge_px_of(cap) -> int:
    """How far a moving object's blur reaches past its outline, px
    (:func:`.object_score.edge_px`)."""

    return edge_px(cap.extra_layers["velocity"], cap.record.exposure_ms, cap.record.optics["r_px"])


def deconvolve_capture(cap, noisy, sigma: float, method: str) -> np.ndarray:
    """Restore with the mode's kernel (:func:`kernel`) and ``method``'s prior: ``sigma`` goes
    to the methods that take one; ``rl`` gets the noisy layer clipped at 0 (its data must be
    non-negative; a pacam deconvolve of the same layer does the same, with a note)."""

    kw = {"noise_sigma": sigma} if method in SIGMA_METHODS else {}
    return deconvolve(nonnegative_for(method, noisy)[0], kernel(cap), method, **kw)


def kernel(cap) -> np.ndarray:
    """The kernel a study restores a capture with.

    The motion-invariant modes (``coded``, ``coded_continuous``, ``levin``) use their analytic
    PSF at s = 0; ``flutter`` the PSF at the fastest object's own velocity (Raskar et al.
    assume the motion known); ``normal`` and ``short``, whose blur depends on each object's
    unknown speed, a delta, so that the method only denoises them with the same prior, and
    every mode is restored alike.
    """

    mode = cap.record.mode
    if mode in STILL_KERNEL_MODES:
        return np.ones((1, 1))
    return analytic_psf(cap.record, fastest_u(cap) if mode == "flutter" else 0.0)


def fastest_u(cap) -> float:
    """The horizontal image velocity of the fastest-moving visible object, px/ms (median)."""
    u = cap.extra_layers["velocity"][..., 0]
    ids = cap.extra_layers["object_id"]
    fastest = ids[np.unravel_index(np.argmax(np.abs(u)), u.shape)]
    return float(np.median(u[ids == fastest]))
