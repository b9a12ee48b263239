"""Issue 47, medium 9: a kernel file's camera is checked from what its psf.json records, even
without a design digest, and a capture without its capture.json says that nothing could be
checked (both passed silently: a PSF made for 700 mm deblurred a 500 mm capture, exit 0)."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from pacam_render.capture.record import CaptureRecord
from pacam_render.exposure.deblur_psf import PSFMismatchError, check_psf_design
from pacam_render.limits import PacamWarning
from pacam_render.model.camera import prototype

KERNEL = Path("g/psf_analytic.exr")


def _record(cam) -> CaptureRecord:
    crop = {"x": 0, "y": 0, "width": 48, "height": 40, "sensor_width_px": 1280,
            "sensor_height_px": 960}  # fmt: skip
    return CaptureRecord.from_json(
        {"camera": cam.inputs(), "mode": "coded", "crop": crop, "objects": {}}
    )


def _meta(cam) -> dict:
    """A psf.json's camera figures, as pacam psf writes them, for ``cam``."""
    s = cam.summary()
    keys = ("r_px", "a_i_px_per_ms2", "n_patterns", "exposure_ms", "object_depth_mm",
            "schedule_kind", "design_digest")  # fmt: skip
    return {"mode": "coded", **{k: s[k] for k in keys}}


def test_without_a_digest_the_recorded_figures_are_still_compared():
    far = prototype().with_(object_depth_mm=700.0)
    meta = _meta(far)
    del meta["design_digest"]
    with pytest.warns(PacamWarning, match="only its .*depth.* are checked"):
        with pytest.raises(PSFMismatchError, match=r"depth 700 mm \(PSF\) against 500 mm"):
            check_psf_design(KERNEL, meta, _record(prototype()), allow=False)
    same = _meta(prototype())
    del same["design_digest"]
    with pytest.warns(PacamWarning, match="records no design digest"):
        assert check_psf_design(KERNEL, same, _record(prototype()), allow=False) == ()


def test_a_capture_without_its_record_says_nothing_was_checked():
    meta = _meta(prototype().with_(object_depth_mm=700.0))
    with pytest.warns(PacamWarning, match=r"no capture.json: .*depth 700 mm.* cannot be checked"):
        assert check_psf_design(KERNEL, meta, None, allow=False) == ()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no kernel record: nothing to say
        assert check_psf_design(KERNEL, None, None, allow=False) == ()
