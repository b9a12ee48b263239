"""The design file's key reference (issue 46, item 7): every key the reader accepts is listed,
with a flag that ``pacam design`` really has, and the defaults are the prototype's."""

from __future__ import annotations

import re

import pytest

from pacam_render.cli import build_parser
from pacam_render.errors import FileKeyError
from pacam_render.model import design_file as df
from pacam_render.model.camera import prototype
from pacam_render.model.design_keys import KEYS, key_rows


def _accepted() -> set[str]:
    """The keys the reader takes: its tables, the opening and the schedule's kinds."""
    out = {"format", "name"}
    out |= {f"[{t}] {k}" for t, keys in df._TABLES.items() for k in keys}
    out |= {f"[opening] {k}" for k in df._OPENING_KEYS}
    out |= {"[schedule] kind", "[schedule] centres_mm", "[schedule] masks"}
    return out


def test_every_accepted_key_is_listed_once():
    listed = [r["key"] for r in key_rows()]
    assert len(listed) == len(set(listed))
    assert set(listed) == _accepted()


def test_a_key_not_listed_is_refused_by_the_reader(tmp_path):
    p = tmp_path / "d.toml"
    p.write_text('[lens]\nfocus_distance_mm = 751.6\nfocus_mm = 1\n[opening]\nR_mm = 1.98\n'
                 '[schedule]\nkind = "parabolic"\n')  # fmt: skip
    with pytest.raises(FileKeyError, match=r"unknown keys in \[lens\]: \['focus_mm'\]"):
        df.read_design(p)


def test_the_flags_exist_and_the_defaults_are_the_prototypes():
    sub = next(a for a in build_parser()._actions if a.dest == "command" or a.choices)
    design = sub.choices["design"]
    flags = {o for a in design._actions for o in a.option_strings}
    for k in KEYS:
        for flag in re.findall(r"--[a-z-]+", k.flag or ""):
            assert flag in flags, (k.key, flag)
    rows = {r["key"]: r for r in key_rows()}
    proto = prototype()
    assert float(rows["[exposure] exposure_ms"]["default"]) == proto.exposure_ms
    assert float(rows["[lens] R_max_mm"]["default"]) == pytest.approx(proto.R_max_mm)
    assert int(rows["[exposure] n_patterns"]["default"]) == proto.n_patterns
