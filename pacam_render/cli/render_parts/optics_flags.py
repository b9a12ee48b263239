"""The flags of ``pacam render`` for the optics that rays through an ideal aperture leave
out: relative illumination, diffraction and the LCoS's flaws (issue 36)."""

from __future__ import annotations

import argparse

from ...exposure.spec import CAMERA_OPTICS


def add_optics(p: argparse.ArgumentParser) -> None:
    """What rays through an ideal aperture leave out: relative illumination, diffraction and
    the LCoS's flaws (issue 36)."""
    add_camera_optics(p)
    _add_lcos(p)


def add_camera_optics(p: argparse.ArgumentParser) -> None:
    """``--relative-illumination`` and ``--diffraction``, a camera's by default."""
    p.add_argument(
        "--relative-illumination",
        default=CAMERA_OPTICS["relative_illumination"],
        metavar="{cos4,off,FILE}",
        help="natural vignetting: cos4 (default: cos^4 of the field angle, irradiance as a "
        "camera measures it), off (radiance, as Mitsuba's thinlens) or a .csv/.json curve "
        "against height_px, height_mm or field_deg; "
        "the map is kept as a layer and deconvolve flat-fields with it",
    )
    p.add_argument(
        "--diffraction",
        default=CAMERA_OPTICS["diffraction"],
        choices=("auto", "on", "off"),
        help="the opening's Fraunhofer diffraction: auto (default: on unless its effect, "
        "measured on a short preview, is below the noise target, or without one the Monte "
        "Carlo sigma; the decision is recorded), on (in the rays, per colour channel; bitmap "
        "schedules after the render) or off (geometric optics)",
    )


def _add_lcos(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--lcos-contrast",
        type=float,
        metavar="C",
        help="the LCoS's contrast ratio (>= 1): 'off' pixels pass 1/C of the light, in the rays "
        "(default: ideal, no datasheet value is known); 1 is the full aperture",
    )
    p.add_argument(
        "--lcos-fill-factor",
        type=float,
        metavar="F",
        help="the LCoS pixels' linear fill factor in (0, 1]: the pixel grid's diffraction "
        "orders (ghosts ~244 px away at 550 nm), with --diffraction on (default: 1, no grid)",
    )
    p.add_argument(
        "--lcos-switching",
        type=float,
        metavar="MS",
        help="the LCoS's switching time, ms: each pattern's first MS change linearly from the "
        "previous one (coded captures; default 0, instant)",
    )
