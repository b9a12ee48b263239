"""Image-sensor model: mean photons per pixel in, noisy digital numbers (DN) out.

Parameters and units follow EMVA 1288 (release 4). One frame, per pixel:

1. ``qe`` (e-/photon): mean photo-electrons = ``qe * photons * g``, where ``g`` is the pixel's
   PRNU gain (fixed pattern, mean 1, standard deviation ``prnu``, log-normal so it stays > 0).
2. plus dark current ``dark_current_e_per_s * exposure_ms / 1000`` (e-);
3. shot noise: the electron count is an exact Poisson draw of that sum, at every count (numpy's
   Poisson sampler is exact, there is no normal approximation). Dark current thus carries its
   own shot noise. Means above ``full_well_e + 40 sqrt(full_well_e) + 100`` e- are drawn at that
   cap: they saturate in step 4 either way (the chance that they would not is below 1e-300);
4. full-well clipping at ``full_well_e`` (e-), applied to the collected charge;
5. read noise, Gaussian with standard deviation ``read_noise_e`` (e-), per frame;
6. DSNU, a per-pixel dark offset (fixed pattern), Gaussian with standard deviation ``dsnu_e``;
7. system gain ``K`` (DN/e-) and black offset ``black_offset_dn`` (DN);
8. ADC: rounding to the nearest integer and clipping to [0, 2**bit_depth - 1] DN.

Saturation therefore comes from the full well or from the ADC, whichever is reached first:
:attr:`SensorModel.saturation_e`. The output is ``uint16`` for ``bit_depth <= 16`` and ``uint32``
above. Subtracting the black offset from it needs a signed or float type first.

Randomness (:mod:`.noise_sources`). The fixed pattern (PRNU, DSNU) belongs to the instance: it
is drawn from the model's ``seed``, once per sensor shape, and reused for every frame, as on a
real sensor. Per-frame noise comes from ``capture(..., seed=...)``. The frame is processed in
fixed blocks of 65536 pixels with one child ``SeedSequence`` per block, on a thread pool: the
same two seeds give a bit-identical frame on any number of cores.

Colour. With ``bayer=None``, every element of the input is one pixel: an (H, W, 3) image is
three independent sensor planes and the output has the input's shape. With ``bayer="RGGB"``
(or another tile), an (H, W, 3) input is first sampled through the colour filter array and the
output is the (H, W) raw mosaic; an (H, W) input is taken as already mosaicked.
:meth:`SensorModel.demosaic` (bilinear) turns a mosaic back into (H, W, 3).

Presets (:mod:`.presets`: ``paper``, the paper's additive Gaussian noise; the prototype's
``grasshopper-icx285`` and its monochrome twin; JSON or TOML files of one's own) are read by
:meth:`SensorModel.from_preset`.

Light levels (:func:`simulate_capture`): a linear render, 1.0 a white diffuse surface, becomes
photons as :mod:`.radiometry` scales it, ``light_level`` photons/px/ms at a reference aperture
area times the exposure and the open area; with ``light_level=None`` the paper's convention
applies instead: 1.0 fills the full well.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError, check_finite, check_integer, check_positive
from . import bayer as _bayer
from .noise_sources import BLOCK_PIXELS, draw_fixed_pattern, frame_seed, poisson_cap, run_blocks
from .presets import (
    FILE_EXTRA_KEYS,
    PRESETS,
    available_presets,
    read_preset_file,
)
from .radiometry import (
    check_image,
    photons_per_unit,
)

_FPN_CACHE_SHAPES = 8


def _number(name: str, value: Any) -> float:
    """Return value as a finite float; reject text, booleans and None with a ParameterError."""
    if isinstance(value, (bool, np.bool_, str, bytes)) or value is None:
        raise ParameterError(f"{name} must be a number, got {value!r}")
    try:
        return check_finite(name, value)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ParameterError):
            raise
        raise ParameterError(f"{name} must be a number, got {value!r}") from None


def _non_negative(name: str, value: Any, unit: str) -> float:
    v = _number(name, value)
    if v < 0:
        raise ParameterError(f"{name} must be >= 0 {unit}, got {value!r}")
    return v


PHYSICAL_RANGES: dict[str, tuple[float, float, str]] = {
    "full_well_e": (1.0, 1e9, "e-"),
    "K": (1e-6, 1e6, "DN/e-"),
    "read_noise_e": (0.0, 1e6, "e-"),
    "dsnu_e": (0.0, 1e6, "e-"),
    "dark_current_e_per_s": (0.0, 1e9, "e-/s"),
}
"""Ranges (lo, hi, unit) that any real sensor lies well inside. Far outside them the chain's
arithmetic overflows or underflows (1 / K**2, float32 noise), and a capture would fail only
after its render; so a model outside them is refused when it is made."""


def _physical(name: str, value: float) -> float:
    lo, hi, unit = PHYSICAL_RANGES[name]
    if not lo <= value <= hi:
        raise ParameterError(
            f"{name} must be in [{lo:g}, {hi:g}] {unit} (a physical sensor's range), got {value!r}"
        )
    return value


@dataclass(frozen=True)
class SensorModel:
    """Photons to DN, with EMVA 1288 parameters (see the module docstring for the chain).

    The defaults are an ideal 16-bit photon counter: qe = 1, shot noise and quantisation only.
    All parameters are validated, against :data:`PHYSICAL_RANGES` too; bad ones raise
    :class:`ParameterError` naming the valid range.

    Attributes
    ----------
    qe
        quantum efficiency, e-/photon, in (0, 1].
    dark_current_e_per_s
        mean dark current, e-/s, in [0, 1e9].
    read_noise_e
        temporal read noise (EMVA sigma_d without dark-current shot noise), e-,
        in [0, 1e6].
    full_well_e
        full-well capacity, e-, in [1, 1e9].
    K
        overall system gain, DN/e-, in [1e-6, 1e6].
    black_offset_dn
        black level added before the ADC, DN, in [0, 2**bit_depth - 1].
    bit_depth
        ADC bits, integer 1..32.
    prnu
        photo-response non-uniformity, std/mean of the pixel gain (0.01 = 1 %), [0, 1].
    dsnu_e
        dark-signal non-uniformity, std of a per-pixel offset, e-, in [0, 1e6].
    bayer
        None, or a 2x2 colour-filter tile ("RGGB", "BGGR", "GRBG", "GBRG").
    shot_noise
        False only for idealised models such as the ``paper`` preset.
    seed
        seed of the fixed pattern (PRNU, DSNU), integer >= 0.
    name
        a label, recorded with captures.
    """

    qe: float = 1.0
    dark_current_e_per_s: float = 0.0
    read_noise_e: float = 0.0
    full_well_e: float = 65535.0
    K: float = 1.0
    black_offset_dn: float = 0.0
    bit_depth: int = 16
    prnu: float = 0.0
    dsnu_e: float = 0.0
    bayer: str | None = None
    shot_noise: bool = True
    seed: int = 0
    name: str = "custom"
    _fpn_cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name, value in self._validated().items():
            object.__setattr__(self, name, value)

    def _validated(self) -> dict[str, Any]:
        qe = _number("qe", self.qe)
        if not 0 < qe <= 1:
            raise ParameterError(f"qe must be in (0, 1] e-/photon, got {self.qe!r}")
        bits = check_integer("bit_depth", self.bit_depth, 1, 32)
        max_dn = float(2**bits - 1)
        offset = _non_negative("black_offset_dn", self.black_offset_dn, "DN")
        if offset > max_dn:
            raise ParameterError(
                f"black_offset_dn must be in [0, {max_dn:g}] DN for bit_depth {bits}, "
                f"got {self.black_offset_dn!r}"
            )
        prnu = _non_negative("prnu", self.prnu, "(fraction)")
        if prnu > 1:
            raise ParameterError(f"prnu must be in [0, 1] (fraction), got {self.prnu!r}")
        if not isinstance(self.shot_noise, (bool, np.bool_)):
            raise ParameterError(f"shot_noise must be true or false, got {self.shot_noise!r}")
        if not isinstance(self.name, str):
            raise ParameterError(f"name must be a string, got {self.name!r}")
        return {
            "qe": qe,
            "dark_current_e_per_s": _physical(
                "dark_current_e_per_s",
                _non_negative("dark_current_e_per_s", self.dark_current_e_per_s, "e-/s"),
            ),
            "read_noise_e": _physical(
                "read_noise_e", _non_negative("read_noise_e", self.read_noise_e, "e-")
            ),
            "full_well_e": _physical(
                "full_well_e",
                check_positive("full_well_e", _number("full_well_e", self.full_well_e)),
            ),
            "K": _physical("K", check_positive("K", _number("K", self.K), "DN/e-")),
            "black_offset_dn": offset,
            "bit_depth": bits,
            "prnu": prnu,
            "dsnu_e": _physical("dsnu_e", _non_negative("dsnu_e", self.dsnu_e, "e-")),
            "bayer": None if self.bayer is None else _bayer.check_pattern(self.bayer),
            "shot_noise": bool(self.shot_noise),
            "seed": check_integer("seed", self.seed, 0, None),
        }

    # ----------------------------------------------------------------- derived quantities
    @property
    def max_dn(self) -> int:
        """Largest ADC output, 2**bit_depth - 1 DN."""
        return 2**self.bit_depth - 1

    @property
    def dtype(self) -> type[np.unsignedinteger]:
        """Output dtype: uint16 up to 16 bits, uint32 above."""
        return np.uint16 if self.bit_depth <= 16 else np.uint32

    @property
    def saturation_e(self) -> float:
        """Saturation capacity, e-: the full well or the ADC top, whichever comes first.

        This is the noise-free value; EMVA 1288 measures it where the temporal variance peaks,
        which noise puts slightly lower.
        """
        return min(self.full_well_e, (self.max_dn - self.black_offset_dn) / self.K)

    @property
    def sigma(self) -> float:
        """Read noise as a fraction of the full well: the paper's sigma on a [0, 1] image."""
        return self.read_noise_e / self.full_well_e

    def temporal_noise_e(self, signal_e: Any, exposure_ms: float | None = None) -> np.ndarray:
        """Temporal noise below saturation, e-: the EMVA 1288 linear model's sigma_y / K.

        ``sqrt(signal_e + dark + read_noise_e**2 + 1 / (12 K**2))`` for mean photo-electrons
        ``signal_e``; without shot noise (``paper``) the signal and dark terms drop out. Divided
        by the electrons of the white level, it is the paper's noise level sigma (Fig. 8).
        """
        sig = check_image("signal_e", signal_e)
        var = np.full(sig.shape, self.read_noise_e**2 + 1.0 / (12.0 * self.K**2))
        if self.shot_noise:
            var += sig + self.dark_electrons(exposure_ms)
        return np.sqrt(var)

    def dark_electrons(self, exposure_ms: float | None) -> float:
        """Mean dark-current electrons over the exposure, e-.

        ``exposure_ms`` may be None only when there is no dark current.
        """
        if exposure_ms is None:
            if self.dark_current_e_per_s > 0:
                raise ParameterError(
                    "exposure_ms is required (>= 0 ms) when dark_current_e_per_s > 0"
                )
            return 0.0
        t = _non_negative("exposure_ms", exposure_ms, "ms")
        return self.dark_current_e_per_s * t * 1e-3

    # ---------------------------------------------------------------------- construction
    @classmethod
    def from_preset(cls, name: str | os.PathLike, **overrides: Any) -> SensorModel:
        """A built-in preset by name, or a user preset file (``.json`` / ``.toml``).

        Keyword overrides replace preset values; ``sigma=`` sets ``read_noise_e`` to
        ``sigma * full_well_e`` (the paper's noise level on a [0, 1] image).
        """
        if isinstance(name, str) and name in PRESETS:
            return _build(dict(PRESETS[name]), overrides, where=f"preset {name!r}")
        if isinstance(name, os.PathLike) or (
            isinstance(name, str) and name.lower().endswith((".json", ".toml"))
        ):
            return cls.from_file(name, **overrides)
        raise ParameterError(
            f"unknown sensor preset {name!r}; built-in presets: "
            f"{', '.join(available_presets())}, or a path to a .json or .toml preset file"
        )

    @classmethod
    def from_file(cls, path: str | os.PathLike, **overrides: Any) -> SensorModel:
        """A user preset from a JSON or TOML file (see the module docstring for its keys)."""
        p = Path(path)
        data = read_preset_file(p)
        base = data.pop("base", None)
        params: dict[str, Any] = {}
        if base is not None:
            if not isinstance(base, str) or base not in PRESETS:
                raise ParameterError(
                    f"preset file {p}: base must be one of {', '.join(available_presets())}, "
                    f"got {base!r}"
                )
            params.update(PRESETS[base])
        params["name"] = p.stem
        data.pop("description", None)
        where = f"preset file {p}"
        allowed = {f.name for f in dataclasses.fields(cls) if f.init} | {"sigma"}
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise ParameterError(
                f"{where}: unknown key(s) {', '.join(unknown)}; valid: "
                f"{', '.join(sorted(allowed | set(FILE_EXTRA_KEYS)))}"
            )
        _apply(params, data, where)
        return _build(params, overrides, where=where)

    def replace(self, **changes: Any) -> SensorModel:
        """A validated copy with some parameters changed (and a fresh fixed-pattern cache)."""
        return _build(self.as_dict(), changes, where="replace()")

    def as_dict(self) -> dict[str, Any]:
        """The parameters as a JSON-serialisable dict; ``SensorModel(**d)`` rebuilds the model."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.init}

    # ----------------------------------------------------------------------- fixed pattern
    def fixed_pattern(self, shape: tuple[int, ...]) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(PRNU gain, DSNU offset in e-) maps for a sensor of this shape, float32 or None.

        Drawn once per shape from ``seed`` and cached, so every frame sees the same pattern.
        """
        key = tuple(int(s) for s in shape)
        hit = self._fpn_cache.get(key)
        if hit is None:
            hit = draw_fixed_pattern(self.seed, self.prnu, self.dsnu_e, key)
            if len(self._fpn_cache) >= _FPN_CACHE_SHAPES:
                self._fpn_cache.pop(next(iter(self._fpn_cache)))
            self._fpn_cache[key] = hit
        return hit

    def capture(
        self,
        photons: np.ndarray,
        *,
        exposure_ms: float | None = None,
        seed: int | np.random.SeedSequence | None = None,
        workers: int | None = None,
    ) -> np.ndarray:
        """One frame: mean photons per pixel over the exposure -> DN (integer array).

        Parameters
        ----------
        photons
            mean photons reaching each pixel during the exposure, before qe; finite and
            >= 0. Any shape without a Bayer filter; (H, W, 3) or (H, W) with one.
        exposure_ms
            exposure time, ms (for the dark current; may be omitted without one).
        seed
            per-frame noise seed (int >= 0 or SeedSequence); None draws fresh entropy.
        workers
            threads to use (default: all cores); the result does not depend on it.

        Returns
        -------
        numpy.ndarray
            DN as ``self.dtype``: the input's shape, or (H, W) for a Bayer model.
        """
        plane = self._sensor_plane(photons)
        dark_e = self.dark_electrons(exposure_ms)
        gain, offset = self.fixed_pattern(plane.shape)
        src = plane.reshape(-1)
        out = np.empty(src.size, dtype=self.dtype)
        n_blocks = max(1, -(-src.size // BLOCK_PIXELS))
        seeds = frame_seed(seed).spawn(n_blocks)
        gain_f = None if gain is None else gain.reshape(-1)
        offset_f = None if offset is None else offset.reshape(-1)

        def block(i: int) -> None:
            sl = slice(i * BLOCK_PIXELS, (i + 1) * BLOCK_PIXELS)
            g = None if gain_f is None else gain_f[sl]
            o = None if offset_f is None else offset_f[sl]
            out[sl] = self._chain(src[sl], dark_e, g, o, seeds[i])

        run_blocks(block, n_blocks, workers)
        return out.reshape(plane.shape)

    def _sensor_plane(self, photons: Any) -> np.ndarray:
        p = np.asarray(photons)
        if p.dtype.kind not in "iuf":
            raise ParameterError(f"photons must be a real numeric array, got dtype {p.dtype}")
        if self.bayer is None:
            return np.ascontiguousarray(p)
        if p.ndim == 3 and p.shape[2] == 3:
            return _bayer.mosaic(p, self.bayer)
        if p.ndim == 2:
            return np.ascontiguousarray(p)
        raise ParameterError(
            f"photons must be (H, W, 3) or an (H, W) mosaic for a Bayer sensor, got {p.shape}"
        )

    def _chain(
        self,
        photons: np.ndarray,
        dark_e: float,
        gain: np.ndarray | None,
        dsnu: np.ndarray | None,
        ss: np.random.SeedSequence,
    ) -> np.ndarray:
        """The per-pixel chain on one block; returns rounded, clipped DN as float64."""
        _check_photons(photons)
        rng = np.random.Generator(np.random.PCG64(ss))
        e = np.multiply(photons, self.qe, dtype=np.float64)
        if gain is not None:
            e *= gain
        if dark_e:
            e += dark_e
        if self.shot_noise:
            np.minimum(e, poisson_cap(self.full_well_e), out=e)
            e = rng.poisson(e).astype(np.float64)
        np.minimum(e, self.full_well_e, out=e)
        if self.read_noise_e:
            z = rng.standard_normal(e.size, dtype=np.float32)
            z *= np.float32(self.read_noise_e)
            e += z
        if dsnu is not None:
            e += dsnu
        e *= self.K
        e += self.black_offset_dn
        np.rint(e, out=e)
        return np.clip(e, 0.0, float(self.max_dn), out=e)

    # ------------------------------------------------------------------- back to light
    def electrons_from_dn(self, dn: np.ndarray, exposure_ms: float | None = None) -> np.ndarray:
        """Signal electrons: (DN - black offset) / K minus the mean dark signal, float64."""
        d = np.asarray(dn, dtype=np.float64)
        return (d - self.black_offset_dn) / self.K - self.dark_electrons(exposure_ms)

    def photons_from_unit(self, image: np.ndarray) -> np.ndarray:
        """Photons for a [0, 1] image where 1.0 fills the full well (the paper's convention)."""
        img = check_image("image", image)
        return img * (self.full_well_e / self.qe)

    def unit_from_dn(self, dn: np.ndarray, exposure_ms: float | None = None) -> np.ndarray:
        """DN back to the [0, 1] scale of :meth:`photons_from_unit`, float64."""
        return self.electrons_from_dn(dn, exposure_ms) / self.full_well_e

    def demosaic(self, mosaic: np.ndarray) -> np.ndarray:
        """Bilinear demosaic of an (H, W) mosaic to (H, W, 3); a copy as is without Bayer."""
        if self.bayer is None:
            return np.array(mosaic)
        return _bayer.demosaic_bilinear(mosaic, self.bayer)

    def linear_from_dn(
        self, dn: np.ndarray, photons_per_unit: float, exposure_ms: float | None = None
    ) -> np.ndarray:
        """Noisy linear image in the render's units: dark-subtracted, demosaicked, float32.

        ``photons_per_unit`` is what :func:`photons_per_unit` returned for the capture.
        """
        ppu = check_positive("photons_per_unit", photons_per_unit, "photons")
        dark_dn = self.black_offset_dn + self.K * self.dark_electrons(exposure_ms)
        # float32 holds every DN exactly up to 24 bits; the demosaic commutes with the affine map
        dtype = np.float32 if self.bit_depth <= 24 else np.float64
        x = self.demosaic(np.asarray(dn, dtype=dtype))
        x -= dtype(dark_dn)
        x *= dtype(1.0 / (self.K * self.qe * ppu))
        return x.astype(np.float32, copy=False)


# ------------------------------------------------------------------------------- helpers
def _apply(params: dict[str, Any], layer: Mapping[str, Any], where: str) -> None:
    """Update params with one layer of settings; ``sigma`` sets read_noise_e = sigma * FW."""
    layer = dict(layer)
    sigma = layer.pop("sigma", None)
    if sigma is not None and "read_noise_e" in layer:
        raise ParameterError(f"{where}: give sigma or read_noise_e, not both")
    params.update(layer)
    if sigma is not None:
        s = _non_negative("sigma", sigma, "(fraction of full well)")
        fw = _number("full_well_e", params.get("full_well_e", SensorModel.full_well_e))
        params["read_noise_e"] = s * fw


def _build(params: dict[str, Any], overrides: Mapping[str, Any], where: str) -> SensorModel:
    """A validated model from base parameters and overrides; unknown keys are an error."""
    allowed = {f.name for f in dataclasses.fields(SensorModel) if f.init}
    unknown = sorted(set(params) - allowed) + sorted(set(overrides) - allowed - {"sigma"})
    if unknown:
        raise ParameterError(
            f"{where}: unknown sensor parameter(s) {', '.join(unknown)}; valid: "
            f"{', '.join(sorted(allowed | {'sigma'}))}"
        )
    params = dict(params)
    try:
        _apply(params, overrides, where)
        return SensorModel(**params)
    except ParameterError as exc:
        if str(exc).startswith(where):
            raise
        raise ParameterError(f"{where}: {exc}") from None


def _check_photons(block: np.ndarray) -> None:
    if block.dtype.kind == "f" and not np.isfinite(block).all():
        raise ParameterError("photons must be finite (>= 0 photons), got NaN or infinity")
    if block.size and block.min() < 0:
        raise ParameterError(f"photons must be >= 0 photons, got {block.min()!r}")


@dataclass(frozen=True)
class SensorCapture:
    """What :func:`simulate_capture` returns."""

    raw_dn: np.ndarray
    """Digital numbers: the render's shape, or (H, W) for a Bayer model."""
    linear: np.ndarray
    """Noisy linear image in the render's units (dark-subtracted, demosaicked), float32."""
    photons_per_unit: float
    """Photons per pixel for 1.0 of the render."""


def simulate_capture(
    linear_image: np.ndarray,
    model: SensorModel,
    *,
    exposure_ms: float,
    seed: int | np.random.SeedSequence | None,
    light_level: float | None = None,
    open_area_mm2: float | None = None,
    reference_area_mm2: float | None = None,
    workers: int | None = None,
) -> SensorCapture:
    """A linear render through the sensor: raw DN and the noisy linear image.

    With ``light_level`` (photons/px/ms at ``reference_area_mm2``), both areas are required.
    With ``light_level=None``, 1.0 of the render fills the full well (the paper's convention,
    for the ``paper`` preset), independent of exposure and aperture; then give no areas.

    Parameters
    ----------
    linear_image : array_like
        The linear render, 1.0 = a white diffuse surface; real, finite and >= 0. Any shape
        without a Bayer filter; (H, W, 3), or an (H, W) mosaic, with one.
    model : SensorModel
        The sensor.
    exposure_ms : float
        Exposure time, ms: scales the photons (with a ``light_level``) and the dark current.
    seed : int, numpy.random.SeedSequence or None
        Per-frame noise seed; None draws fresh entropy.
    light_level : float, optional
        Photons/px/ms from a white diffuse surface with ``reference_area_mm2`` open
        (:data:`DEFAULT_LIGHT_LEVEL` is a typical value).
    open_area_mm2 : float, optional
        Open aperture area, mm^2; required with ``light_level``, forbidden without.
    reference_area_mm2 : float, optional
        Aperture area at which ``light_level`` is given, mm^2; likewise.
    workers : int, optional
        Threads to use (default: all cores); the result does not depend on it.

    Returns
    -------
    SensorCapture
        ``raw_dn`` (DN, ``model.dtype``: the render's shape, or (H, W) for a Bayer model),
        ``linear`` (float32, the noisy image in the render's units: dark-subtracted and
        demosaicked) and ``photons_per_unit`` (photons per pixel for 1.0 of the render).

    Raises
    ------
    ParameterError
        If ``light_level`` comes without both areas, or an area without it; if the light
        level, an area or (with a light level) the exposure is not a finite number > 0; if
        ``exposure_ms`` is negative; or if the image or ``seed`` is invalid.

    Notes
    -----
    photons = linear_image x p, with p = light_level x exposure_ms x open_area_mm2 /
    reference_area_mm2 (:func:`photons_per_unit`), or p = full_well_e / qe without a light
    level. :meth:`SensorModel.capture` turns them into DN, and
    :meth:`SensorModel.linear_from_dn` maps the DN back to the render's units.
    """
    if light_level is None:
        if open_area_mm2 is not None or reference_area_mm2 is not None:
            raise ParameterError(
                "open_area_mm2 and reference_area_mm2 need a light_level (photons/px/ms); "
                "without one, 1.0 of the image fills the full well"
            )
        ppu = model.full_well_e / model.qe
    else:
        if open_area_mm2 is None or reference_area_mm2 is None:
            raise ParameterError("light_level needs open_area_mm2 and reference_area_mm2 (mm^2)")
        ppu = photons_per_unit(light_level, exposure_ms, open_area_mm2, reference_area_mm2)
    photons = check_image("linear_image", linear_image) * ppu
    raw = model.capture(photons, exposure_ms=exposure_ms, seed=seed, workers=workers)
    return SensorCapture(raw, model.linear_from_dn(raw, ppu, exposure_ms), ppu)
