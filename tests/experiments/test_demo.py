"""The demo end to end at a tiny size: it renders, deconvolves and writes its figure and table."""

from pacam_render.cli import main


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
    assert "design report" in capsys.readouterr().out
    assert main(argv) == 2  # a second run needs --force
    assert main([*argv, "--force"]) == 0


def test_demo_rejects_tiny_sizes(capsys):
    assert main(["demo", "--width", "8"]) == 2
    assert "--width must be >= 16" in capsys.readouterr().err
