"""The crossover map (issue 38): which camera wins per light level and speed, by how much, and
where the win is not resolved; and the per-camera small multiples. Both are written by
``pacam study``. No render: the rows are made by hand, the reference is computed here by brute
force, independently of :mod:`pacam_render.study.crossover_map`."""

from __future__ import annotations

import itertools
import math
import statistics

import matplotlib
import numpy as np
import pytest
from scipy import stats

from pacam_render.study import crossover_map as cmap
from pacam_render.study.point import point_row
from pacam_render.study.report import write_report
from pacam_render.study.results import Results
from pacam_render.study.small_multiples import curves_figure, mode_curves, y_floor
from pacam_render.study.spec import load_study

matplotlib.use("Agg")

LIGHT = "light_level_photons_per_px_per_ms"
CAPTURES = [  # (mode, design, method)
    *(("coded", d, m) for d in ("prototype", "cover=1.4") for m in ("hl", "wiener")),
    *(("levin", "cover=1.4", m) for m in ("hl", "wiener")),
    *((mode, "prototype", m) for mode in ("normal", "short") for m in ("hl", "wiener")),
]


def _row(mode, design, method, speed, light, seed, psnr, status="ok") -> dict:
    """A row as :func:`.report.load_rows` gives it (numbers as floats)."""
    return {
        "mode": mode,
        "design": design,
        "method": method,
        "speed_px_per_ms": speed,
        LIGHT: light,
        "seed": seed,
        "psnr_moving_db": psnr,
        "status": status,
        "scene": "train",
        "sensor": "grasshopper-icx285",
        "depth_mm": 495.0,
    }


def _synthetic(seed: int = 0) -> list[dict]:
    """Three seeds of every capture at 2 speeds x 5 light levels: PSNRs whose order changes
    with light, with seed scatter large enough that some winners are not resolved; plus a
    failed row and a nan score, which must not count."""
    rng = np.random.default_rng(seed)
    base = {"coded": 20.0, "levin": 19.5, "normal": 18.0, "short": 14.0}
    slope = {"coded": 1.0, "levin": 1.2, "normal": 0.4, "short": 3.0}
    rows = []
    for (mode, design, method), speed, light in itertools.product(
        CAPTURES, (0.7, 1.4), (10.0, 30.0, 100.0, 1000.0, 10000.0)
    ):
        centre = base[mode] + slope[mode] * math.log10(light) - (method == "wiener") * 1.5
        centre += rng.normal(0, 0.5) - (design == "prototype") * 0.3 - speed
        for s in range(3):
            rows.append(_row(mode, design, method, speed, light, s, centre + rng.normal(0, 0.2)))
    rows.append(_row("short", "prototype", "hl", 0.7, 10.0, 3, 99.0, status="error: boom"))
    rows.append(_row("normal", "prototype", "hl", 0.7, 10.0, 4, math.nan))
    return rows


def _reference(rows: list[dict]) -> dict:
    """Brute force: {(speed, light): (winner, runner-up, margin, overlap)}, each camera at the
    capture with the best mean over its seeds, the 95 % interval from scipy's t.interval."""
    groups: dict = {}
    for r in rows:
        if r["status"] == "ok" and not math.isnan(r["psnr_moving_db"]):
            key = (r["speed_px_per_ms"], r[LIGHT], r["mode"], r["design"], r["method"])
            groups.setdefault(key, []).append(r["psnr_moving_db"])
    best: dict = {}
    for (speed, light, mode, _, _), v in groups.items():
        mean = statistics.mean(v)
        lo, hi = stats.t.interval(0.95, len(v) - 1, loc=mean, scale=stats.sem(v))
        if mean > best.get((speed, light), {}).get(mode, (-math.inf,))[0]:
            best.setdefault((speed, light), {})[mode] = (mean, lo, hi)
    out = {}
    for cell, modes in best.items():
        (w, (wm, wlo, _)), (r, (rm, _, rhi)) = sorted(modes.items(), key=lambda kv: -kv[1][0])[:2]
        out[cell] = (w, r, wm - rm, wlo <= rhi)
    return out


def _title(fig) -> str:
    """The figure's suptitle, its lines (wrapped to the figure's width) joined by spaces."""
    return " ".join(fig._suptitle.get_text().split())


def test_winner_and_margin_per_cell_match_brute_force():
    rows = _synthetic()
    ref = _reference(rows)
    cells = cmap.winner_cells(rows)
    assert {(c.speed, c.light) for c in cells} == set(ref)
    for c in cells:
        winner, runner_up, margin, overlap = ref[(c.speed, c.light)]
        assert (c.winner, c.runner_up) == (winner, runner_up)
        assert c.margin_db == pytest.approx(margin, abs=1e-9)
        assert c.overlap == overlap
    assert {c.winner for c in cells} >= {"short", "levin"}  # the winner changes across the map
    assert 0 < sum(c.overlap for c in cells) < len(cells)  # both kinds of cell are tested


