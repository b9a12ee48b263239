"""The analytic camera model: one object holding a design and every quantity it implies.

Inputs are what a camera engineer sets (film, field of view, clear aperture, opening, focus,
exposure, pattern count); every paper quantity of Sections 2.1-2.3 is derived from them, in mm,
ms and px. The ``prototype`` preset follows Table 1 and Section 4 of the paper.

Modelling decision (documented in the report): as in the paper's Fig. 3, the LCoS is the stop of
a thin lens, so an opening of n display pixels has radius n x 13.62 um. F-numbers follow the
paper's own scale, N = N_min R_max / R (F2.8 at the full 512-px disc, F9.85 at 145.5 px).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from ..errors import ParameterError, check_positive
from . import optics, paper
from . import schedule as sch
from .masks import MaskStack
from .schedule_fit import schedule_figures

MIN_OPENING_LCOS_PX = 1.0
"""Smallest displayable opening radius, LCoS pixels."""
MIN_FOCUS_MM = 100.0
"""Closest focus of the prototype's 25 mm primary lens (estimate), mm; also the closest object
depth the thin-lens model is used for."""
MIN_EXPOSURE_MS = 0.01
"""Shortest exposure, ms: 10 us, the shortest shutter of machine-vision sensors such as the
Grasshopper's ICX285."""
MAX_EXPOSURE_MS = 1e5
"""Longest exposure modelled, ms (100 s); far longer ones overflow the schedule's 1/T^2."""


def check_exposure(exposure_ms: float) -> float:
    """``exposure_ms`` if within [:data:`MIN_EXPOSURE_MS`, :data:`MAX_EXPOSURE_MS`]."""
    v = check_positive("exposure_ms", exposure_ms, "ms")
    if v < MIN_EXPOSURE_MS:
        raise ParameterError(
            f"exposure_ms must be >= {MIN_EXPOSURE_MS:g} ms (the sensor's shortest shutter), "
            f"got {exposure_ms!r}"
        )
    if v > MAX_EXPOSURE_MS:
        raise ParameterError(
            f"exposure_ms must be <= {MAX_EXPOSURE_MS:g} ms (the longest exposure modelled), "
            f"got {exposure_ms!r}"
        )
    return v


