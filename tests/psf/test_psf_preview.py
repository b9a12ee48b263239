"""The PSF preview (``pacam psf``'s PNG) carries its scale: axes in px from the centre pixel,
which is the kernel's origin, and a colour bar; written atomically, never over a file."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.io.preview import psf_extent, write_psf_preview
from pacam_render.psf.analytic import discrete_coded_psf


@pytest.mark.parametrize("shape", [(5, 7), (4, 6), (17, 17), (1, 9)])
def test_the_centre_pixel_is_at_zero_and_pixels_are_one_px(shape):
    left, right, bottom, top = psf_extent(shape)
    h, w = shape
    assert (right - left, bottom - top) == (w, h)  # one unit per pixel
    # the centre of pixel (h // 2, w // 2) sits at (0, 0)
    assert left + (w // 2 + 0.5) == 0.0 and top + (h // 2 + 0.5) == 0.0


def test_preview_is_written_with_room_for_axes_and_not_over_a_file(tmp_path):
    k = discrete_coded_psf(0.5, 0.04, 2.0, 22.5)
    path = write_psf_preview(tmp_path / "psf.png", k, "coded PSF")
    img = iio.imread(path)
    assert img.ndim == 3 and img.shape[0] > 3 * k.shape[0] and img.shape[1] > 3 * k.shape[1]
    assert len(np.unique(img.reshape(-1, img.shape[2]), axis=0)) > 50  # colour map and text
    with pytest.raises(ParameterError):
        write_psf_preview(path, k)  # exists: needs force
    write_psf_preview(path, np.stack([k] * 3, axis=-1), force=True)  # a colour kernel
    with pytest.raises(ParameterError, match="kernel"):
        write_psf_preview(tmp_path / "bad.png", np.full((3, 3), np.nan))
    assert not (tmp_path / "bad.png").exists()
