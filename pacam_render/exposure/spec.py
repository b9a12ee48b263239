"""What a capture renders: :class:`CaptureSpec`, checked on construction, and its sensor crop.

Sizes are in px of the capture's sensor, ``max_step_px`` in px of image motion between time
steps; the spec's :meth:`~CaptureSpec.key` hashes everything that changes the image, so a
stopped capture resumes only into the same one.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from ..model.design_file import resolve_design
from ..model.illumination import CURVE_SUFFIXES, parse_relative_illumination
from ..model.modes import mode
from ..render.ray_diffraction import grid_orders
from ..render.samplers import DEFAULT_SAMPLER, check_sampler
from .estimate import check_passes
from .optics.diffraction import check_diffraction

GEOMETRIC_OPTICS = {"relative_illumination": "off", "diffraction": "off"}
"""Geometric radiance through an ideal opening: what the closed-form checks and the studies'
``[render]`` tables assume (a study reads them from here), and
:meth:`CaptureSpec.geometric`'s."""

CAMERA_OPTICS = {"relative_illumination": "cos4", "diffraction": "auto"}
"""The optics of a camera's capture, as a sensor measures it: irradiance (the thin lens's
natural vignetting) and the opening's diffraction wherever a preview measures it at the
capture's noise target (issue 36). A :class:`CaptureSpec`'s defaults, which ``pacam render``
reads (issue 46: the API and the command line render one camera alike), and the regression
images'. This module owns both sets of optics."""