@dataclass(frozen=True)
class CameraDesign:
    """A programmable-aperture camera focused for one object depth. Lengths mm, times ms."""

    width_px: int = paper.WIDTH_PX
    height_px: int = paper.HEIGHT_PX
    fov_deg: float = paper.FOV_DEG
    R_max_mm: float = optics.lcos_px_to_mm(paper.LCOS_DISC_PX)
    R_mm: float = optics.lcos_px_to_mm(paper.OPENING_LCOS_PX)
    F_min: float = paper.F_MIN
    focus_distance_mm: float = 751.6
    object_depth_mm: float = paper.OBJECT_DEPTH_MM
    exposure_ms: float = paper.EXPOSURE_MS
    n_patterns: int = paper.N_PATTERNS
    pixel_pitch_mm: float = paper.PIXEL_PITCH_MM
    lcos_pitch_mm: float = optics.LCOS_PITCH_MM
    pattern_centres_mm: tuple[tuple[float, float], ...] | None = None
    """A designed schedule (``pacam optimize``): pattern k's opening centre (x, y) in mm, x to
    the image's right and y downwards (the LCoS bitmaps' orientation); the opening keeps the
    radius R. None: the parabola of Eq. 11."""
    pattern_masks: MaskStack | None = None
    """A bitmap schedule: the LCoS shows pattern k of this stack during window k (see
    :mod:`pacam_render.model.masks`); R is then the radius of a disc of the patterns' mean open
    area, which the still modes open. None: discs of radius R."""
    lcos_rate_fps: float = paper.LCOS_RATE_FPS
    """Patterns the LCoS can show per second: a coded exposure shows at most
    floor(rate x 2T) (:meth:`check_lcos_rate`)."""
    sensor_preset: str | None = None
    """The image sensor's noise preset (:mod:`pacam_render.sensor.model`), or None."""
    name: str = "custom"
    quoted_a_i_px_per_ms2: float | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        for k in ("width_px", "height_px"):
            if int(getattr(self, k)) != getattr(self, k) or getattr(self, k) < 1:
                raise ParameterError(f"{k} must be a positive integer, got {getattr(self, k)!r}")
        optics.focal_length_px(self.fov_deg, self.width_px)
        if isinstance(self.pattern_masks, MaskStack):  # before R_mm: black masks give R = 0
            self.pattern_masks.check_open("pattern_masks")
        for k in ("R_max_mm", "R_mm", "F_min", "focus_distance_mm", "object_depth_mm"):
            check_positive(k, getattr(self, k))
        check_positive("exposure_ms", self.exposure_ms, "ms")
        check_positive("pixel_pitch_mm", self.pixel_pitch_mm, "mm")
        check_positive("lcos_pitch_mm", self.lcos_pitch_mm, "mm")
        sch.check_design_patterns(self.n_patterns)
        self._check_physical_limits()
        check_positive("lcos_rate_fps", self.lcos_rate_fps, "patterns/s")
        if self.pattern_centres_mm is not None:
            self._check_centres()
        if self.pattern_masks is not None:
            self._check_masks()
        if self.R_mm > self.R_max_mm:
            raise ParameterError(
                f"R_mm must be in (0, R_max_mm = {self.R_max_mm:g}] mm: the opening must fit "
                f"inside the lens, got {self.R_mm!r}"
            )

    def _check_physical_limits(self) -> None:
        """Depths, openings and exposures a real camera of this kind can have."""
        for k in ("object_depth_mm", "focus_distance_mm"):
            if getattr(self, k) < MIN_FOCUS_MM:
                raise ParameterError(
                    f"{k} must be >= {MIN_FOCUS_MM:g} mm (the lens's closest focus; the "
                    f"thin-lens model is not used closer), got {getattr(self, k)!r}"
                )
        opening_px = self.R_mm / self.lcos_pitch_mm
        if opening_px < MIN_OPENING_LCOS_PX:
            raise ParameterError(
                f"R_mm must be >= {MIN_OPENING_LCOS_PX:g} LCoS px = "
                f"{MIN_OPENING_LCOS_PX * self.lcos_pitch_mm:.4g} mm (the display cannot show a "
                f"smaller opening), got {self.R_mm!r} mm = {opening_px:.3g} LCoS px"
            )
        check_exposure(self.exposure_ms)

    def _check_centres(self) -> None:
        """A designed schedule: one finite centre per pattern, every opening inside the lens."""
        try:
            c = np.array(self.pattern_centres_mm, dtype=float)
        except (TypeError, ValueError):
            c = np.zeros((0, 0))
        if c.shape != (self.n_patterns, 2) or not np.all(np.isfinite(c)):
            raise ParameterError(
                f"pattern_centres_mm must be n_patterns = {self.n_patterns} finite (x, y) pairs "
                f"in mm, got {self.pattern_centres_mm!r}"
            )
        reach = np.hypot(c[:, 0], c[:, 1]) + min(self.R_mm, self.R_max_mm)
        bad = np.flatnonzero(reach > self.R_max_mm * (1 + 1e-9))
        if bad.size:
            k = int(bad[0])
            raise ParameterError(
                f"pattern_centres_mm[{k}] = ({c[k, 0]:g}, {c[k, 1]:g}) mm puts the opening "
                f"outside the lens: |centre| + R = {reach[k]:.6g} mm > R_max = "
                f"{self.R_max_mm:g} mm"
            )
        object.__setattr__(self, "pattern_centres_mm", tuple(map(tuple, c.tolist())))

    def _check_masks(self) -> None:
        """A bitmap schedule: a MaskStack of n_patterns patterns, open only inside the lens."""
        m = self.pattern_masks
        if not isinstance(m, MaskStack):
            raise ParameterError(
                f"pattern_masks must be a MaskStack (pacam_render.model.masks), got "
                f"{type(m).__name__}"
            )
        if self.pattern_centres_mm is not None:
            raise ParameterError(
                "give pattern_centres_mm or pattern_masks, not both: each is the schedule"
            )
        if m.n_patterns != self.n_patterns:
            raise ParameterError(
                f"pattern_masks holds {m.n_patterns} patterns, but n_patterns = "
                f"{self.n_patterns}: they must agree"
            )
        m.check_inside(self.R_max_mm)

    def check_lcos_rate(self) -> None:
        """Raise unless the LCoS can show n_patterns in the exposure at ``lcos_rate_fps``."""
        top = sch.max_patterns(self.exposure_ms, self.lcos_rate_fps)
        if self.n_patterns > top:
            raise ParameterError(
                f"n_patterns = {self.n_patterns} in exposure_ms = {self.exposure_ms:g} needs "
                f"{1000.0 * self.n_patterns / self.exposure_ms:.4g} patterns/s, more than the "
                f"LCoS's lcos_rate_fps = {self.lcos_rate_fps:g} (at most {top} patterns): "
                "lengthen the exposure, show fewer patterns or raise lcos_rate_fps"
            )

    @property
    def designed(self) -> bool:
        """The camera shows a designed schedule (centres or bitmaps), not the parabola."""
        return self.pattern_centres_mm is not None or self.pattern_masks is not None

    @property
    def schedule_kind(self) -> str:
        """``parabolic`` (Eq. 11), ``centres`` (discs of radius R) or ``bitmap``."""
        if self.pattern_masks is not None:
            return "bitmap"
        return "parabolic" if self.pattern_centres_mm is None else "centres"

    def pattern_centres_xy_mm(self) -> np.ndarray:
        """Each pattern's opening centre (x right, y down), mm, shape (n, 2): the designed
        schedule's, a bitmap's transmittance-weighted centroid (NaN for a black pattern), or
        the parabola's (Eq. 11 at the windows' mid-times, y = 0)."""
        if self.pattern_masks is not None:
            return self.pattern_masks.centroids_xy_mm()
        if self.pattern_centres_mm is not None:
            return np.array(self.pattern_centres_mm, dtype=float)
        x = sch.pattern_centres_mm(self.R_max_mm, self.R_mm, self.T_ms, self.n_patterns)
        return np.stack([x, np.zeros_like(x)], axis=1)

    @property
    def pattern_rate_fps(self) -> float:
        """Patterns shown per second, n / 2T (the paper's prototype: 16 in 45 ms)."""
        return 1000.0 * self.n_patterns / self.exposure_ms

    # --- Section 2.1: projection -------------------------------------------------------------
    @property
    def T_ms(self) -> float:
        """Half the exposure (the paper's exposure is 2T), ms."""
        return 0.5 * self.exposure_ms

    @property
    def focal_length_px(self) -> float:
        """Sensor distance Z_p in pixels, (W/2) / tan(fov/2)."""
        return optics.focal_length_px(self.fov_deg, self.width_px)

    @property
    def Z_p_mm(self) -> float:
        """Sensor distance Z_p (Eqs. 7, 9), mm: focal_length_px x pixel pitch."""
        return self.focal_length_px * self.pixel_pitch_mm

    @property
    def lens_focal_length_mm(self) -> float:
        """Thin-lens f with the sensor at Z_p focused at Z_f: 1/f = 1/Z_f + 1/Z_p (Eq. 7), mm."""
        return 1.0 / (1.0 / self.focus_distance_mm + 1.0 / self.Z_p_mm)

    @property
    def alpha(self) -> float:
        """alpha = -Z_p / Z (Eq. 3), dimensionless."""
        return optics.alpha(self.object_depth_mm, self.Z_p_mm)

    @property
    def alpha_px_per_mm(self) -> float:
        """alpha in image px per scene mm at the object depth."""
        return -self.focal_length_px / self.object_depth_mm

    @property
    def beta(self) -> float:
        """beta (Eq. 9) with the sensor at Z_p, dimensionless (mm of image per mm)."""
        return optics.beta(self.Z_p_mm, self.lens_focal_length_mm, self.object_depth_mm)

    @property
    def beta_px_per_mm(self) -> float:
        """Image shift per mm of aperture offset, px/mm (signed; < 0 beyond the focal plane)."""
        return optics.beta_px_per_mm(
            self.object_depth_mm, self.focus_distance_mm, self.fov_deg, self.width_px
        )

    # --- Section 2.2: static PSF -------------------------------------------------------------
    @property
    def r_px(self) -> float:
        """Static (defocus) PSF radius r = |beta| R (Eq. 12), px."""
        return optics.defocus_radius_px(self.beta_px_per_mm, self.R_mm)

    @property
    def F_number(self) -> float:
        """F-number of the opening on the paper's scale, N_min R_max / R."""
        return self.F_min * self.R_max_mm / self.R_mm

    @property
    def f_number_focal_mm(self) -> float:
        """Focal length that the F-number scale implies at the aperture plane, 2 R N, mm."""
        return 2.0 * self.R_mm * self.F_number

    @property
    def open_area_mm2(self) -> float:
        """Area of the opening, mm^2 (light scales with it)."""
        return math.pi * self.R_mm**2

    # --- Section 2.3: aperture motion --------------------------------------------------------
    @property
    def delta_X_a_mm(self) -> float:
        """Aperture travel Delta X_a = 2 (R_max - R) (Eq. 15), mm."""
        return sch.aperture_travel_mm(self.R_max_mm, self.R_mm)

    @property
    def a_a_mm_per_ms2(self) -> float:
        """Aperture acceleration a_a = 4 (R_max - R) / T^2 (Eq. 17), mm/ms^2."""
        return sch.aperture_acceleration(self.R_max_mm, self.R_mm, self.T_ms)

    @property
    def a_i_px_per_ms2(self) -> float:
        """Image acceleration a_i = beta a_a (Eq. 18), px/ms^2, signed like beta."""
        return sch.image_acceleration(self.beta_px_per_mm, self.R_max_mm, self.R_mm, self.T_ms)

    @property
    def velocity_range_px_per_ms(self) -> float:
        """Motion-invariant speed range |s| <= |a_i| T, px/ms."""
        return sch.velocity_range(self.a_i_px_per_ms2, self.T_ms)

    def pattern_table(self) -> list[dict]:
        """The n-pattern schedule: window, centre (mm, LCoS px) and upright-image offset (px)."""
        edges = sch.pattern_edges_ms(self.T_ms, self.n_patterns)
        centres = self.pattern_centres_xy_mm()[:, 0]
        rows = []
        for k, c in enumerate(centres):
            rows.append(
                {
                    "k": k,
                    "t_start_ms": float(edges[k]),
                    "t_end_ms": float(edges[k + 1]),
                    "centre_mm": float(c),
                    "centre_lcos_px": float(c / self.lcos_pitch_mm),
                    "image_offset_px": optics.aperture_mm_to_image_px(c, self.beta_px_per_mm),
                }
            )
        return rows

    def aperture_centre_mm(self, t_ms) -> np.ndarray:
        """Continuous aperture trajectory X_a(t) (Eq. 11), mm."""
        return sch.aperture_centre_mm(t_ms, self.R_max_mm, self.R_mm, self.T_ms)

    def require_parallax(self) -> None:
        """Coded capture needs beta != 0: an in-focus object gets no motion coding."""
        if self.beta_px_per_mm == 0.0:
            raise ParameterError(
                "focus_distance_mm equals object_depth_mm: beta = 0, so moving the aperture "
                "moves nothing (no parallax, no coding); defocus the lens (r_px > 0)"
            )

    def summary(self) -> dict:
        """Every derived quantity, JSON-ready."""
        out = {
            "preset": self.name,
            "r_px": self.r_px,
            "beta_px_per_mm": self.beta_px_per_mm,
            "a_i_px_per_ms2": self.a_i_px_per_ms2,
            "exposure_ms": self.exposure_ms,
            "T_ms": self.T_ms,
            "R_mm": self.R_mm,
            "R_max_mm": self.R_max_mm,
            "R_lcos_px": self.R_mm / self.lcos_pitch_mm,
            "R_max_lcos_px": self.R_max_mm / self.lcos_pitch_mm,
            "F_number": self.F_number,
            "F_min": self.F_min,
            "focus_distance_mm": self.focus_distance_mm,
            "object_depth_mm": self.object_depth_mm,
            "fov_deg": self.fov_deg,
            "width_px": self.width_px,
            "height_px": self.height_px,
            "velocity_range_px_per_ms": self.velocity_range_px_per_ms,
            "alpha": self.alpha,
            "alpha_px_per_mm": self.alpha_px_per_mm,
            "beta": self.beta,
            "Z_p_mm": self.Z_p_mm,
            "focal_length_px": self.focal_length_px,
            "lens_focal_length_mm": self.lens_focal_length_mm,
            "f_number_focal_mm": self.f_number_focal_mm,
            "delta_X_a_mm": self.delta_X_a_mm,
            "a_a_mm_per_ms2": self.a_a_mm_per_ms2,
            "n_patterns": self.n_patterns,
            "open_area_mm2": self.open_area_mm2,
            "schedule": "parabola" if not self.designed else "designed",
            "schedule_kind": self.schedule_kind,
            "lcos_rate_fps": self.lcos_rate_fps,
            "design_digest": self.digest(),
        }
        out.update(self._schedule_summary())
        if self.pattern_centres_mm is not None:
            out["pattern_centres_mm"] = [list(c) for c in self.pattern_centres_mm]
        if self.sensor_preset is not None:
            out["sensor_preset"] = self.sensor_preset
        return out

    def _schedule_summary(self) -> dict:
        """The schedule's own figures (:func:`~.schedule_fit.schedule_figures`): each
        pattern's centre and open fraction, and for a designed schedule a_i and the invariant
        range fitted to its image trajectory, which replace Eq. 18's (the parabola's at this
        opening, kept as ``a_i_eq18_px_per_ms2``)."""

        fig = schedule_figures(self)
        out = {
            "pattern_centres_xy_mm": fig["pattern_centres_mm"],
            "open_fraction": fig["open_fraction"],
            "fit_rms_residual_px": fig["fit_rms_residual_px"],
            "a_i_source": "Eq. 18" if not self.designed else fig["fit_method"],
        }
        if self.designed:
            out["a_i_eq18_px_per_ms2"] = self.a_i_px_per_ms2
            out["a_i_px_per_ms2"] = fig["a_i_fitted_px_per_ms2"]
            out["velocity_range_px_per_ms"] = fig["velocity_range_fitted_px_per_ms"]
            out["velocity_centre_px_per_ms"] = fig["velocity_centre_fitted_px_per_ms"]
            if fig["fit_undefined_reason"]:
                out["fit_undefined_reason"] = fig["fit_undefined_reason"]
        return out

    def with_(self, **changes) -> CameraDesign:
        """A copy with some inputs changed (derived quantities follow)."""
        return replace(self, **changes)

    def inputs(self) -> dict:
        """The constructor arguments, JSON-ready (round-trips through :meth:`from_inputs`):
        a bitmap schedule's patterns are stored whole (:meth:`MaskStack.to_json`)."""
        return self._inputs(whole_masks=True)

    def _inputs(self, whole_masks: bool) -> dict:
        out = asdict(self)
        if self.pattern_masks is not None:
            m = self.pattern_masks
            out["pattern_masks"] = m.to_json() if whole_masks else m.digest
        if self.pattern_centres_mm is not None:
            out["pattern_centres_mm"] = [list(c) for c in self.pattern_centres_mm]
        return out

    def digest(self) -> str:
        """A hash of everything that makes this camera (the name aside): equal digests, equal
        cameras. The first 16 hex digits of SHA-256 over the sorted inputs, the bitmaps by
        their own digest."""
        d = self._inputs(whole_masks=False)
        d.pop("name")
        d.pop("quoted_a_i_px_per_ms2")
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]

    @classmethod
    def from_inputs(cls, inputs: dict) -> CameraDesign:
        """Rebuild a design from :meth:`inputs` (e.g. a capture's JSON)."""
        known = {f.name for f in fields(cls)}
        unknown = set(inputs) - known
        if unknown:
            raise ParameterError(
                f"unknown camera parameters {sorted(unknown)}; valid: {sorted(known)}"
            )
        kw = dict(inputs)
        if isinstance(kw.get("pattern_masks"), dict):
            kw["pattern_masks"] = MaskStack.from_json(kw["pattern_masks"])
        if isinstance(kw.get("pattern_centres_mm"), list):
            kw["pattern_centres_mm"] = tuple(tuple(c) for c in kw["pattern_centres_mm"])
        return cls(**kw)