def test_a_hand_computed_cell():
    """coded 20, 21, 22 (mean 21, s = 1, half-width t_2 / sqrt 3 = 2.484) against normal at
    18, 18, 18 (no spread) wins by 3 dB, resolved; against 19, 19.5, 20 (half-width 1.242)
    it wins by 1.5 dB, unresolved (18.516 <= 20.742). Its best capture is the better design."""
    rows = [_row("coded", "cover=1.4", "hl", 1.4, 10.0, s, v) for s, v in enumerate((20, 21, 22))]
    rows += [_row("coded", "prototype", "hl", 1.4, 10.0, s, 15.0) for s in range(3)]
    rows += [_row("normal", "prototype", "hl", 1.4, 10.0, s, 18.0) for s in range(3)]
    rows += [_row("coded", "cover=1.4", "hl", 1.4, 100.0, s, v) for s, v in enumerate((20, 21, 22))]
    rows += [
        _row("normal", "prototype", "hl", 1.4, 100.0, s, v) for s, v in enumerate((19, 19.5, 20))
    ]
    a, b = cmap.winner_cells(rows)
    assert (a.winner, a.runner_up, a.overlap) == ("coded", "normal", False)
    assert a.margin_db == pytest.approx(3.0)
    assert a.scores["coded"].half == pytest.approx(4.302653 / math.sqrt(3), rel=1e-6)
    assert a.scores["coded"].capture == "cover=1.4 + hl"
    assert (b.winner, b.runner_up, b.overlap) == ("coded", "normal", True)
    assert b.margin_db == pytest.approx(1.5)
    assert cmap.margin_text(a) == "+3.0 dB" and cmap.margin_text(b) == "+1.5 dB"


def test_the_map_colours_writes_and_hatches_each_cell_as_computed():
    rows = _synthetic(1)
    ref = _reference(rows)
    fig = cmap.map_figure(cmap.winner_cells(rows), "study test")
    (ax,) = fig.axes
    rects = {p.get_gid(): p for p in ax.patches if (p.get_gid() or "").startswith("cell ")}
    texts = {t.get_gid(): t.get_text() for t in ax.texts}
    modes = sorted({r["mode"] for r in rows})
    assert len(rects) == len(ref) == 10
    hatched = set()
    for (speed, light), (winner, runner_up, margin, _) in ref.items():
        rect = rects[f"cell {speed:g} {light:g}"]
        colour = matplotlib.colors.to_hex(rect.get_facecolor())
        assert colour == matplotlib.colors.to_hex(cmap.mode_colour(winner, modes))
        assert texts[f"margin {speed:g} {light:g}"] == f"{margin:+.1f} dB"
        assert texts[f"detail {speed:g} {light:g}"].endswith(f"over {runner_up}")
        if rect.get_hatch():
            hatched.add((speed, light))
    assert hatched == {cell for cell, (*_, overlap) in ref.items() if overlap}  # exactly there
    assert hatched  # the synthetic table has unresolved cells
    assert "hatched: their 95 % intervals over 3 seeds overlap" in _title(fig)
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "intervals overlap" in legend
    assert {f"{c.winner} wins" for c in cmap.winner_cells(rows)} <= set(legend)


def test_one_camera_cells_and_the_scenes_own_speed():
    rows = [_row("coded", "prototype", "hl", math.nan, 10.0, 0, 20.0)]
    rows += [_row("short", "prototype", "hl", math.nan, 10.0, 0, 19.0)]
    rows += [_row("short", "prototype", "hl", math.nan, 300.0, 0, 25.0)]
    a, b = cmap.winner_cells(rows)
    assert (a.speed, a.winner, a.runner_up, a.margin_db) == (cmap.SCENE_SPEED, "coded", "short", 1)
    assert (b.winner, b.runner_up, b.overlap) == ("short", None, False)
    assert math.isnan(b.margin_db) and cmap.margin_text(b) == "only short"
    fig = cmap.map_figure([a, b])
    assert [t.get_text() for t in fig.axes[0].get_yticklabels()] == ["the scene's own"]
    assert "one seed: no intervals, so nothing is hatched" in _title(fig)
    assert cmap.map_applies(rows)


def test_the_map_is_drawn_only_over_light_levels_with_several_cameras():
    rows = _synthetic()
    assert cmap.map_applies(rows)
    one_light = [r for r in rows if r[LIGHT] == 100.0]
    assert not cmap.map_applies(one_light)  # the speed study's shape: one light level
    one_mode = [r for r in rows if r["mode"] == "coded"]
    assert not cmap.map_applies(one_mode)
    two_scenes = rows + [{**rows[0], "scene": "soccer"}]
    assert not cmap.map_applies(two_scenes)


