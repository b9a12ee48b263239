"""Issue 37 item 9: a deconvolution's memory and seconds are estimated before any work, what
does not fit the memory is refused (naming the estimate, what is available and what fits),
the iterative methods show their progress, and a MemoryError is one line, not a traceback.

References: the padded grid of :func:`~pacam_render.restore.fourier.taper_pad`, a peak RSS
measured in a fresh process, scikit-image's ``richardson_lucy``, and a ``ulimit -v`` of 6 GB
(the issue's limit, under which a 4000 x 3000 ``hl`` died with a traceback).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from pacam_render.cli import main
from pacam_render.errors import ParameterError
from pacam_render.io.exr import write_exr
from pacam_render.restore import deconvolve as D
from pacam_render.restore import deconvolve_cost as cost
from pacam_render.restore.fourier import pad_width, taper_pad

BENCH = os.path.join(
    os.path.dirname(__file__), "..", "..", "benchmarks", "bench_deconvolve_cost.py"
)


def _refuse(what: str):
    def fail(*args, **kwargs):
        raise AssertionError(what)

    return fail


def test_the_grid_is_the_one_the_methods_pad_to_and_the_cost_grows_with_it():
    k = np.ones((17, 13))
    for shape in ((96, 128), (101, 77, 3)):
        padded, _ = taper_pad(np.zeros(shape[:2]), pad_width(k.shape))
        assert cost.padded_grid(shape, k.shape) == padded.shape
    fixed = cost.MODEL["hl"][0]
    small = cost.deconvolve_cost((96, 128, 3), k.shape, "hl")
    big = cost.deconvolve_cost((192, 256, 3), k.shape, "hl")
    grids = np.prod(big.grid) / np.prod(small.grid)
    assert (big.method_bytes - fixed) / (small.method_bytes - fixed) == pytest.approx(grids)
    assert cost.deconvolve_cost((96, 128), k.shape, "hl").bytes < small.bytes
    longer = cost.deconvolve_cost((96, 128, 3), k.shape, "rl", {"iterations": 60})
    assert longer.seconds == pytest.approx(
        2 * cost.deconvolve_cost((96, 128, 3), k.shape, "rl").seconds
    )


def test_the_model_agrees_with_a_measured_peak():
    """hl's peak RSS (VmHWM) over the RSS before the call, in a fresh process, at a size the
    constants were not fitted on (640 x 480, 224 MB): the model within 20 %. (The benchmark
    checks more methods and sizes; a few MB of a small method's peak are the allocator's.)"""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    argv = [sys.executable, BENCH, "--one", "hl", "480", "640", "3", "1"]
    out = subprocess.run(argv, capture_output=True, text=True, env=env, check=True)
    measured = json.loads(out.stdout.strip().splitlines()[-1])["bytes"]
    model = cost.deconvolve_cost((480, 640, 3), (17, 17), "hl").method_bytes
    assert 0.8 < model / measured < 1.25


def test_deconvolve_refuses_what_does_not_fit_before_any_work(monkeypatch):
    image, k = np.full((64, 96, 3), 0.5), np.ones((5, 5))
    hl = cost.deconvolve_cost(image.shape, k.shape, "hl").bytes
    wiener = cost.deconvolve_cost(image.shape, k.shape, "wiener").bytes
    assert wiener < hl
    monkeypatch.setattr(cost, "available_bytes", lambda: (hl + wiener) / 2)
    monkeypatch.setattr(D, "sparse_deconvolve", _refuse("solved before refusing"))
    with pytest.raises(ParameterError) as err:
        D.deconvolve(image, k, "hl", noise_sigma=0.01)
    words = str(err.value)
    assert "96x64 px image of 3 channel(s) with `method` hl needs about" in words
    assert "is available; `method` wiener (" in words and "`crop`" in words
    assert D.deconvolve(image, k, "wiener", noise_sigma=0.01).shape == image.shape


@pytest.fixture(scope="module")
def big_capture(tmp_path_factory):
    """A 4000 x 3000 capture (zeros compress to almost nothing) and a 17 px kernel."""
    root = tmp_path_factory.mktemp("big")
    write_exr(root / "capture.exr", {"capture": np.zeros((3000, 4000, 3), np.float32)})
    np.save(root / "k.npy", np.ones((17, 17)))
    return root


def test_a_4000x3000_hl_is_refused_under_a_6_gb_limit_before_reading(big_capture, tmp_path):
    """The must-show: under ``ulimit -v`` 6 GB, where hl died with a MemoryError traceback from
    scipy.fft, it is refused at once, exit 2, naming the estimate (GiB and minutes), the
    memory available and the methods that fit."""

    limit = 'ulimit -v 5859375 && exec "$0" "$@"'  # 6e9 bytes, in KiB; the shell sets it
    argv = ["bash", "-c", limit, sys.executable, "-m", "pacam_render", "deconvolve",
            str(big_capture / "capture.exr"), "--psf", str(big_capture / "k.npy"),
            "--out", str(tmp_path / "d")]  # fmt: skip
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    done = subprocess.run(argv, capture_output=True, text=True, env=env)
    assert done.returncode == 2, done.stderr
    err = done.stderr
    errors = [line for line in err.splitlines() if line.startswith("pacam deconvolve: error:")]
    assert "Traceback" not in err and len(errors) == 1
    assert "deconvolving a 4000x3000 px image of 3 channel(s) with --method hl needs about" in err
    assert "GiB of memory and " in err and " min (its FFT grid is 4050x3072 px)" in err
    assert "is available; --method wiener (" in err and "--crop" in err


def test_a_long_deconvolution_says_its_estimate_before_reading(big_capture, tmp_path, capsys,
                                                               monkeypatch):  # fmt: skip
    import pacam_render.cli.deconvolve as cli

    monkeypatch.setattr(cost, "available_bytes", lambda: 64 * 2**30)
    monkeypatch.setattr(cli, "read_exr", lambda path: (_ for _ in ()).throw(ParameterError("x")))
    argv = ["deconvolve", str(big_capture / "capture.exr"), "--psf", str(big_capture / "k.npy")]
    assert main([*argv, "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert "note: deblurring layer capture (4000x3000 px, 3 channel(s)) with --method hl" in err
    assert " GiB of memory and " in err and "(estimated; 64 GiB available)" in err


def test_a_memory_error_is_one_line(tmp_path, capsys, monkeypatch):
    import pacam_render.restore.restoration as restoration

    write_exr(tmp_path / "capture.exr", {"capture": np.full((24, 32, 3), 0.5)})
    np.save(tmp_path / "k.npy", np.ones((5, 5)))

    def out_of_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(restoration, "deconvolve", out_of_memory)
    argv = ["deconvolve", str(tmp_path / "capture.exr"), "--psf", str(tmp_path / "k.npy")]
    assert main([*argv, "--noise-sigma", "0.01", "--out", str(tmp_path / "d")]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    line = "\npacam deconvolve: error: out of memory: deblurring layer capture with --method hl"
    assert line in err
    assert "estimated," in err and "available when it began" in err


@pytest.mark.parametrize("method, steps", [("hl", 8), ("tv", 12), ("rl", 3), ("pnp", 2)])
def test_the_iterative_methods_show_their_progress(method, steps, monkeypatch):
    if method == "pnp":
        pytest.importorskip("scico")
    import tqdm

    bars = []

    class Bar:
        def __init__(self, **kw):
            self.kw, self.n = kw, 0
            bars.append(self)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def update(self, n=1):
            self.n += n

    monkeypatch.setattr(tqdm, "tqdm", Bar)
    seen = []
    kw = {"iterations": steps} if method in ("rl", "pnp") else {}
    image = np.random.default_rng(0).random((24, 32)) + 0.1
    D.deconvolve(image, np.ones((3, 3)), method, callback=lambda i, x: seen.append(i), **kw)
    (bar,) = bars
    assert bar.n == bar.kw["total"] == steps and seen == list(range(steps))
    assert bar.kw["delay"] == 2.0 and bar.kw["disable"] is None


def test_richardson_lucy_is_scikit_images_to_the_bit():
    from skimage.restoration import richardson_lucy as sk

    rng = np.random.default_rng(1)
    y, k = rng.random((20, 24, 3)), rng.random((5, 3))
    kk = k / k.sum()
    pad = pad_width(k.shape)
    want = []
    for c in range(3):
        yp, keep = taper_pad(y[..., c], pad)
        want.append(sk(yp, kk, num_iter=7, clip=False)[keep])
    assert np.array_equal(D.richardson_lucy(y, k, 7), np.stack(want, axis=-1))
