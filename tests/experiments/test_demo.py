"""The demo end to end at a tiny size: it renders, deconvolves and writes its figure and table."""

from types import SimpleNamespace

import numpy as np

from pacam_render.cli import main
from pacam_render.experiments.demo import _noisy
from pacam_render.io import exr as exrio
from pacam_render.model.illumination import relative_illumination_map


def test_demo_runs_small(tmp_path, capsys):
    out = tmp_path / "demo"
    argv = ["demo", "--out", str(out), "--width", "64", "--height", "48", "--spp", "16"]
    assert main(argv) == 0
    assert (out / "demo.png").stat().st_size > 10_000
    table = (out / "demo.md").read_text()
    for row in ("normal", "coded, prototype", "deconvolved (analytic PSF), covers 1.4", "short"):
        assert row in table
    for sub in ("reference", "normal", "coded_0", "coded_1", "short"):
        assert (out / sub / "capture.exr").is_file()
    # a camera's optics: the lens captures are irradiance with the cos^4 map (0.61 at the
    # corners of the whole frame); the pinhole reference is the radiance truth
    for sub in ("normal", "coded_0", "short"):
        m = exrio.read_exr(out / sub / "capture.exr")["relative_illumination"]
        assert abs(float(m.min()) - 0.613) < 0.02 and float(m.max()) > 0.99
    assert "relative_illumination" not in exrio.read_exr(out / "reference" / "capture.exr")
    said = capsys.readouterr()
    assert "design report" in said.out
    # the whole demo's time is said once, before any render, and one bar covers it
    assert said.err.count("estimate:") == 1
    head = said.err[: said.err.index("diffraction auto: rendering")]
    assert "estimate: demo about" in head and "deblurring" in head
    assert "demo:" in said.err.rsplit("estimate:", 1)[1]  # the overall bar's label
    assert main(argv) == 2  # a second run needs --force
    assert main([*argv, "--force"]) == 0


def test_demo_rejects_tiny_sizes(capsys):
    assert main(["demo", "--width", "8"]) == 2
    assert "--width must be >= 16" in capsys.readouterr().err


def test_the_demo_shows_and_deblurs_the_flat_fielded_image():
    """The panels are what a camera pipeline shows: the sensor's image over light_factor,
    divided by the cos^4 map (closed form), so the corners are not darkened."""
    m = relative_illumination_map("cos4", 40, 30, 60.0, None).astype("float32")
    rng = np.random.default_rng(1)
    noisy = rng.uniform(0.1, 0.2, (30, 40, 3)).astype("float32")
    cap = SimpleNamespace(
        extra_layers={"noisy": noisy, "relative_illumination": m},
        record=SimpleNamespace(light_factor=0.5),
    )
    half = np.radians(30.0)
    corner = (np.hypot(39.0 / 40, 29.0 / 40) * np.tan(half)) ** 2  # tan^2 at the corner pixel
    assert abs(float(m[-1, -1]) - 1.0 / (1.0 + corner) ** 2) < 0.01
    assert np.allclose(_noisy(cap), noisy / 0.5 / m[..., None], rtol=1e-6)
    cap.extra_layers.pop("relative_illumination")
    assert np.allclose(_noisy(cap), noisy / 0.5)
