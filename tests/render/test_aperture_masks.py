"""LCoS mask handling: orientation, rasterising, loading, checks and the sampling tables."""

from __future__ import annotations

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.model.optics import LCOS_PITCH_MM
from pacam_render.render.masks import (
    DISPLAY_SHAPE,
    build_tables,
    check_masks,
    disc_mask,
    disc_masks,
    load_masks,
    pixel_centres_mm,
    sample_tables_numpy,
)


def test_pixel_centres_orientation():
    x, y = pixel_centres_mm((4, 6), pitch_mm=1.0)
    # columns run along -x (the image's right), rows along -y (down); centred on the axis
    assert np.allclose(x, [2.5, 1.5, 0.5, -0.5, -1.5, -2.5])
    assert np.allclose(y, [1.5, 0.5, -0.5, -1.5])


def test_disc_mask_area_and_centre():
    pitch = LCOS_PITCH_MM
    r = 60 * pitch
    m = disc_mask((20 * pitch, -10 * pitch), r, shape=(256, 320), supersample=4)
    area = m.sum() * pitch**2
    assert area == pytest.approx(np.pi * r * r, rel=2e-3)
    x, y = pixel_centres_mm(m.shape, pitch)
    cx = (m.sum(axis=0) @ x) / m.sum()
    cy = (m.sum(axis=1) @ y) / m.sum()
    assert cx == pytest.approx(20 * pitch, abs=0.02 * pitch)
    assert cy == pytest.approx(-10 * pitch, abs=0.02 * pitch)
    # +x on the aperture is the left half of the mask image, +y the top half
    assert m[:, :160].sum() > m[:, 160:].sum()
    assert m[128:].sum() > m[:128].sum()
    assert set(np.unique(disc_mask((0, 0), r, shape=(64, 64)))) <= {0.0, 1.0}


def test_disc_masks_stack():
    s = disc_masks([0.0, 0.1], 0.2, shape=(32, 32), pitch_mm=0.02)
    assert s.shape == (2, 32, 32)
    assert np.array_equal(s[0], disc_mask((0, 0), 0.2, (32, 32), 0.02))


def test_load_masks_types(tmp_path):
    u8 = np.zeros((8, 10), np.uint8)
    u8[2, 3] = 255
    u8[4, 5] = 51
    m = load_masks(u8)
    assert m.shape == (1, 8, 10) and m.dtype == np.float32
    assert m[0, 2, 3] == 1.0 and m[0, 4, 5] == pytest.approx(0.2)
    assert load_masks(u8.astype(np.uint16) * 257)[0, 2, 3] == 1.0
    assert load_masks(np.ones((2, 8, 10), bool)).sum() == 160
    assert load_masks([u8, u8]).shape == (2, 8, 10)
    np.save(tmp_path / "m.npy", np.stack([u8, u8, u8]))
    assert load_masks(str(tmp_path / "m.npy")).shape == (3, 8, 10)

    import mitsuba as mi

    from pacam_render.render.backend import select_variant

    select_variant()
    for i in range(2):
        mi.Bitmap(u8[..., None]).write(str(tmp_path / f"p{i}.png"))
    files = f"{tmp_path / 'p0.png'}, {tmp_path / 'p1.png'}"
    m = load_masks(files)
    assert m.shape == (2, 8, 10)
    assert np.allclose(m[1], u8 / 255.0)  # grey level = transmittance, no gamma


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.full((4, 4), 1.5), r"\[0, 1\]"),
        (np.full((4, 4), -0.1), r"\[0, 1\]"),
        (np.full((4, 4), np.nan), "finite"),
        (np.full((4, 4), np.inf), "finite"),
        (np.full((4, 4), 0.5 + 0.5j), "real"),
        (np.full((4, 4), 2, np.int64), r"\[0, 1\]"),
        (np.zeros((2, 2, 2, 2)), "shape"),
        (np.zeros((0, 4, 4)), "empty"),
        ([np.zeros((4, 4)), np.zeros((5, 4))], "same size"),
        ("/nonexistent/mask.npy", "no such file"),
    ],
)
def test_load_masks_rejects(bad, match):
    with pytest.raises(ParameterError, match=match):
        load_masks(bad)