@dataclass(frozen=True)
class CaptureSpec:
    """What to capture. Sizes in px, ``max_step_px`` in px of motion between time steps.

    ``width`` and ``height`` are the sensor's resolution: below the preset's (1280x960 for the
    prototype) the sensor has fewer, larger pixels, and every px quantity (r, a_i, speeds)
    shrinks with it. ``crop`` = (x, y, w, h) renders only that window of the sensor, in its
    pixels (Mitsuba's film crop): the optics stay those of the whole sensor, so a crop of the
    full-resolution sensor is the prototype's camera at its real pixel scale.

    ``spp`` is shared among ``passes`` independent passes (at least 2: their spread measures the
    Monte Carlo error); ``sampler`` is Mitsuba's sample generator (:mod:`~..render.samplers`).

    ``grey`` renders one channel (luminance) with Mitsuba's mono variant
    (:func:`~pacam_render.render.variant.choose_variant`): every image layer is then (H, W)
    instead of (H, W, 3). A capture rendered under ``PACAM_VARIANT=llvm_ad_mono`` is grey too
    (:func:`~pacam_render.exposure.direct.render_capture` records it so).
    """

    scene: str = "train"
    mode: str = "coded"
    width: int = 320
    height: int = 240
    spp: int = 64
    seed: int = 0
    max_step_px: float = 0.5
    per_pattern: bool = False
    preset: str = "prototype"
    cover_px_per_ms: float | None = None
    crop: tuple[int, int, int, int] | None = None
    f_number: float | None = None
    r_px: float | None = None
    object_depth_mm: float | None = None
    schedule: str | None = None
    passes: int = 2
    sampler: str = DEFAULT_SAMPLER
    design: str | None = None
    """A camera design to use instead of ``preset``: a design file (``.toml``), a capture or
    PSF JSON, or a legacy schedule.json (:func:`~pacam_render.model.design_file.resolve_design`)."""
    grey: bool = False
    """Render one channel (luminance) with a mono variant; see the class docstring."""
    relative_illumination: str = CAMERA_OPTICS["relative_illumination"]
    """The sensor's relative illumination: ``cos4`` (default, :data:`CAMERA_OPTICS`), ``off``
    (radiance, as ``thinlens``; :meth:`geometric`) or a curve file
    (:mod:`~pacam_render.model.illumination`). Not ``off``: the capture records its map as the
    ``relative_illumination`` layer, and readers flat-field with it."""
    diffraction: str = CAMERA_OPTICS["diffraction"]
    """The openings' diffraction: ``auto`` (default, :data:`CAMERA_OPTICS`: on unless its
    effect is below the noise target; :mod:`~pacam_render.exposure.optics.diffraction`), ``on`` or
    ``off`` (:meth:`geometric`). Disc
    openings diffract in the rays, a bitmap schedule's patterns after the render; it is in the
    key, since the passes differ."""

    lcos_contrast: float | None = None
    """The LCoS's contrast ratio C >= 1: "off" pixels pass 1/C of the light (None: ideal, no
    datasheet value is known for the prototype's display). Disc schedules on the LCoS only
    (normal, coded, short); C = 1 is no coding at all: the full aperture."""

    lcos_fill_factor: float | None = None
    """The LCoS pixels' linear fill factor f in (0, 1] (None: 1, ideal): the pixel grid
    diffracts (1 - f^2 of the passed light) into ghost orders m at m lambda D / pitch, rendered
    with the opening's diffraction (it needs ``diffraction`` on), and the display passes f^2."""

    lcos_switching_ms: float | None = None
    """The LCoS's switching time, ms (None: 0, instant): in the first t of each pattern's
    window the pixels turn linearly from the previous pattern (coded captures of discrete disc
    schedules)."""

    @classmethod
    def geometric(cls, **fields) -> CaptureSpec:
        """A spec with geometric radiance through an ideal opening (:data:`GEOMETRIC_OPTICS`)
        unless ``fields`` give the optics: what closed-form checks and Mitsuba's ``thinlens``
        see.

        Examples
        --------
        >>> s = CaptureSpec.geometric(scene="train", mode="coded")
        >>> (s.relative_illumination, s.diffraction), CaptureSpec().diffraction
        (('off', 'off'), 'auto')
        """
        return cls(**{**GEOMETRIC_OPTICS, **fields})

    def __post_init__(self) -> None:
        if not isinstance(self.grey, (bool, np.bool_)):
            raise ParameterError(f"grey must be true or false, got {self.grey!r}")
        object.__setattr__(self, "grey", bool(self.grey))
        ri = parse_relative_illumination(self.relative_illumination)  # a bad file: named here
        object.__setattr__(self, "relative_illumination", ri.source)
        mode(self.mode)  # raises, listing the valid modes
        check_diffraction(self.diffraction)
        if self.lcos_fill_factor is not None:
            grid_orders(self.lcos_fill_factor)  # (0, 1], named
            if self.diffraction != "on":
                raise ParameterError(
                    "lcos_fill_factor: the grid's orders are diffraction, rendered with the "
                    f"opening's; give diffraction on (got {self.diffraction!r})"
                )
        if self.lcos_switching_ms is not None:
            t = check_finite("lcos_switching_ms", self.lcos_switching_ms)
            if t < 0:
                raise ParameterError(f"lcos_switching_ms must be >= 0 ms, got {t!r}")
        if self.lcos_contrast is not None:
            c = check_positive("lcos_contrast", self.lcos_contrast)
            if c < 1.0:
                raise ParameterError(
                    f"lcos_contrast must be >= 1 (1: the full aperture, no coding), got {c!r}"
                )
        if self.crop is not None:
            object.__setattr__(self, "crop", check_crop(self.crop, self.width, self.height))
        for k, lo in (("width", 2), ("height", 2), ("spp", 1)):
            v = getattr(self, k)
            if not isinstance(v, (int, np.integer)) or v < lo:
                raise ParameterError(f"{k} must be an integer >= {lo}, got {v!r}")
        if not isinstance(self.seed, (int, np.integer)) or not 0 <= self.seed < 2**31:
            raise ParameterError(f"seed must be an integer in [0, 2^31), got {self.seed!r}")
        check_positive("max_step_px", self.max_step_px, "px")
        check_passes(self.passes)
        check_sampler(self.sampler)
        if self.cover_px_per_ms is not None:
            check_positive("cover_px_per_ms", self.cover_px_per_ms, "px/ms")
        if self.object_depth_mm is not None:
            check_positive("object_depth_mm", self.object_depth_mm, "mm")
        if (self.f_number is not None or self.r_px is not None) and self.cover_px_per_ms is None:
            raise ParameterError(
                "f_number and r_px size a covering design: they need cover_px_per_ms"
            )
        if self.schedule is not None and self.cover_px_per_ms is not None:
            raise ParameterError(
                "give cover_px_per_ms or `schedule`, not both: each sets the design"
            )
        if self.design is not None and self.schedule is not None:
            raise ParameterError("give `design` or `schedule`, not both: each sets the design")

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) of the rendered image, px: the crop's, or the whole sensor's."""
        return (self.crop[2], self.crop[3]) if self.crop else (self.width, self.height)

    def key(self, design_digest: str | None = None) -> str:
        """A hash of everything that changes the image (for resuming).

        Parameters
        ----------
        design_digest : str, optional
            The digest of ``design`` as already read (a capture's plan has it); None reads it.

        Returns
        -------
        str
            The first 16 hex digits of the SHA-256 of the spec's fields as sorted JSON, and of
            the contents of the schedule file and relative-illumination curve it names, or the
            digest of its design (a file rewritten in place is another capture).
        """
        fields = asdict(self)
        if self.diffraction == "off":  # the key it had before this field; on and auto
            del fields["diffraction"]  # can put it in the rays, so their passes differ
        for key in ("lcos_contrast", "lcos_fill_factor", "lcos_switching_ms"):
            if fields[key] is None:  # ideal: the key it had before this field
                del fields[key]
        if not self.grey:  # so that a colour capture keeps the key it had before `grey`
            del fields["grey"]
        if self.relative_illumination == "off":  # and the key it had before this field
            del fields["relative_illumination"]
        h = hashlib.sha256(json.dumps(fields, sort_keys=True).encode())
        if Path(self.relative_illumination).suffix.lower() in CURVE_SUFFIXES:
            h.update(Path(self.relative_illumination).read_bytes())  # a curve edited in place
        if self.schedule is not None and Path(self.schedule).is_file():
            h.update(Path(self.schedule).read_bytes())
        if self.design is not None and design_digest is None:
            design_digest = resolve_design(self.design).digest()
        if self.design is not None:
            h.update(design_digest.encode())
        return h.hexdigest()[:16]


def check_crop(crop, width: int, height: int) -> tuple[int, int, int, int]:
    """(x, y, w, h) as ints inside a width x height sensor, or ParameterError."""
    try:
        x, y, w, h = (int(v) for v in crop)
        ok = all(int(v) == v for v in crop)
    except (TypeError, ValueError):
        ok = False
    if not ok or w < 2 or h < 2 or x < 0 or y < 0 or x + w > width or y + h > height:
        raise ParameterError(
            f"`crop` must be X,Y,W,H: integers with W, H >= 2 and the window inside the "
            f"{width}x{height} sensor (X + W <= {width}, Y + H <= {height}), got {crop!r}"
        )
    return x, y, w, h


def parse_crop(text: str) -> tuple[int, int, int, int]:
    """``"X,Y,W,H"`` (the ``--crop`` flag) as four ints, or ParameterError."""
    parts = text.split(",")
    try:
        if len(parts) != 4:
            raise ValueError
        return tuple(int(p) for p in parts)  # type: ignore[return-value]
    except ValueError:
        raise ParameterError(f"`crop` must be X,Y,W,H (four integers), got {text!r}") from None
