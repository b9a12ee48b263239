"""The exact defocused-disc PSF (Hopkins's OTF) and the W020 that gives a blur radius r."""

from __future__ import annotations

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.wave.defocus import (
    defocus_kernel,
    defocused_disc_otf,
    edge_phase,
    hopkins_otf,
    pillbox_otf,
    w020_mm,
)
from pacam_render.wave.fraunhofer import fraunhofer_kernel, kernel_from_otf
from pacam_render.wave.pupil import DiscPupil, disc_pupil
from pacam_render.wave.reference import circular_mtf
from pacam_render.wave.scale import DiffractionScale

LCOS = 0.01362
S550 = DiffractionScale(550.0, 0.00645, 2 * 2.8 * 512 * LCOS)
DISC = DiscPupil(145.5 * LCOS)
LN = S550.lambda_n_px(DISC.radius_mm)


def test_without_defocus_hopkins_is_the_circular_mtf():
    rho = np.linspace(0, 1.3, 400)
    assert np.max(np.abs(hopkins_otf(rho, LN, 0.0) - circular_mtf(rho, LN))) < 1e-14
    k0 = defocus_kernel(DISC, 0.0, S550, size=41, max_lost=0.05).kernel
    ka = fraunhofer_kernel(DISC, S550, size=41, max_lost=0.05).kernel
    assert np.abs(k0 - ka).sum() < 1e-13


def test_w020_gives_the_geometric_blur_radius():
    """At low frequency the defocus factor of the exact OTF is the pillbox's: both fall as
    1 - (pi r nu)^2 / 2, which fixes W020 = r p / (4N) (the geometric blur radius is r)."""
    for r in (0.5, 2.0, 4.0):
        nu = np.array([1e-3, 2e-3])
        psi = edge_phase(r, LN)
        drop = circular_mtf(nu, LN) - hopkins_otf(nu, LN, psi)
        assert drop / nu**2 == pytest.approx(np.full(2, (np.pi * r) ** 2 / 2), rel=2e-2)
        geo = 1.0 - pillbox_otf(nu, r)
        assert geo / nu**2 == pytest.approx(np.full(2, (np.pi * r) ** 2 / 2), rel=2e-3)
    assert w020_mm(2.0, 9.85, 0.00645) / 550e-6 == pytest.approx(0.595, abs=1e-3)
    assert edge_phase(2.0, LN) == pytest.approx(
        2 * np.pi * w020_mm(2.0, 9.853, 0.00645) / 550e-6, rel=1e-3
    )


def test_hopkins_quadrature_is_converged():
    base = defocus_kernel(DISC, 4.0, S550, size=41, max_lost=0.05).kernel
    more = kernel_from_otf(defocused_disc_otf(DISC, 4.0, S550, nodes=200), 41, 0.05).kernel
    assert np.abs(base - more).sum() < 1e-12


@pytest.mark.parametrize("r", [1.0, 2.0])
def test_hopkins_agrees_with_a_sampled_defocused_pupil(r):
    """An independent route: the disc on square cells with the phase psi rho^2 at each cell's
    centre, whose kernel converges to Hopkins's as the cells shrink."""
    psi = edge_phase(r, LN)
    exact = defocus_kernel(DISC, r, S550, size=41, max_lost=0.05).kernel
    errs = [
        np.abs(
            fraunhofer_kernel(
                disc_pupil(DISC.radius_mm, n, phase=lambda rho: psi * rho**2), S550, 41, 0.05
            ).kernel
            - exact
        ).sum()
        for n in (64, 128)
    ]
    assert errs[1] < 1.5e-3 and errs[1] < errs[0] / 2.5


def test_defocus_parameters_are_checked():
    with pytest.raises(ParameterError, match=r"r_px must be in \[0, 64\] px"):
        defocus_kernel(DISC, -1.0, S550)
    with pytest.raises(ParameterError, match="pupil must be a DiscPupil"):
        defocus_kernel(disc_pupil(1.0, 8), 1.0, S550)
