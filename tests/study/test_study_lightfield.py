"""A study on light-field stores (``[render] lightfield = true``, issue 44 item 3): one store
per scene, speed and seed serves every design and mode of the grid, and its rows are scored as
a rendered study's; the key is checked before any work."""

import csv

import pytest

from pacam_render.errors import ParameterError
from pacam_render.study import load_study, run_study
from tests.patching import patch_everywhere

STUDY = """
[study]
name = "lf"
report = "table"
[render]
width = 1280
height = 960
crop = [440, 400, 96, 64]
spp = 8
noise_ratio = false
lightfield = true
[grid]
mode = ["coded", "normal"]
design = ["prototype", "cover=1.4"]
light_level = [3000.0]
seed = [0, 1]
"""


def _load(tmp_path, text):
    path = tmp_path / "lf.toml"
    path.write_text(text)
    return load_study(str(path))


@pytest.mark.render
def test_one_store_serves_every_design_and_mode(tmp_path, monkeypatch):
    import pacam_render.lightfield as lf

    stores = []
    real = lf.render_lightfield

    def counted(*args, **kwargs):
        stores.append(args[0])
        return real(*args, **kwargs)

    patch_everywhere(monkeypatch, lf, "render_lightfield", counted)
    spec = _load(tmp_path, STUDY)
    assert len(spec.groups()) == 2  # one per seed: every design and mode shares it
    run_study(spec, tmp_path / "out", workers=0, progress=False)
    with open(tmp_path / "out" / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    bad = [r["status"] for r in rows if r["status"] != "ok"]
    assert len(rows) == 8 and not bad, bad
    assert len(stores) == 2 and {len(s.designs) for s in stores} == {4}
    r_px = {(r["mode"], r["design"]): float(r["r_px"]) for r in rows}
    assert r_px[("coded", "prototype")] == pytest.approx(2.0, rel=1e-3)
    assert r_px[("coded", "cover=1.4")] == pytest.approx(3.13, rel=1e-2)
    assert not (tmp_path / "out" / ".renders" / "render_0000" / "store").exists()  # not kept
    report = (tmp_path / "out" / "report.md").read_text()
    assert "Paired differences between designs" in report and "| coded cover=1.4 |" in report


def test_paired_differences_are_taken_seed_by_seed():
    """Two seeds whose scores move together: the paired interval is narrow where the scores'
    own spread is wide (a closed form: differences 1.0 and 1.2 dB)."""
    from pacam_render.study.paired import paired_differences

    base = {"scene": "train", "speed_px_per_ms": 1.0, "depth_mm": None, "sensor": "s",
            "light_level_photons_per_px_per_ms": 300.0, "method": "hl"}  # fmt: skip
    rows = [
        {**base, "mode": "coded", "design": d, "seed": s, "psnr_moving_db": v}
        for d, s, v in [("a", 0, 20.0), ("b", 0, 21.0), ("a", 1, 30.0), ("b", 1, 31.2)]
    ]
    (d,) = paired_differences(rows)
    assert d["capture"] == "coded b" and d["n"] == 2
    assert d["mean"] == pytest.approx(1.1)
    assert d["half"] == pytest.approx(12.706 * 0.1414214 / 2**0.5, rel=1e-3)


@pytest.mark.parametrize(
    "change, words",
    [
        (("noise_ratio = false\n", "noise_ratio = 0.2\n"), "noise_ratio = false"),
        (('mode = ["coded", "normal"]', 'mode = ["coded", "levin"]'), "levin"),
        (("lightfield = true", 'lightfield = "yes"'), "lightfield must be true or false"),
    ],
)
def test_a_lightfield_study_is_checked_before_any_work(tmp_path, change, words):
    with pytest.raises(ParameterError, match=words):
        _load(tmp_path, STUDY.replace(*change))
