"""A study's report describes the run that made it (issue 35): a ``--quick`` run's report and
plots say they are the quick run, with its window, sensor, grid and seeds, derived from the spec
that ran; the study's description (of the full run) follows as such. No render: the rows are
made by hand."""

from __future__ import annotations

import csv

import pytest

from pacam_render.study import crossover_map, small_multiples
from pacam_render.study import report as report_module
from pacam_render.study.point import COLUMNS, point_row
from pacam_render.study.results import RESULTS
from pacam_render.study.spec import load_study


def _write_rows(out, spec, points=None) -> None:
    """results.csv for ``points`` of ``spec`` (default all), with plausible numbers."""
    rows = []
    for p in spec.points if points is None else points:
        psnr = 20.0 + (p.light_level**0.1) + (1.0 if p.mode == "coded" else 0.0)
        values = {
            "psnr_db": psnr,
            "ssim": 0.5,
            "psnr_moving_db": psnr - 1.0,
            "psnr_static_db": psnr + 1.0,
            "psnr_moving_interior_db": psnr - 0.5,
            "r_px": 0.5,
            "noise_sigma": 1.0 / p.light_level**0.5,
            "render_noise_sigma": 1e-4,
            "render_noise_ratio": 1e-4 * p.light_level**0.5,
            "model_sigma": 0.01,
            "render_spp": 256 if p.mode == "coded" else 512,
        }
        rows.append(point_row(p, values, "ok", 1.0, 2.0))
    out.mkdir(parents=True, exist_ok=True)
    with open(out / RESULTS, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


@pytest.fixture
def titles(monkeypatch):
    """The suptitle of every figure the report saves."""
    seen = []
    real = report_module.save_figure

    def save(fig, path, dpi):
        seen.append(fig._suptitle.get_text() if fig._suptitle else "")
        return real(fig, path, dpi)

    for module in (report_module, crossover_map, small_multiples):  # every figure's writer
        monkeypatch.setattr(module, "save_figure", save)
    return seen


def test_a_quick_report_describes_the_quick_run(tmp_path, titles):
    spec = load_study("crossover", quick=True)
    assert spec.quick
    _write_rows(tmp_path, spec)
    files = report_module.write_report(spec, tmp_path)
    assert "crossover.png" in files
    text = (tmp_path / "report.md").read_text()
    head, _, rest = text.partition("The full study (without `--quick`), which this run is not:")
    assert head.startswith("# Study `crossover` (quick)\n")
    assert "pacam study crossover --quick" in head
    r = spec.render  # what ran, from the spec: not the description's 400x160 window
    crop = f"a {r['crop'][2]}x{r['crop'][3]} px window at ({r['crop'][0]}, {r['crop'][1]})"
    assert crop == "a 96x64 px window at (128, 120)"
    assert crop in head
    assert "a 320x240 px `prototype` sensor (the preset's 1280x960 binned 4x4)" in head
    assert f"{len(spec.points)} points of scene train" in head
    assert "light level 10, 300, 3000 photons/px/ms" in head
    assert "1 seed(s) (0)" in head
    assert "(`ldsampler`; the renders took 256 to 512 spp)" in head  # as they ran
    assert "400x160" not in head and "three seeds" not in head
    assert "> Fig. 8 rendered" in rest  # the full study's description, quoted as such
    quick = (
        "study crossover, QUICK run (--quick): 96x64 px window of a 320x240 sensor, 1 seed; "
        "not the full study"
    )
    assert "crossover_map.png" in files  # issue 38: the map, then the small multiples
    assert [t.split("\n")[0] for t in titles] == [quick, quick]  # each over its caption


def test_a_full_report_describes_the_full_run(tmp_path, titles):
    spec = load_study("crossover")
    assert not spec.quick
    _write_rows(tmp_path, spec, spec.points[:6])
    report_module.write_report(spec, tmp_path)
    text = (tmp_path / "report.md").read_text()
    assert text.startswith("# Study `crossover`\n\nFig. 8 rendered")
    assert (
        "a 400x160 px window at (200, 560) of a 1280x960 px `prototype` sensor (full resolution)"
        in text
    )
    assert f"6 of {len(spec.points)} points done" in text
    assert "3 seed(s) (0, 1, 2)" in text
    assert "quick" not in text.lower()
    assert titles and [t.split("\n")[0] for t in titles] == ["study crossover"] * len(titles)