def prototype(
    object_depth_mm: float = paper.OBJECT_DEPTH_MM,
    r_px: float = paper.STATIC_R_PX,
    side: str = "far",
) -> CameraDesign:
    """The paper's prototype: Table 1 and Section 4, with focus derived from r = 2 px at 500 mm.

    The focus distance is not published; it follows from r = |beta| R. ``side="far"`` focuses
    behind the objects (beta < 0, the sign of Eq. 12's r = -beta R).
    """
    base = CameraDesign(name="prototype", quoted_a_i_px_per_ms2=0.089)
    Zf = optics.focus_for_defocus_mm(
        object_depth_mm, r_px, base.R_mm, base.fov_deg, base.width_px, side
    )
    return base.with_(focus_distance_mm=Zf, object_depth_mm=object_depth_mm)


PRESETS = {"prototype": prototype}
"""Camera presets by name: the paper's prototype (:func:`prototype`)."""


def preset(name: str, **options) -> CameraDesign:
    """A named camera design; ``options`` go to the preset's factory (e.g. ``object_depth_mm``).

    Parameters
    ----------
    name : str
        A key of :data:`PRESETS`.
    **options
        Keyword arguments of the factory, e.g. ``prototype(object_depth_mm, r_px, side)``.

    Returns
    -------
    CameraDesign

    Examples
    --------
    The paper's prototype: r = 2 px of defocus buys invariance for |s| <= |a_i| T.

    >>> d = preset("prototype")
    >>> round(d.r_px, 3), round(d.velocity_range_px_per_ms, 3), d.n_patterns, d.exposure_ms
    (2.0, 0.896, 16, 45.0)
    """
    if name not in PRESETS:
        raise ParameterError(f"unknown preset {name!r}; valid: {', '.join(sorted(PRESETS))}")
    return PRESETS[name](**options)