def test_small_multiples_one_panel_per_camera_and_speed_on_shared_axes():
    rows = _synthetic()
    data = mode_curves(rows)
    fig = curves_figure(rows, "study test")
    panels = {ax.get_gid(): ax for ax in fig.axes}
    assert set(panels) == {
        f"panel {m} {s:g}" for m in ("coded", "levin", "normal", "short") for s in (0.7, 1.4)
    }
    coded = panels["panel coded 0.7"]
    labels = [t.get_text() for t in coded.get_legend().get_texts()]
    assert sorted(labels) == sorted(f"{d} + {m}" for _, d, m in CAPTURES[:4])  # its 4 captures
    assert [t.get_text() for t in panels["panel short 1.4"].get_legend().get_texts()] == [
        "hl",
        "wiener",
    ]
    ylims = {ax.get_ylim() for ax in fig.axes}
    xlims = {ax.get_xlim() for ax in fig.axes}
    assert len(ylims) == 1 and len(xlims) == 1  # shared
    xs, ys, ci = data[0.7]["coded"]["cover=1.4 + hl"]
    ref = [
        r["psnr_moving_db"]
        for r in rows
        if r["mode"] == "coded"
        and r["design"] == "cover=1.4"
        and r["method"] == "hl"
        and r["speed_px_per_ms"] == 0.7
        and r[LIGHT] == 10.0
    ]
    assert (xs[0], ys[0]) == (10.0, pytest.approx(np.mean(ref)))
    floor = y_floor(data)
    assert floor is None or ylims.pop()[0] == floor


def _quick_results(out) -> None:
    """A finished ``--quick`` crossover run's folder, without rendering: every point's row,
    with the study's own keys and digests (:class:`.results.Results`)."""
    spec = load_study("crossover", quick=True)
    rows = []
    for p in spec.points:
        psnr = {"coded": 20.0, "normal": 19.0, "short": 14.0}[p.mode] + 2 * math.log10(
            p.light_level
        )
        values = {"psnr_db": psnr, "ssim": 0.5, "psnr_moving_db": psnr, "psnr_static_db": psnr}
        values.update(psnr_moving_interior_db=psnr, noise_sigma=0.01, render_spp=64)
        rows.append(point_row(p, values, "ok", 1.0, 2.0))
    out.mkdir()
    Results(out, spec).add(rows)


def test_pacam_study_quick_writes_the_map_and_the_small_multiples(tmp_path, capsys):
    """The command path: ``pacam study crossover --quick`` over a finished folder renders
    nothing, and writes the report with both figures."""
    from pacam_render.cli import main

    out = tmp_path / "study"
    _quick_results(out)
    argv = ["study", "crossover", "--quick", "--out", str(out), "--workers", "0", "--quiet"]
    assert main(argv) == 0
    said = capsys.readouterr().out
    assert "0 points run, 9 already done, 0 failed" in said
    assert "crossover_map.png" in said and "crossover.png" in said
    for name in ("crossover_map.png", "crossover.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = (out / "report.md").read_text()
    assert "![Which camera wins at each light level and speed](crossover_map.png)" in text
    assert "*Figure: Which camera restores the moving objects best?" in text
    assert "(crossover.png)" in text and "one panel per camera and speed" in text
    assert "| 1.4 | 10 | coded hl | 22.00 | normal hl | 21.00 | +1.00 | no |" in text


def test_the_speed_study_gets_no_map(tmp_path):
    spec = load_study("speed", quick=True)
    rows = []
    for p in spec.points:
        values = {"psnr_db": 20.0, "ssim": 0.5, "psnr_moving_db": 20.0 - (p.speed_px_per_ms or 0)}
        values.update(psnr_static_db=20.0, psnr_moving_interior_db=20.0)
        rows.append(point_row(p, values, "ok", 1.0, 2.0))
    tmp_path.mkdir(exist_ok=True)
    Results(tmp_path, spec).add(rows)
    files = write_report(spec, tmp_path)
    assert "crossover_map.png" not in files and not (tmp_path / "crossover_map.png").exists()


def test_several_scenes_map_as_rows_when_each_has_its_own_speed():
    """Held-out scenes of a family, each at its own speed: one map row per scene (issue 58,
    item 6); two scenes in one speed row stay refused (above)."""
    rows = [r for r in _synthetic() if r[cmap.SPEED] == 0.7]
    other = [{**r, "scene": "family:occluders:11", cmap.SPEED: 2.1} for r in rows]
    assert cmap.map_applies(rows + other)
    scenes = cmap.row_scenes(rows + other)
    assert list(scenes.values()) == [rows[0]["scene"], "family:occluders:11"]
    text = "\n".join(cmap.map_section(rows + other))
    assert "2.1 px/ms: family:occluders:11" in text
    assert cmap.row_scenes(rows) == {}
