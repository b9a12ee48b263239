"""Choosing the variant for grey renders (issue 35 item 5): ``grey`` selects a mono variant
and is refused, naming the fix, with a colour ``PACAM_VARIANT``. No rendering."""

from __future__ import annotations

import pytest

from pacam_render.errors import ParameterError
from pacam_render.render.variant import choose_variant, grey_request, is_mono


def test_is_mono():
    assert is_mono("llvm_ad_mono") and is_mono("cuda_ad_mono_polarized")
    assert not is_mono("llvm_ad_rgb") and not is_mono("scalar_spectral") and not is_mono(None)


def test_grey_request_reads_the_environment_without_mitsuba(monkeypatch):
    monkeypatch.delenv("PACAM_VARIANT", raising=False)
    assert grey_request(True) is True and grey_request(False) is False
    monkeypatch.setenv("PACAM_VARIANT", "llvm_ad_mono")
    assert grey_request(False) is True  # a mono variant makes every capture grey
    monkeypatch.setenv("PACAM_VARIANT", "llvm_ad_rgb")
    assert grey_request(False) is False
    with pytest.raises(ParameterError, match="PACAM_VARIANT='llvm_ad_rgb' renders colour"):
        grey_request(True)


def test_choose_variant_refuses_mono_with_a_colour_override(monkeypatch):
    monkeypatch.setenv("PACAM_VARIANT", "scalar_rgb")
    with pytest.raises(ParameterError, match="unset PACAM_VARIANT or set it to a mono variant"):
        choose_variant(mono=True)
    assert choose_variant(mono=False) == "scalar_rgb"
    monkeypatch.setenv("PACAM_VARIANT", "llvm_ad_mono")
    from pacam_render.render.variant import llvm_status

    if llvm_status()[0]:
        assert choose_variant(mono=True) == "llvm_ad_mono"
