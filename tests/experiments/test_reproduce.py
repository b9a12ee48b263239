"""The paper's simulation figures on --quick runs: files written, and the paper's qualitative
claims asserted on our numbers (each claim could fail if the physics or the pipeline broke)."""

import csv

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.experiments import fig6, fig7, fig8, fig9
from pacam_render.experiments import reproduce as R
from pacam_render.experiments import simulate as E
from pacam_render.restore import metrics


@pytest.fixture(scope="module")
def quick_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("repro")
    assert main(["reproduce", "all", "--quick", "--out", str(out)]) == 0
    return out


def rows(path):
    with open(path) as fh:
        return list(csv.DictReader(fh))


def test_files_written(quick_dir):
    for name in R.FIGURES:
        for ext in ("csv", "png", "md"):
            assert (quick_dir / f"{name}.{ext}").stat().st_size > 0
    assert {"a_i_px_per_ms2", "velocity_px_per_ms", "psnr_db"} <= set(
        rows(quick_dir / "fig6.csv")[0]
    )


def test_the_engine_gives_the_serial_figures(quick_dir, tmp_path):
    """``reproduce all`` ran its figures on a 2-worker LocalCluster; serially, fig9 is the same."""
    out = tmp_path / "serial"
    assert main(["reproduce", "fig9", "--quick", "--workers", "0", "--out", str(out)]) == 0
    assert rows(out / "fig9.csv") == rows(quick_dir / "fig9.csv")


def test_refuses_to_overwrite(quick_dir, capsys):
    assert main(["reproduce", "fig9", "--quick", "--out", str(quick_dir)]) == 2
    assert "--force" in capsys.readouterr().err


def curves(path, model):
    out = {}
    for r in rows(path):
        if r["model"] == model:
            out.setdefault(float(r["a_i_px_per_ms2"]), []).append(
                (float(r["velocity_px_per_ms"]), float(r["psnr_db"]))
            )
    return {a: np.array(v) for a, v in sorted(out.items())}


def test_fig6_higher_acceleration_flattens_and_lowers_peak(quick_dir):
    c = curves(quick_dir / "fig6.csv", "Eq. 14 (continuous)")
    peaks = [v[:, 1].max() for v in c.values()]
    falls = [fig6.flattening_db(v) for v in c.values()]
    assert all(np.diff(peaks) < 0)  # lower peak with every step up in a_i
    assert falls[-1] < falls[0] / 2  # much flatter at the highest a_i
    assert c[0.256][-1, 1] > c[0.008][-1, 1] + 2  # and better for the fastest objects


def test_fig9_peaks_at_zero_displacement_and_widens(quick_dir):
    by = {}
    for r in rows(quick_dir / "fig9.csv"):
        by.setdefault(float(r["assumed_depth_mm"]), []).append(
            (float(r["depth_mm"]), float(r["psnr_db"]))
        )
    widths = []
    for Za, pts in sorted(by.items()):
        c = np.array(pts)
        assert fig9.peak_gap_db(c, Za) < 0.25
        lo, hi = fig9.tolerated_range_mm(c)
        assert lo <= Za <= hi
        widths.append((hi - lo) / Za)
    assert widths == sorted(widths) and widths[-1] > 3 * widths[0]


def test_alignment_recovers_a_known_shift():
    """A pure shift PSF (delta off-centre) must score like no blur after alignment."""
    imgs = E.load_images(2, size=64)
    sc = E.Scenes(imgs, pad=8)
    k = np.zeros((1, 9))
    k[0, 7] = 1.0  # shift by +3 px
    k0 = np.zeros((1, 1))
    k0[0, 0] = 1.0
    aligned = E.simulate(sc, k, k0, E.gaussian_noise(0.0), 0, margin_px=4)
    unaligned = metrics.psnr_batch(E.wiener_batch(sc.blurred(k), k0, 0.0), imgs, 4)
    assert np.all(unaligned < 25)  # a 3-px shift ruins PSNR ...
    assert np.all(aligned > 35)  # ... and sub-pixel alignment (parabola peak) recovers it


def test_tolerated_range_interpolates():
    c = np.array([[100.0, 0.0], [200.0, 10.0], [400.0, 0.0]])
    lo, hi = fig9.tolerated_range_mm(c, drop_db=5.0)
    assert lo == pytest.approx(np.exp(0.5 * (np.log(100) + np.log(200))))
    assert hi == pytest.approx(np.exp(0.5 * (np.log(200) + np.log(400))))


def test_fig7_interior_peak_moves_with_acceleration(quick_dir):
    by = {}
    for r in rows(quick_dir / "fig7.csv"):
        by.setdefault(float(r["a_i_px_per_ms2"]), []).append(
            (float(r["r_px"]), float(r["psnr_db"]))
        )
    peaks = []
    for _, pts in sorted(by.items()):
        c = np.array(pts)
        k = int(np.argmax(c[:, 1]))
        assert 0 < k < len(c) - 1  # an interior optimum: too little light vs too much defocus
        peaks.append(fig7.peak_radius_px(c))
    assert peaks == sorted(peaks)  # the best r grows with a_i, as in the paper


def test_fig8_ratio_rises_with_noise_and_crosses_one(quick_dir):
    by = {}
    for r in rows(quick_dir / "fig8.csv"):
        by.setdefault((r["curve"], float(r["a_i_px_per_ms2"])), []).append(
            (float(r["noise_level"]), float(r["quality_ratio"]))
        )
    for (curve, a), pts in by.items():
        c = np.array(pts)
        assert c[-1, 1] > 1 > c[0, 1], (curve, a)  # short exposure wins when bright only
        assert np.isfinite(fig8.crossing_noise_level(c))
        assert np.all(np.diff(c[:, 1]) > -0.05), (curve, a)  # rises (up to MC wiggle)
    for a in fig7.FIG7_A:  # Levin's camera, with no defocus, does better at high noise
        assert by[("Levin (same aperture)", a)][-1][1] > by[("proposed", a)][-1][1]
