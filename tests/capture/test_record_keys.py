"""A capture record's top-level keys (issue 47, low): an unknown key was ignored silently, so
a misspelt hand edit (``lightfactor``) changed nothing and said nothing."""

from __future__ import annotations

import warnings

import pytest

from pacam_render.capture.record import CaptureRecord
from pacam_render.limits import PacamWarning
from pacam_render.model.camera import prototype


def _record(**more) -> dict:
    return {"camera": prototype().inputs(), "mode": "coded", **more}


def test_an_unknown_key_is_named_and_kept():
    with pytest.warns(PacamWarning, match="unknown key\\(s\\) 'lightfactor' not read"):
        rec = CaptureRecord.from_json(_record(lightfactor=0.5))
    assert rec.light_factor == 1.0  # not read as the light factor
    assert rec.to_json()["lightfactor"] == 0.5  # and written back as it was


def test_the_keys_pacam_writes_say_nothing():
    with warnings.catch_warnings():
        warnings.simplefilter("error", PacamWarning)
        rec = CaptureRecord.from_json(_record(lightfield={"store": "s"}, light_factor=0.2))
        again = CaptureRecord.from_json(rec.to_json())
    assert rec.extra == again.extra == {"lightfield": {"store": "s"}}
    assert again.light_factor == 0.2
