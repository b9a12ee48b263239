"""The LCoS's finite contrast in the rays (issue 36, item 3).

References: the closed form, image = (1 - 1/C) coded + (1/C) full aperture over the same
exposure, on a uniform emitter (every ray sees the same radiance) and, for C = 1, a capture of
the same scene through a full-aperture design; the ideal display (no ``lcos_contrast``) is
bit for bit the capture it was before.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.exposure.camera import capture_design
from pacam_render.exposure.direct import render_capture
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.model.design_file import write_design
from tests.exposure.test_render_error import _glowing_wall

pytestmark = pytest.mark.render


def _capture(desc=None, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return render_capture(
            CaptureSpec.geometric(**kw), progress=False, description=desc, truth=False
        )


@pytest.mark.parametrize("contrast", [2.0, 50.0])
def test_a_uniform_emitter_reads_the_closed_form(contrast):
    kw = {"scene": "wall", "mode": "coded", "width": 24, "height": 16, "spp": 64}
    cap = _capture(_glowing_wall(False), **kw, lcos_contrast=contrast)
    rec = cap.record
    full = rec.exposure_ms / rec.reference_exposure_ms  # the full aperture's light factor
    coded = (rec.camera["R_mm"] / rec.camera["R_max_mm"]) ** 2 * full  # the opening's alone
    want = 0.8 * ((1 - 1 / contrast) * coded + full / contrast)
    err = float(np.sqrt(np.mean(cap.mc_sigma**2)))
    assert abs(float(cap.image.mean()) - want) < 5 * err / np.sqrt(cap.image.size) + 1e-6
    assert rec.optics_error["effects"]["lcos_leakage"]["included"]
    assert float(cap.image.mean()) > 0.8 * coded * 1.01  # the leak is visible
    # the record's scale counts the leak too (issue 47): white reads 1 on the white scale
    assert rec.light_factor == pytest.approx(want / 0.8, rel=1e-9)


def test_contrast_one_is_the_full_aperture(tmp_path):
    """C = 1: no coding at all; the normal capture equals one through a full-aperture design,
    within the two captures' Monte Carlo error (pooled over the window)."""
    kw = {"scene": "train", "mode": "normal", "width": 64, "height": 48, "spp": 64}
    full = capture_design(CaptureSpec.geometric(**kw))
    write_design(tmp_path / "full.toml", full.with_(R_mm=full.R_max_mm))
    leak = _capture(**kw, lcos_contrast=1.0)
    wide = _capture(**{**kw, "seed": 1}, design=str(tmp_path / "full.toml"))  # independent
    assert leak.record.exposure_ms == wide.record.exposure_ms
    diff, var = leak.image - wide.image, leak.mc_sigma**2 + wide.mc_sigma**2
    assert float(np.mean(diff**2) / np.mean(var)) == pytest.approx(1.0, abs=0.3)
    ideal = _capture(**kw)  # and the coded opening alone is far from it
    assert np.mean((ideal.image - wide.image) ** 2) / np.mean(var) > 100


def test_an_ideal_display_is_the_capture_it_was():
    kw = {"scene": "train", "mode": "coded", "width": 32, "height": 24, "spp": 8}
    a, b = _capture(**kw), _capture(**kw, lcos_contrast=None)
    assert np.array_equal(a.image, b.image)
    assert not a.record.optics_error["effects"]["lcos_leakage"]["included"]


def test_contrast_is_checked_and_named():
    with pytest.raises(ParameterError, match="lcos_contrast must be >= 1"):
        CaptureSpec.geometric(lcos_contrast=0.5)
    with pytest.raises(ParameterError, match="lcos_contrast"):
        CaptureSpec.geometric(lcos_contrast=float("nan"))
    assert CaptureSpec.geometric(lcos_contrast=100.0).key() != CaptureSpec.geometric().key()


def test_levin_has_no_lcos_to_leak():
    kw = {"scene": "train", "mode": "levin", "width": 32, "height": 24, "spp": 8}
    with pytest.warns(Warning, match="lcos_contrast has no effect in levin mode"):
        cap = render_capture(
            CaptureSpec.geometric(**kw, lcos_contrast=10.0), progress=False, truth=False
        )
    assert any("lcos_contrast has no effect" in n for n in cap.record.notes)
    assert not cap.record.optics_error["effects"]["lcos_leakage"]["included"]
    assert np.array_equal(cap.image, _capture(**kw).image)  # the capture without it


def test_an_asked_lcos_value_not_applied_is_sized_not_called_ideal():
    """Issue 47, medium 7: a contrast or switching time given for a schedule without discs
    (the fluttered shutter here, a bitmap design alike) is named in the budget as asked and
    not applied, sized at the asked value by the closed forms; it was "ideal LCoS", size 0."""
    from pacam_render.capture.optics_error import image_rms, summary_line

    kw = {"scene": "train", "mode": "flutter", "width": 32, "height": 24, "spp": 8}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cap = render_capture(
            CaptureSpec.geometric(**kw, lcos_contrast=2.0, lcos_switching_ms=0.5),
            progress=False,
            truth=False,
        )
    block = cap.record.optics_error
    leak, switch = block["effects"]["lcos_leakage"], block["effects"]["lcos_switching"]
    for e, flag, value in ((leak, "lcos_contrast", 2), (switch, "lcos_switching_ms", 0.5)):
        assert not e["included"] and e["asked"] == value
        assert e["how"].startswith(f"{flag} = {value:g} was asked but is not in the rays")
        assert "ideal" not in e["how"]
    assert leak["size_rms"] == pytest.approx(leak["size_rms_per_inverse_contrast"] / 2.0)
    assert leak["size_rms"] > 0
    code = "1010000111000001010000110011110111010111001001100111"  # Raskar et al. 2006
    n = 1 + sum(a != b for a, b in zip(code, code[1:]))  # the shutter's runs switch, issue 56
    t = cap.record.exposure_ms
    assert switch["size_rms"] == pytest.approx((n - 1) / t * 0.5 * image_rms(cap.image))
    assert block["largest_left_out"] in ("lcos_leakage", "lcos_switching")
    assert "at the asked" in summary_line(block)


def test_the_cli_renders_every_lcos_flaw_and_the_budget_says_so(tmp_path):
    import json

    from pacam_render.cli import main

    out = tmp_path / "c"
    args = ["render", "train", "--mode", "coded", "--crop", "600,440,32,24", "--spp", "8",
            "--diffraction", "on", "--lcos-contrast", "500", "--lcos-fill-factor", "0.9",
            "--lcos-switching", "0.5", "--no-truth", "--quiet", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    rec = json.loads((out / "capture.json").read_text())
    effects = rec["optics_error"]["effects"]
    assert effects["lcos_leakage"]["contrast"] == 500
    assert effects["lcos_grid"]["fill_factor"] == 0.9
    assert effects["lcos_switching"]["switching_ms"] == 0.5
    assert all(effects[k]["included"] for k in ("diffraction", "lcos_leakage", "lcos_grid"))
    assert rec["spec"]["lcos_switching_ms"] == 0.5