def test_levels_and_compact_stack_round_trip():
    """8- and 16-bit levels read as level / max rounded once to float32 (the table of levels
    against the closed form), and a stack of levels is stored as its 8-bit codes, exactly;
    other transmittances stay float32."""
    from pacam_render.model.masks import MaskStack

    u8 = np.arange(256, dtype=np.uint8).reshape(1, 16, 16)
    assert np.array_equal(load_masks(u8), (u8 / 255.0).astype(np.float32))
    u16 = np.arange(65536, dtype=np.uint16).reshape(1, 256, 256)  # every level
    assert np.array_equal(load_masks(u16), (u16 / 65535.0).astype(np.float32))
    stack = MaskStack(u8)
    codes = stack.compact_array()
    assert codes.dtype == np.uint8 and np.array_equal(codes, u8)
    assert stack.to_json() == stack.to_json()  # compressed once, the same record
    odd = MaskStack(np.full((1, 4, 4), 0.3, np.float32))
    assert odd.compact_array().dtype == np.float32
    assert np.array_equal(load_masks(odd.compact_array()), odd.array)


def test_check_masks():
    pitch = 0.1
    ok = disc_masks([0.0, 0.3], 0.5, shape=(40, 40), pitch_mm=pitch)
    check_masks(ok, lens_radius_mm=0.8, pitch_mm=pitch)
    with_black = np.concatenate([ok, np.zeros((1, 40, 40), np.float32)])
    check_masks(with_black, lens_radius_mm=0.8, pitch_mm=pitch)  # a closed frame is fine
    with pytest.raises(ParameterError, match="all patterns are black"):
        check_masks(np.zeros((3, 40, 40), np.float32), 0.8, pitch)
    with pytest.raises(ParameterError, match=r"pattern\(s\) \[1\].*outside the lens"):
        check_masks(ok, lens_radius_mm=0.7, pitch_mm=pitch)


def test_tables_and_guide_bounds():
    rng = np.random.default_rng(1)
    m = (rng.random((3, 30, 30)) * (rng.random((3, 30, 30)) < 0.3)).astype(np.float32)
    m[0, 5, 3:20] = 0.5  # a long run
    m[1] = 0.0  # a closed pattern
    tb = build_tables(m, pitch_mm=0.05)
    assert tb.n_patterns == 3 and tb.count[1] == 0
    assert tb.area_mm2 == pytest.approx(m.sum(axis=(1, 2)) * 0.05**2, rel=1e-6)
    for k in (0, 2):
        s, n, g0 = int(tb.start[k]), int(tb.count[k]), int(tb.guide_start[k])
        cdf = tb.cdf[s : s + n]
        assert cdf[-1] == 1.0 and np.all(np.diff(cdf) >= 0)
        # the runs tile the open pixels exactly
        assert tb.span_mm[s : s + n].sum() == pytest.approx((m[k] > 0).sum() * 0.05, rel=1e-5)
        u = rng.random(20000).astype(np.float32)
        ans = np.minimum(np.searchsorted(cdf, u, side="right"), n - 1)
        i = np.minimum(np.floor(u * np.float32(n)).astype(int), n - 1)
        g = tb.guide[g0 : g0 + n + 1]
        assert np.all(g[i] <= ans) and np.all(ans <= g[i + 1])


def test_binary_disc_is_a_few_runs():
    m = disc_mask((0.0, 0.0), 145.5 * LCOS_PITCH_MM)[None]
    tb = build_tables(m)
    rows = int(np.any(m[0] > 0, axis=1).sum())
    assert tb.count[0] == rows and 285 < rows < 292  # one run per open row
    assert tb.span_mm.sum() == pytest.approx(m.sum() * LCOS_PITCH_MM, rel=1e-6)


def test_numpy_sampler_follows_transmittance():
    rng = np.random.default_rng(2)
    m = np.zeros((1, 12, 16), np.float32)
    m[0, 3:9, 2:14] = rng.random((6, 12)).astype(np.float32) + 0.05
    pitch = 0.1
    tb = build_tables(m, pitch)
    n = 400_000
    x, y = sample_tables_numpy(tb, 0, rng.random(n), rng.random(n))
    xc, yc = pixel_centres_mm(m.shape[1:], pitch)
    j = np.rint(-(x / pitch) + 16 / 2 - 0.5).astype(int)
    i = np.rint(12 / 2 - 0.5 - y / pitch).astype(int)
    # each sample lies inside the pixel it was drawn from
    assert np.all(np.abs(x - xc[j]) <= pitch / 2 + 1e-9)
    assert np.all(np.abs(y - yc[i]) <= pitch / 2 + 1e-9)
    counts = np.zeros(m.shape[1:])
    np.add.at(counts, (i, j), 1)
    expect = m[0] / m[0].sum() * n
    open_ = expect > 0
    assert counts[~open_].sum() == 0
    chi2 = (((counts - expect) ** 2)[open_] / expect[open_]).sum()
    dof = open_.sum() - 1
    assert chi2 < dof + 5 * np.sqrt(2 * dof)


def test_display_shape():
    assert DISPLAY_SHAPE == (1024, 1280)
