"""Mitsuba 3 sensor ``programmable_aperture``: a thin lens with a time-varying aperture.

The camera of Sonoda, Nagahara and Taniguchi (2014): a thin lens whose stop is an LCoS display
that shows ``n_patterns`` aperture patterns, each for an equal share of the exposure. Each ray's
time selects its pattern. With ``schedule="static"`` and ``aperture_radius == lens_radius`` it is
exactly Mitsuba's ``thinlens`` (same rays for the same samples).

Units
-----
Scene lengths in mm, times in ms (the ray time runs over [shutter_open, shutter_close]),
image quantities in px, angles in degrees.

Parameters
----------
==================== ======================================================================
``fov``              field of view (deg), as in ``thinlens`` (``fov_axis``, ``focal_length``
                     work too)
``focus_distance``   distance to the plane in focus, mm (default: ``far_clip``, as thinlens)
``lens_radius``      R_max, the clear aperture of the lens, mm (required)
``aperture_radius``  R, the radius of the disc opening, mm (default ``lens_radius``)
``shutter_open``,    the exposure, ms; the paper's time is t = time - (open + close)/2 and
``shutter_close``    T = (close - open)/2
``n_patterns``       number of patterns shown during the exposure (default 16)
``schedule``         ``static`` | ``parabolic`` | ``centres`` | ``bitmap`` | ``flutter`` |
                     ``camera_parabolic`` (default ``static``)
``continuous``       evaluate the parabola at each ray's time (the N -> infinity limit)
                     instead of per pattern; default false, true for ``camera_parabolic``
``centres``          ``centres`` schedule: N centres (mm), string ``"x y; x y; ..."`` or
                     ``"x; x; ..."`` (y = 0), or a Dr.Jit array/tensor of shape (N,) or (N, 2)
``masks``            ``bitmap`` schedule: Dr.Jit tensor (N, H, W) / Bitmap of transmittances
``mask_file``        ``bitmap`` schedule, for XML: a ``.npy`` stack or comma-separated images
``mask_pitch``       display pixel pitch, mm (default 0.01362, the prototype's LCoS)
``flutter_code``     ``flutter`` schedule: a 0/1 string, one chop per character (default:
                     Raskar et al. 2006's 52-chop code)
``camera_acceleration`` ``camera_parabolic``: a_c, mm/ms^2, or instead
``image_acceleration``  a_i of objects at ``focus_distance``, px/ms^2 (a_c = a_i Z_f / f_px)
``reference_exposure``  E_ref, ms: the exposure that gives thinlens' brightness (default: the
                     shutter interval, close - open)
``time_window``      "start, end" (ms): render only this part of the exposure (see
                     :meth:`configure`)
``near_clip``, ``far_clip``  as thinlens (defaults 0.01 and 10000 scene units)
==================== ======================================================================

Conventions (see also PHYSICS.md)
---------------------------------
* The aperture plane is the camera's local z = 0 plane (Mitsuba camera space: +z forward, +y up,
  +x to the image's *left*: Mitsuba's perspective projection flips x and y, so the rendered image
  is upright and not mirrored). Aperture coordinates (X_a, Y_a) are along local +x and +y.
  Film column u (px) grows to the image's right, i.e. along local -x.
* With these, the paper's Eq. 8 holds with the paper's image x read as the film column u:
  an opening displaced by X_a shifts the image of a point at depth Z by ``-beta_px * X_a`` px,
  beta_px = (1/Z_f - 1/Z) (W/2)/tan(fov/2) (:func:`pacam_render.optics.beta_px_per_mm`).
  The parabolic schedule runs along the image's +u axis (local -x): its local centre is
  -(a_a t^2/2 - (R_max - R)), so the image accelerates by ``+beta_px * a_a`` in film columns:
  the a_i of Eq. 18 with its sign, as Eq. 10 states it in the upright image frame that
  :mod:`pacam_render.optics` uses, and as :func:`pacam_render.psf.design_psf` draws it.
* ``camera_parabolic`` (Levin et al. 2008): the camera body translates along its local +x axis
  by X_c(t) = a_c (t^2/2 - T^2/4) mm (centred like the aperture parabola), the aperture is a
  centred disc of radius R, and the lens stays focused at ``focus_distance``. A static point at
  depth Z then moves on the film by ``+f_px X_c(t) / Z`` px: image acceleration
  a_i(Z) = f_px a_c / Z, with f_px = (W/2)/tan(fov/2).
* Masks (``bitmap``): see :mod:`pacam_render.aperture_masks` for their orientation (the display
  as seen from the sensor, in the image's orientation: column j along local -x).

Radiometry
----------
The image is proportional to the light collected: to the open area and to the open time.
Each camera ray carries the weight

    w = (A_open(t) / (pi R_max^2)) * (E / E_ref)

where A_open is the open area of the pattern shown (pi R^2 for a disc, sum(tau) pitch^2 for a
mask), E the time the shutter is actually open during [shutter_open, shutter_close] (less than
the interval for ``flutter`` or black bitmap patterns) and E_ref = ``reference_exposure``.
With the full ``lens_radius`` open and the default E_ref (the scene's shutter interval), w = 1:
the image equals ``thinlens``, whose brightness ignores its aperture radius. A smaller opening
scales it by the open-area ratio; to compare exposures of different length, give all renders
the same ``reference_exposure``: doubling the exposure then doubles the signal.
Pixel values stay in Mitsuba's units (radiance for a full opening and E = E_ref).

Closed chops and black patterns: the time the integrator draws (uniform over the shutter) is
mapped, measure-preservingly, onto the open patterns only, and the open fraction goes into the
weight, so no ray or particle-tracer connection is wasted on a closed aperture. The same kind
of map serves ``time_window`` (see :meth:`configure`): render part of the exposure, schedule
unchanged (there closed chops weigh 0). ``sample_direction`` applies the map to the light
path's time; Mitsuba 3 moves no geometry with time, so this changes nothing else.

Particle tracing (``sample_direction``) uses the same estimator: a lens point is sampled as for
a camera ray, the ray through it and the scene point meets the focal plane at a point whose
projection through the lens centre is the film position, and the weight is
w / (A' cos(theta) z^2) with A' the film's area at unit distance, theta the ray's angle to the
axis and z the point's depth: exactly ``thinlens`` for the full opening.

Schedules and time
------------------
Pattern k (k = 0..N-1) is shown for ray times in [open + k D/N, open + (k+1) D/N), D = close -
open; ``shutter_close`` itself belongs to the last pattern. The boundaries are exact: a float32
ray time selects the same pattern as ``schedule.pattern_index`` in float64. ``flutter`` has one
pattern per chop (the centred disc, or shut), so its N is the code's length (52).

Kernels and recompilation
-------------------------
Every value (radii, centres, masks, accelerations, focus, exposure, time window, to_world) is an
opaque Dr.Jit variable: sweeping values through :meth:`configure` or ``mi.traverse`` never
recompiles. The kernel code depends only on the schedule's *type* (``kernel_features`` of the
plan: e.g. ``static`` needs no table look-up at all, ``parabolic`` one pattern look-up and one
centre), so the first render with a new type compiles once (~0.3 s) and later switches back
hit Dr.Jit's kernel cache. Changing Mitsuba's own shutter (``shutter_open``/``_time`` through
``mi.traverse``) re-times the schedule, but recompiles the integrators, which bake it in; use
``time_window`` to render part of an exposure.

Known Mitsuba 3.9.1 limitation: with ``ptracer``, light leaving a *textured* area emitter carries
time = shutter_open (its position sampling drops the time), so every such particle sees the
first pattern. Uniform emitters, reflected light and the ``path`` integrator are unaffected.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from ..model import schedule as sch
from ..model.optics import LCOS_PITCH_MM
from .masks import MaskTables, build_tables, check_masks, load_masks

PLUGIN_NAME = "programmable_aperture"
SCHEDULES = ("static", "parabolic", "centres", "bitmap", "flutter", "camera_parabolic")
TIME_VARYING = ("parabolic", "flutter", "camera_parabolic")  # centres, bitmap: if N > 1
_TOL = 1e-9  # relative tolerance for "opening inside the lens"


def _f32_up(x) -> np.ndarray:
    """float32 values >= x (round up): t >= result <=> t >= x for every float32 t."""
    x = np.asarray(x, dtype=np.float64)
    y = x.astype(np.float32)
    low = y.astype(np.float64) < x
    y[low] = np.nextafter(y[low], np.float32(np.inf))
    return y


def _index_bias(t_open: float, t_close: float, n: int) -> float:
    """Downward bias for the kernels' pattern index, and a check that float32 times work.

    In float32, i = (t - t_open) * n / duration errs by at most E = 3 u n + ulp(t_open) n /
    (2 duration) (u = 2^-24: rounding of the difference, of the scale and of the product; the
    float32 copy of t_open). Subtracting 2 E puts floor(i) at the true index or one below.
    """
    dur = t_close - t_open
    if dur <= 0:
        return 0.0
    ulp = float(np.spacing(np.float32(abs(t_open)))) if t_open else 0.0
    err = 3 * 2.0**-24 * n + ulp * n / (2 * dur)
    if err > 0.1:
        raise ParameterError(
            f"shutter_open = {t_open:g} ms is too large for a {dur:g} ms exposure in "
            f"{n} patterns: ray times are float32; shift the shutter times towards 0"
        )
    return 2 * err


# ------------------------------------------------------------------------------------------
# Host side: the schedule, resolved into per-pattern arrays (numpy, no Mitsuba)
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AperturePlan:
    """Everything the kernels need, as plain numbers and numpy arrays.

    Aperture centre of pattern k at paper time tau = time - t_mid (ms), in mm (local x, y):
    ``centres_mm[k] + (aperture_quad * tau^2, 0)``. Camera offset along local x (mm):
    ``camera_x_mm[k] + camera_quad * tau^2``. ``area_mm2[k]`` is the open area, 0 for a closed
    pattern (a closed chop of ``flutter``, a black mask): the aperture is then shut.
    """

    schedule: str
    kind: str  # "disc" or "bitmap": the shape of the opening
    t_open: float
    t_close: float
    lens_radius_mm: float
    radius_mm: float
    n_patterns: int
    centres_mm: np.ndarray
    aperture_quad: float
    camera_x_mm: np.ndarray
    camera_quad: float
    area_mm2: np.ndarray
    reference_exposure: float | None
    window: tuple[float, float] | None = None
    continuous: bool = False
    tables: MaskTables | None = field(default=None, repr=False)

    @property
    def duration(self) -> float:
        return self.t_close - self.t_open

    @property
    def t_mid(self) -> float:
        return 0.5 * (self.t_open + self.t_close)

    @property
    def T(self) -> float:
        return 0.5 * self.duration

    @property
    def pattern_edges(self) -> np.ndarray:
        return np.linspace(self.t_open, self.t_close, self.n_patterns + 1)

    @property
    def is_open(self) -> np.ndarray:
        """Whether each pattern lets light through."""
        return self.area_mm2 > 0

    @property
    def open_fraction(self) -> float:
        return float(np.mean(self.is_open))

    @property
    def integration_interval(self) -> tuple[float, float]:
        """The times the integrator samples: the time window, or the whole exposure."""
        return self.window if self.window is not None else (self.t_open, self.t_close)

    @property
    def exposure_factor(self) -> float:
        """E / E_ref for the whole exposure (open time over the reference exposure)."""
        if self.reference_exposure is None:
            return self.open_fraction
        return self.open_fraction * self.duration / self.reference_exposure

    @property
    def time_scale(self) -> float:
        """Time factor of every ray's weight.

        Whole exposure: E / E_ref, E the open time (rays are sampled in open chops only).
        Time window [a, b]: (b - a) / E_ref (rays uniform in the window; closed chops weigh 0).
        """
        if self.window is None:
            return self.exposure_factor
        a, b = self.window
        return (b - a) / (self.reference_exposure or self.duration)

    @property
    def area_ratio(self) -> np.ndarray:
        """Open area of each pattern over the lens area pi R_max^2."""
        return self.area_mm2 / (math.pi * self.lens_radius_mm**2)

    def pattern_at(self, time_ms) -> np.ndarray:
        """Index of the pattern shown at ray time ``time_ms`` (float64 reference)."""
        if self.duration <= 0:
            return np.zeros(np.shape(time_ms), dtype=int)
        return sch.pattern_index(np.asarray(time_ms) - self.t_mid, self.T, self.n_patterns)

    def aperture_centre_at(self, time_ms) -> np.ndarray:
        """Centre of the opening (mm, local x and y) at ray time ``time_ms``; (..., 2)."""
        k = self.pattern_at(time_ms)
        c = self.centres_mm[k].copy()
        c[..., 0] += self.aperture_quad * (np.asarray(time_ms) - self.t_mid) ** 2
        return c

    def camera_offset_at(self, time_ms) -> np.ndarray:
        """Camera body offset along local +x (mm) at ray time ``time_ms``."""
        k = self.pattern_at(time_ms)
        return self.camera_x_mm[k] + self.camera_quad * (np.asarray(time_ms) - self.t_mid) ** 2

    @property
    def kernel_features(self) -> frozenset[str]:
        """What the kernels must compute for this schedule *type* (never for its values).

        ``gate``: sample times in open patterns only; ``window``: map times into the time
        window; ``lookup``: find the pattern from the time; ``cx``/``cy``/``cam``: per-pattern
        aperture x, y and camera offsets; ``quad_a``/``quad_c``: continuous parabolas;
        ``weights``: per-pattern open areas; ``bitmap``: sample masks. Each set traces its own
        kernel, compiled once; values within a set never recompile.
        """
        s, f = self.schedule, set()
        if self.window is not None:
            f.add("window")
        elif not self.is_open.all():
            f.add("gate")
        if s in ("centres", "bitmap", "flutter") or (
            s in ("parabolic", "camera_parabolic") and not self.continuous
        ):
            f.add("lookup")
        if s == "centres" or (s == "parabolic" and not self.continuous):
            f.add("cx")
        if s == "centres":
            f.add("cy")
        if s == "camera_parabolic":
            f.add("quad_c" if self.continuous else "cam")
        if s == "parabolic" and self.continuous:
            f.add("quad_a")
        if s in ("flutter", "bitmap"):
            f.add("weights")
        if s == "bitmap":
            f.add("bitmap")
        return frozenset(f)

    def mean_weight(self) -> float:
        """Expected ray weight: the image's scale relative to thinlens (exact)."""
        a, b = self.integration_interval
        if self.duration <= 0:
            return float(self.area_ratio[0])
        # the open area is constant between these times
        cuts = np.unique(np.clip(np.concatenate([[a, b], self.pattern_edges]), a, b))
        k = self.pattern_at(0.5 * (cuts[:-1] + cuts[1:]))
        collected = float(np.sum(self.area_ratio[k] * np.diff(cuts)))  # ms
        return collected / (self.reference_exposure or self.duration)


def parse_centres(value) -> np.ndarray:
    """Centres (N, 2) in mm from a string ``"x y; x y"`` / ``"x; x"`` or an array-like."""
    if isinstance(value, str):
        rows = [r for r in re.split(r"[;\n]", value) if r.strip()]
        try:
            parsed = [[float(v) for v in re.split(r"[,\s]+", r.strip()) if v] for r in rows]
        except ValueError:
            parsed = []
        if not parsed or any(len(r) not in (1, 2) for r in parsed):
            raise ParameterError(
                f"centres: expected 'x y; x y; ...' or 'x; x; ...' (mm), got {value!r}"
            )
        arr = np.array([r if len(r) == 2 else [r[0], 0.0] for r in parsed], dtype=float)
    else:
        try:
            arr = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(f"centres: expected numbers (mm), got {value!r}") from None
        if arr.ndim == 1:
            arr = np.stack([arr, np.zeros_like(arr)], axis=1)
        if arr.ndim != 2 or arr.shape[1] != 2:
            raise ParameterError(f"centres: expected shape (N,) or (N, 2), got {arr.shape}")
    if arr.shape[0] == 0:
        raise ParameterError("centres: need at least one centre")
    if not np.all(np.isfinite(arr)):
        raise ParameterError("centres: must be finite numbers (mm)")
    return arr


def _check_inside(centres: np.ndarray, R: float, R_max: float, what: str) -> None:
    reach = R + np.hypot(centres[:, 0], centres[:, 1])
    bad = np.flatnonzero(reach > R_max * (1 + _TOL))
    if bad.size:
        k = int(bad[0])
        raise ParameterError(
            f"{what}: opening outside the lens: aperture_radius + |centre| = {reach[k]:.6g} mm "
            f"> lens_radius = {R_max:g} mm (pattern {k}, centre {tuple(centres[k])}); need "
            f"aperture_radius + |centre| <= lens_radius"
        )


DEFAULTS = dict(
    schedule="static",
    n_patterns=None,  # 16 where it matters
    continuous=None,
    aperture_radius=None,  # lens_radius
    centres=None,
    masks=None,
    mask_file=None,
    mask_pitch=LCOS_PITCH_MM,
    flutter_code=sch.RASKAR_2006_CODE,
    camera_acceleration=None,
    image_acceleration=None,
    reference_exposure=None,
    time_window=None,
)


def build_plan(
    cfg: dict,
    t_open: float,
    t_close: float,
    focal_px: float | None = None,
    focus_mm: float | None = None,
) -> AperturePlan:
    """Resolve a configuration (see the module docstring) into an :class:`AperturePlan`.

    ``focal_px`` ((W/2)/tan(fov/2)) and ``focus_mm`` are needed only to turn an
    ``image_acceleration`` into a camera acceleration. Raises :class:`ParameterError` naming
    the parameter on bad input.
    """
    c = {**DEFAULTS, **cfg}
    kind = str(c["schedule"]).strip().lower()
    if kind not in SCHEDULES:
        raise ParameterError(f"schedule must be one of {', '.join(SCHEDULES)}, got {kind!r}")
    R_max = check_positive("lens_radius", c["lens_radius"], "mm")
    R = (
        R_max
        if c["aperture_radius"] is None
        else check_finite("aperture_radius", c["aperture_radius"])
    )
    if R <= 0:
        raise ParameterError(
            f"aperture_radius must be in (0, lens_radius = {R_max:g}] mm, got {R!r}"
        )
    if R > R_max * (1 + _TOL):
        raise ParameterError(
            f"aperture_radius must be in (0, lens_radius = {R_max:g}] mm (opening inside the "
            f"lens), got {R!r}"
        )
    R = min(R, R_max)
    t0 = check_finite("shutter_open", t_open)
    t1 = check_finite("shutter_close", t_close)
    dur = t1 - t0
    if dur < 0:
        raise ParameterError(f"shutter_close must be >= shutter_open = {t0:g} ms, got {t1:g}")
    n_given = c["n_patterns"]
    n = 16 if n_given is None else sch.check_n_patterns(n_given)
    T = 0.5 * dur

    # exposure: E_ref defaults to the shutter interval
    e_ref = None
    if c["reference_exposure"] is not None:
        e_ref = check_positive("reference_exposure", c["reference_exposure"], "ms")
        if dur <= 0:
            raise ParameterError(
                "reference_exposure needs an exposure: shutter_close must be > shutter_open"
            )
    window = c["time_window"]
    if isinstance(window, str):
        window = [v for v in re.split(r"[,\s]+", window.strip()) if v] or None
    if window is not None:
        try:
            wa, wb = (float(v) for v in window)
        except (TypeError, ValueError):
            raise ParameterError(
                f"time_window must be a pair (start, end) in ms, got {window!r}"
            ) from None
        eps = 1e-9 * max(1.0, abs(t0), abs(t1))
        if not (dur > 0 and t0 - eps <= wa < wb <= t1 + eps):
            raise ParameterError(
                f"time_window must satisfy shutter_open <= start < end <= shutter_close = "
                f"[{t0:g}, {t1:g}] ms, got ({wa:g}, {wb:g})"
            )
        window = (max(wa, t0), min(wb, t1))

    def need_time(what: str) -> None:
        if not dur > 0:
            raise ParameterError(
                f"schedule={kind!r} varies in time ({what}) and needs shutter_close > "
                f"shutter_open (ms), got shutter_open = {t0:g}, shutter_close = {t1:g}: "
                f"Mitsuba would give every ray the same time and the pattern would never change"
            )

    if kind in TIME_VARYING:
        need_time("by definition")
    continuous = c["continuous"]
    continuous = (kind == "camera_parabolic") if continuous is None else bool(continuous)
    if continuous and kind not in ("parabolic", "camera_parabolic"):
        raise ParameterError(
            f"continuous applies to the parabolic and camera_parabolic schedules, not {kind!r}"
        )

    def fixed_n(count: int, what: str) -> int:
        if n_given is not None and int(n_given) != count:
            raise ParameterError(
                f"n_patterns = {n_given} disagrees with the {count} {what} of schedule={kind!r}"
            )
        return count

    centres = np.zeros((1, 2))
    cam_x = np.zeros(1)
    a_quad = c_quad = 0.0
    gate = np.ones(1, dtype=bool)
    tables = None
    area = None
    if kind == "static":
        n = 1
    elif kind == "parabolic":
        # The parabola runs along local -x, the image's +u axis, so that in film columns the
        # image accelerates by +beta a_a: Eq. 18 with its sign (Eq. 10 in the upright frame).
        a_a = sch.aperture_acceleration(R_max, R, T)  # mm/ms^2
        if continuous:
            centres = np.array([[R_max - R, 0.0]])
            a_quad, n = -0.5 * a_a, 1
        else:
            xs = -sch.pattern_centres_mm(R_max, R, T, n)
            centres = np.stack([xs, np.zeros(n)], axis=1)
    elif kind == "centres":
        if c["centres"] is None:
            raise ParameterError("centres: schedule='centres' needs a list of centres (mm)")
        centres = parse_centres(c["centres"])
        n = fixed_n(len(centres), "centres")
    elif kind == "flutter":
        gate = sch.flutter_code(str(c["flutter_code"]).strip()).astype(bool)
        n = fixed_n(len(gate), "chops")  # a pattern per chop: the centred disc, or shut
    elif kind == "camera_parabolic":
        a_c = _camera_acceleration(c, focal_px, focus_mm)
        if continuous:
            cam_x = np.array([-0.25 * a_c * T**2])
            c_quad, n = 0.5 * a_c, 1
        else:
            tm = sch.pattern_mid_times_ms(T, n)
            cam_x = a_c * (0.5 * tm**2 - 0.25 * T**2)
    elif kind == "bitmap":
        source = c["masks"] if c["masks"] is not None else c["mask_file"]
        if source is None:
            raise ParameterError("masks: schedule='bitmap' needs masks (array) or mask_file")
        pitch = check_positive("mask_pitch", c["mask_pitch"], "mm")
        masks = load_masks(source)
        check_masks(masks, R_max, pitch)
        n = fixed_n(len(masks), "masks")
        tables = build_tables(masks, pitch)
        area = tables.area_mm2
        centres = np.zeros((n, 2))
    if n > 1:
        need_time(f"{n} patterns")
        _index_bias(t0, t1, n)  # raises if float32 ray times cannot tell the patterns apart
    if kind != "bitmap":
        _check_inside(centres, R, R_max, "centres" if kind == "centres" else "aperture_radius")
        centres = np.broadcast_to(centres, (n, 2)).copy() if len(centres) != n else centres
        area = np.full(n, math.pi * R * R) * np.broadcast_to(gate, (n,))
    cam_x = np.broadcast_to(cam_x, (n,)).copy() if len(cam_x) != n else cam_x
    return AperturePlan(
        schedule=kind,
        kind="bitmap" if kind == "bitmap" else "disc",
        t_open=t0,
        t_close=t1,
        lens_radius_mm=R_max,
        radius_mm=R,
        n_patterns=n,
        centres_mm=centres,
        aperture_quad=a_quad,
        camera_x_mm=cam_x,
        camera_quad=c_quad,
        area_mm2=np.asarray(area, dtype=float),
        reference_exposure=e_ref,
        window=window,
        continuous=continuous,
        tables=tables,
    )


def _camera_acceleration(c: dict, focal_px: float | None, focus_mm: float | None) -> float:
    a_c, a_i = c["camera_acceleration"], c["image_acceleration"]
    if (a_c is None) == (a_i is None):
        raise ParameterError(
            "camera_parabolic needs exactly one of camera_acceleration (mm/ms^2) or "
            "image_acceleration (px/ms^2, for objects at focus_distance)"
        )
    if a_c is not None:
        return check_finite("camera_acceleration", a_c)
    a_i = check_finite("image_acceleration", a_i)
    if focal_px is None or focus_mm is None:
        raise ParameterError("image_acceleration needs the film width, fov and focus_distance")
    return a_i * focus_mm / focal_px  # a_i(Z_f) = f_px a_c / Z_f


# ------------------------------------------------------------------------------------------
# Mitsuba side
# ------------------------------------------------------------------------------------------

_CLASSES: dict[str, type] = {}
_PROP_KEYS = (
    "schedule",
    "n_patterns",
    "continuous",
    "lens_radius",
    "aperture_radius",
    "centres",
    "masks",
    "mask_file",
    "mask_pitch",
    "flutter_code",
    "camera_acceleration",
    "image_acceleration",
    "reference_exposure",
    "time_window",
)


def _config_from_props(props) -> dict:
    cfg = {}
    for key in _PROP_KEYS:
        if key in props:
            cfg[key] = props.get(key)
    if "lens_radius" not in cfg:
        raise ParameterError("lens_radius (R_max, mm) is required")
    return cfg


def _pad(a: np.ndarray, n: int = 2) -> np.ndarray:
    """At least n entries: a gather from a 1-element array is folded into a different kernel."""
    a = np.asarray(a)
    if len(a) >= n:
        return a
    fill = a[-1] if len(a) else 0
    return np.concatenate([a, np.full(n - len(a), fill, dtype=a.dtype)])


def _make_class(variant: str):
    import drjit as dr
    import mitsuba as mi

    M = getattr(mi, variant)
    Float, Int, UInt = M.Float, M.Int32, M.UInt32
    Point2f, Point3f, Vector3f = M.Point2f, M.Point3f, M.Vector3f

    jit = dr.is_jit_v(Float)  # scalar variants: plain Python numbers and numpy tables

    def opaque_scalar(v, t=Float):
        return dr.opaque(t, v) if jit else t(v)

    def opaque_array(a, t=Float):
        if not jit:
            return np.asarray(_pad(a))
        x = t(_pad(a))
        dr.make_opaque(x)
        return x

    def gather(t, source, index, active=True):
        if jit:
            return dr.gather(t, source, index, active)
        return t(source[min(max(int(index), 0), len(source) - 1)]) if active else t(0)

    def first(v) -> float:
        return float(v[0]) if jit else float(v)

    def make_opaque(*args):
        if jit:
            dr.make_opaque(*args)

    def lookup(t, edges, n, scale, t0, bias, active):
        """Index k of the window [edges[k], edges[k+1]) containing t (the last one closed).

        (t - t0) * scale is the index up to float32 rounding; lowered by ``bias`` (more than
        that rounding, see :func:`_index_bias`) its floor is k or k - 1, and one comparison
        with the next edge (float32, rounded up) settles it, exactly as in float64.
        """
        k = dr.clip(Int(dr.floor((t - t0) * scale - bias)), 0, n - 1)
        hi = gather(Float, edges, UInt(k + 1), active)
        k = dr.select((t >= hi) & (k < n - 1), k + 1, k)
        return UInt(k)

    class ProgrammableApertureCamera(M.Sensor):
        """Thin-lens camera with a programmable aperture (see the module docstring)."""

        def __init__(self, props):
            M.Sensor.__init__(self, props)
            film = self.film()
            size, crop = film.size(), film.crop_size()
            self._resolution = mi.ScalarVector2f(crop)
            self._x_fov = float(mi.parse_fov(props, size.x / size.y))
            self._near = check_positive("near_clip", props.get("near_clip", 1e-2))
            self._far = check_positive("far_clip", props.get("far_clip", 1e4))
            focus = props.get("focus_distance", self._far)
            self._focal_px = 0.5 * size.x / math.tan(math.radians(self._x_fov) / 2.0)
            self.m_needs_sample_3 = True

            proj = mi.perspective_projection(
                size, crop, film.crop_offset(), self._x_fov, self._near, self._far
            )
            self._camera_to_sample = M.ProjectiveTransform4f(proj)
            self._sample_to_camera = self._camera_to_sample.inverse()
            s2c = self._sample_to_camera
            o = s2c @ Point3f(0.0, 0.0, 0.0)
            self._dx = (s2c @ Point3f(1.0 / crop.x, 0.0, 0.0)) - o
            self._dy = (s2c @ Point3f(0.0, 1.0 / crop.y, 0.0)) - o
            pmin = s2c @ Point3f(0.0, 0.0, 0.0)
            pmax = s2c @ Point3f(1.0, 1.0, 0.0)
            w = abs(first(pmax.x) / first(pmax.z) - first(pmin.x) / first(pmin.z))
            h = abs(first(pmax.y) / first(pmax.z) - first(pmin.y) / first(pmin.z))
            self._inv_image_area = opaque_scalar(1.0 / (w * h))  # 1/A' at z = 1
            make_opaque(self._camera_to_sample, self._sample_to_camera, self._dx, self._dy)

            self._to_world = M.AffineTransform4f(self.m_to_world)
            self._check_to_world()
            self._focus = opaque_scalar(check_positive("focus_distance", focus, "mm"))
            self._traversed_cfg = {}
            # the exposure as written (double precision); Mitsuba keeps float32 copies
            t_open = float(props.get("shutter_open", self.shutter_open()))
            t_close = float(props.get("shutter_close", t_open + self.shutter_open_time()))
            self._exposure = (t_open, t_close)
            self._cfg = _config_from_props(props)
            self._set_plan(self._build(self._cfg))
            self._sync_traversed()

        # ---------------------------------------------------------------- configuration
        def _check_to_world(self):
            m = np.array(self._to_world.matrix, dtype=float).reshape(4, 4)
            lin = m[:3, :3]
            if not np.allclose(lin.T @ lin, np.eye(3), atol=1e-4):
                raise ParameterError(
                    "to_world: scale factors in the camera-to-world transformation are not "
                    "allowed (rotation and translation only)"
                )
            make_opaque(self._to_world)
            self._from_world = self._to_world.inverse()
            make_opaque(self._from_world)
            self.m_to_world = self._to_world

        def _build(self, cfg: dict) -> AperturePlan:
            return build_plan(
                cfg,
                *self._exposure,
                focal_px=self._focal_px,
                focus_mm=first(self._focus),
            )

        def configure(self, **changes) -> AperturePlan:
            """Change the schedule or its parameters (same names as the plugin's properties).

            Opaque uploads: no kernel is recompiled, except once when switching between disc
            schedules and ``bitmap``. ``focus_distance`` may be given too. On a bad value
            nothing changes and :class:`ParameterError` is raised.

            ``time_window=(start, end)`` (ms, inside the exposure) renders only that part of
            the exposure, with the schedule's timing unchanged: the sensor maps the uniform
            time the integrator draws over the exposure onto the window (Mitsuba's own shutter
            is left alone: the integrators bake it into their kernels). Images of windows that
            tile the exposure sum to the full image. ``time_window=None``: whole exposure.
            """
            focus = changes.pop("focus_distance", None)
            unknown = set(changes) - set(_PROP_KEYS)
            if unknown:
                raise ParameterError(
                    f"configure: unknown parameter(s) {sorted(unknown)}; valid: "
                    f"{', '.join(_PROP_KEYS)}, focus_distance"
                )
            cfg = {**self._cfg, **changes}
            for key, other in (
                ("image_acceleration", "camera_acceleration"),
                ("camera_acceleration", "image_acceleration"),
            ):
                if changes.get(key) is not None and other not in changes:
                    cfg[other] = None  # one replaces the other
            if "schedule" in changes:  # values of another schedule do not carry over
                for key in ("centres", "masks", "mask_file", "n_patterns", "continuous"):
                    if key not in changes:
                        cfg.pop(key, None)
            old_focus = self._focus
            if focus is not None:
                self._focus = opaque_scalar(check_positive("focus_distance", focus, "mm"))
            try:
                plan = self._build(cfg)
            except Exception:
                self._focus = old_focus
                raise
            self._cfg = cfg
            self._set_plan(plan)
            self._sync_traversed()
            return plan

        @property
        def plan(self) -> AperturePlan:
            """The resolved schedule (numpy), e.g. for tests and analysis."""
            return self._plan

        @property
        def focal_length_px(self) -> float:
            """(W/2)/tan(fov/2): the film's focal length in pixels."""
            return self._focal_px

        @property
        def focus_distance(self) -> float:
            return first(self._focus)

        def _set_plan(self, plan: AperturePlan):
            self._plan = plan
            dur = plan.duration
            n = plan.n_patterns
            open_idx = np.flatnonzero(plan.is_open).astype(np.uint32)
            self._features = plan.kernel_features
            self._t_open = opaque_scalar(plan.t_open)
            self._t_mid = opaque_scalar(plan.t_mid)
            self._n = opaque_scalar(n, Int)
            self._scale = opaque_scalar(n / dur if dur > 0 else 0.0)
            self._bias = opaque_scalar(_index_bias(plan.t_open, plan.t_close, n))
            self._width = opaque_scalar(dur / n)
            # window edges rounded up to float32: t >= edge exactly when t >= the float64 edge
            self._edges = opaque_array(_f32_up(plan.pattern_edges), Float)
            self._n_open = opaque_scalar(len(open_idx), Int)
            self._open_idx = opaque_array(open_idx, UInt)
            self._time_scale = opaque_scalar(plan.time_scale)
            win = plan.integration_interval
            self._win_open = opaque_scalar(win[0])
            self._win_len = opaque_scalar(win[1] - win[0])
            self._inv_dur = opaque_scalar(1.0 / dur if dur > 0 else 0.0)
            # per-pattern tables, and their first entries for the schedules that need no table
            ratio = plan.area_ratio.astype(np.float32)
            self._weight = opaque_array(ratio)
            self._cx = opaque_array(plan.centres_mm[:, 0].astype(np.float32))
            self._cy = opaque_array(plan.centres_mm[:, 1].astype(np.float32))
            self._cam = opaque_array(plan.camera_x_mm.astype(np.float32))
            open_ratio = ratio[plan.is_open] if plan.is_open.any() else ratio
            self._weight0 = opaque_scalar(float(open_ratio[0]) * plan.time_scale)
            self._cx0 = opaque_scalar(float(plan.centres_mm[0, 0]))
            self._cy0 = opaque_scalar(float(plan.centres_mm[0, 1]))
            self._cam0 = opaque_scalar(float(plan.camera_x_mm[0]))
            self._a_quad = opaque_scalar(plan.aperture_quad)
            self._c_quad = opaque_scalar(plan.camera_quad)
            self._radius = opaque_scalar(plan.radius_mm)
            self._inv_disc_area = opaque_scalar(1.0 / (math.pi * plan.radius_mm**2))
            if plan.tables is not None:
                tb = plan.tables
                # one record per run: x_hi, y, span, cdf before it, cdf up to it
                c_hi = tb.cdf.astype(np.float32)
                c_lo = np.concatenate([[0.0], c_hi[:-1]]).astype(np.float32)
                c_lo[tb.start[tb.count > 0]] = 0.0
                rec = np.stack([tb.x_hi_mm, tb.y_mm, tb.span_mm, c_lo, c_hi], axis=1)
                rec = rec.astype(np.float32)
                self._m_rec = rec if not jit else opaque_array(rec.reshape(-1))
                self._m_start = opaque_array(tb.start, UInt)
                self._m_count = opaque_array(tb.count, UInt)
                self._m_guide = opaque_array(tb.guide, UInt)
                self._m_gstart = opaque_array(tb.guide_start, UInt)
                self._m_pitch = opaque_scalar(tb.pitch_mm)
            # camera travel, for bbox()
            ts = np.linspace(plan.t_open, plan.t_close, 4 * n + 1)
            xs = plan.camera_offset_at(ts)
            self._travel = (float(np.min(xs)), float(np.max(xs)))

        # ---- traversal: to_world and the swept scalars
        def _sync_traversed(self):
            p = self._plan
            c = self._cfg
            vals = {
                "aperture_radius": p.radius_mm,
                "lens_radius": p.lens_radius_mm,
                "focus_distance": first(self._focus),
                "camera_acceleration": float(c.get("camera_acceleration") or 0.0)
                if c.get("image_acceleration") is None
                else float(c["image_acceleration"]) * first(self._focus) / self._focal_px,
            }
            self._traversed_vals = dict(vals)
            if not jit:  # plain floats cannot be updated in place: use configure()
                return
            for k, v in vals.items():
                if k in self._traversed_cfg:
                    mi.set_property(self._traversed_cfg[k], Float(v))
                else:
                    self._traversed_cfg[k] = Float(v)

        def traverse(self, callback):
            super().traverse(callback)
            flags = mi.ParamFlags.NonDifferentiable
            callback.put("to_world", self._to_world, flags)
            for k, v in self._traversed_cfg.items():
                callback.put(k, v, flags)

        def parameters_changed(self, keys):
            super().parameters_changed(keys)
            old_tw = M.AffineTransform4f(self._from_world.inverse())
            if not keys or "to_world" in keys:
                try:
                    self._check_to_world()
                except ParameterError:
                    self._to_world.assign(old_tw)
                    self._check_to_world()
                    raise
            changes = {}
            for k, holder in self._traversed_cfg.items():
                v = first(holder)
                if v != self._traversed_vals[k]:
                    changes[k] = v
            if "camera_acceleration" in changes:
                changes["image_acceleration"] = None
            shutter = (self.shutter_open(), self.shutter_open() + self.shutter_open_time())
            old_exposure = self._exposure
            if not np.allclose(shutter, self._exposure, rtol=1e-6, atol=1e-6):
                # a new exposure: the schedule is re-timed
                self._exposure = shutter
                changes["time_window"] = None
            try:
                self.configure(**changes)  # also rebuilds for a changed shutter
            except ParameterError:
                self._exposure = old_exposure
                self._sync_traversed()
                raise

        # ---------------------------------------------------------------- kernels
        def _time_and_pattern(self, time, active):
            """The ray's time and pattern from the integrator's time (uniform over the
            exposure). Measure-preserving maps: into the time window, or into the open
            patterns only (closed flutter chops, black masks), the open fraction going into the
            weight. Returns (time, pattern index)."""
            f = self._features
            if "gate" in f:
                u = (time - self._t_open) * self._inv_dur * Float(self._n_open)
                j = dr.clip(Int(dr.floor(u)), 0, self._n_open - 1)
                frac = dr.clip(u - Float(j), 0.0, 1.0)
                k = gather(UInt, self._open_idx, UInt(j), active)
                return self._t_open + (Float(k) + frac) * self._width, k
            if "window" in f:
                u = (time - self._t_open) * self._inv_dur
                time = self._win_open + u * self._win_len
            if "lookup" in f:
                return time, self._pattern(time, active)
            return time, UInt(0)

        def _pattern(self, time, active):
            return lookup(time, self._edges, self._n, self._scale, self._t_open, self._bias, active)

        def _weight_at(self, k, active):
            """Ray weight of pattern k: open-area ratio (0 if shut) x time factor."""
            f = self._features
            # gated flutter samples open chops only, which all have the same area
            if "weights" in f and ("bitmap" in f or "gate" not in f):
                return gather(Float, self._weight, k, active) * self._time_scale
            return self._weight0

        def _camera_x(self, k, time, active):
            f = self._features
            x = gather(Float, self._cam, k, active) if "cam" in f else self._cam0
            if "quad_c" in f:
                tau = time - self._t_mid
                x = x + self._c_quad * tau * tau
            return x

        def _aperture(self, k, time, sample, active):
            """Aperture point (local mm) for pattern k, and its area density (1/mm^2)."""
            f = self._features
            if "bitmap" in f:
                return self._sample_mask(k, sample, active)
            d = M.warp.square_to_uniform_disk_concentric(sample) * self._radius
            cx = gather(Float, self._cx, k, active) if "cx" in f else self._cx0
            cy = gather(Float, self._cy, k, active) if "cy" in f else self._cy0
            if "quad_a" in f:
                tau = time - self._t_mid
                cx = cx + self._a_quad * tau * tau
            return Point2f(d.x + cx, d.y + cy), self._inv_disc_area

        def _rec(self, j, c, active):
            """Field c of run record j: 0 x_hi, 1 y, 2 span, 3 cdf before, 4 cdf up to it."""
            if jit:  # separate gathers: a Vector gather traces a packet or single gathers
                # depending on Dr.Jit's state, i.e. two kernels (needless recompiles)
                return gather(Float, self._m_rec, j * 5 + c, active)
            return float(self._m_rec[int(j), c]) if active else 0.0

        def _sample_mask(self, k, sample, active):
            """Pick a run of mask k with probability tau x length / sum (CDF inversion: guide
            table, then a binary search over the few runs it leaves), then a uniform point in
            the run. Returns the point (mm) and its area density tau / (sum(tau) pitch^2)."""
            start = gather(UInt, self._m_start, k, active)
            count = gather(UInt, self._m_count, k, active)
            gstart = gather(UInt, self._m_gstart, k, active)
            active = active & (count > 0)
            u = sample.x
            i = UInt(dr.clip(Int(dr.floor(u * Float(count))), 0, Int(count) - 1))
            lo = gather(UInt, self._m_guide, gstart + i, active)
            hi = gather(UInt, self._m_guide, gstart + i + 1, active)

            def cond(lo, hi):
                return lo < hi

            def body(lo, hi):
                mid = (lo + hi) >> 1
                big = self._rec(start + mid, 4, active) > u
                return dr.select(big, lo, mid + 1), dr.select(big, mid, hi)

            lo, hi = dr.while_loop(
                (lo, hi), cond, body, labels=("lo", "hi"), label="aperture mask search"
            )
            j = start + lo
            c_lo, c_hi = self._rec(j, 3, active), self._rec(j, 4, active)
            step = c_hi - c_lo
            r = dr.clip((u - c_lo) / dr.maximum(step, 1e-30), 0.0, 1.0)
            span = self._rec(j, 2, active)
            x = self._rec(j, 0, active) - r * span
            y = self._rec(j, 1, active) + (sample.y - 0.5) * self._m_pitch
            pdf = dr.select(active, step / dr.maximum(span * self._m_pitch, 1e-30), 0.0)
            return Point2f(x, y), pdf

        def _ray_setup(self, time, position_sample, aperture_sample, active):
            time, k = self._time_and_pattern(time, active)
            weight = self._weight_at(k, active)
            near_p = self._sample_to_camera @ Point3f(position_sample.x, position_sample.y, 0.0)
            a, _ = self._aperture(k, time, aperture_sample, active)
            aperture_p = Point3f(a.x, a.y, 0.0)
            origin = Point3f(a.x + self._camera_x(k, time, active), a.y, 0.0)
            return time, weight, near_p, aperture_p, origin

        def _finish(self, ray, d, origin):
            ray.o = self._to_world @ origin
            ray.d = self._to_world @ d
            inv_z = dr.rcp(d.z)
            near_t = self._near * inv_z
            far_t = self._far * inv_z
            ray.o += ray.d * near_t
            ray.maxt = far_t - near_t

        def sample_ray(self, time, sample1, sample2, sample3, active=True):
            wavelengths, wav_weight = self.sample_wavelengths(
                dr.zeros(M.SurfaceInteraction3f), sample1, active
            )
            time, weight, near_p, aperture_p, origin = self._ray_setup(
                time, sample2, sample3, active
            )
            focus_p = near_p * (self._focus / near_p.z)
            d = dr.normalize(Vector3f(focus_p - aperture_p))
            ray = M.Ray3f(Point3f(0.0), Vector3f(0.0, 0.0, 1.0), time, wavelengths)
            self._finish(ray, d, origin)
            return ray, wav_weight * weight

        def sample_ray_differential(self, time, sample1, sample2, sample3, active=True):
            wavelengths, wav_weight = self.sample_wavelengths(
                dr.zeros(M.SurfaceInteraction3f), sample1, active
            )
            time, weight, near_p, aperture_p, origin = self._ray_setup(
                time, sample2, sample3, active
            )
            f_dist = self._focus / near_p.z
            focus_p = near_p * f_dist
            d = dr.normalize(Vector3f(focus_p - aperture_p))
            ray = M.RayDifferential3f(
                M.Ray3f(Point3f(0.0), Vector3f(0.0, 0.0, 1.0), time, wavelengths)
            )
            self._finish(ray, d, origin)
            ray.o_x = ray.o
            ray.o_y = ray.o
            focus_x = (near_p + self._dx) * f_dist
            focus_y = (near_p + self._dy) * f_dist
            ray.d_x = self._to_world @ dr.normalize(Vector3f(focus_x - aperture_p))
            ray.d_y = self._to_world @ dr.normalize(Vector3f(focus_y - aperture_p))
            ray.has_differentials = True
            return ray, wav_weight * weight

        def sample_direction(self, it, sample, active=True):
            """Connect a scene point to the lens (particle tracing): a lens point, the film
            position its ray lands on, and importance / pdf (same estimator as sample_ray)."""
            time, k = self._time_and_pattern(it.time, active)
            cam_x = self._camera_x(k, time, active)
            ref_p = self._from_world @ it.p
            ref_p = Point3f(ref_p.x - cam_x, ref_p.y, ref_p.z)
            active = active & (ref_p.z >= self._near) & (ref_p.z <= self._far)
            a, pdf_area = self._aperture(k, time, Point2f(sample.x, sample.y), active)
            aperture_p = Point3f(a.x, a.y, 0.0)
            v = Vector3f(ref_p - aperture_p)
            z = dr.select(active, ref_p.z, 1.0)  # > 0 where active (scalar mode: no 1/0)
            # the ray from the lens point through ref_p meets the focal plane at focus_p;
            # the film pixel is where the lens centre projects focus_p
            focus_p = Point3f(aperture_p + v * (self._focus / z))
            screen = self._camera_to_sample @ focus_p
            uv = Point2f(screen.x, screen.y)
            active &= (uv.x >= 0.0) & (uv.x <= 1.0) & (uv.y >= 0.0) & (uv.y <= 1.0)
            dist = dr.norm(v)
            inv_dist = dr.rcp(dr.maximum(dist, 1e-20))
            cos_t = dr.maximum(v.z * inv_dist, 1e-20)  # v.z = z > 0 where active
            active &= pdf_area > 0.0
            # W_e cos / (dist^2 p_A): with W_e cos = p_A p_omega w (the camera-ray estimator)
            # and p_omega = |focus_p - a|^2 / (cos A' F^2) = dist^2 / (cos A' z^2) on the
            # ray through a (collinear: |focus_p - a| / dist = F / z), this is w / (A' cos z^2)
            weight = self._weight_at(k, active)
            weight = weight * self._inv_image_area * dr.rcp(cos_t * z * z)

            if jit:
                ds = dr.zeros(M.DirectionSample3f)
            else:
                ds = M.DirectionSample3f()
                ds.delta = False
            ds.p = self._to_world @ Point3f(a.x + cam_x, a.y, 0.0)
            ds.d = (ds.p - it.p) * inv_dist
            ds.dist = dist
            ds.n = self._to_world @ Vector3f(0.0, 0.0, 1.0)
            ds.uv = uv * self._resolution
            ds.time = time
            ds.pdf = dr.select(active, pdf_area * dist * dist / cos_t, 0.0)
            return ds, M.Spectrum(dr.select(active, weight, 0.0))

        # ---------------------------------------------------------------- misc
        def pattern_index(self, time):
            """Pattern shown at each ray time (the kernels' own lookup), as numpy."""
            t = Float(np.asarray(time, dtype=np.float32)) if jit else Float(time)
            return np.array(self._pattern(t, True), dtype=np.int64)

        def sample_aperture(self, time, u1, u2):
            """Aperture points (local mm) that the kernels sample at ray times ``time`` from
            uniforms (u1, u2), and each ray's weight (without the wavelength weight); numpy.
            ``time`` is used as is (no window or chop remapping)."""
            if not jit:
                raise ParameterError("sample_aperture needs a JIT (llvm/cuda) variant")
            t, a, b = (Float(np.asarray(v, dtype=np.float32)) for v in (time, u1, u2))
            active = M.Bool(True)
            k = self._pattern(t, active)
            p, _ = self._aperture(k, t, Point2f(a, b), active)
            w = gather(Float, self._weight, k, active) * self._time_scale
            return np.array(p.x), np.array(p.y), np.array(w)

        def bbox(self):
            lo = self._to_world @ Point3f(self._travel[0], 0.0, 0.0)
            hi = self._to_world @ Point3f(self._travel[1], 0.0, 0.0)
            box = mi.ScalarBoundingBox3f()
            for p in (lo, hi):
                box.expand(mi.ScalarPoint3f(first(p.x), first(p.y), first(p.z)))
            return box

        def to_string(self):
            p = self._plan
            return (
                "ProgrammableApertureCamera[\n"
                f"  schedule = {p.schedule}{' (continuous)' if p.continuous else ''},\n"
                f"  n_patterns = {p.n_patterns},\n"
                f"  lens_radius = {p.lens_radius_mm:g} mm,\n"
                f"  aperture_radius = {p.radius_mm:g} mm,\n"
                f"  x_fov = {self._x_fov:g} deg,\n"
                f"  focus_distance = {first(self._focus):g} mm,\n"
                f"  near_clip = {self._near:g}, far_clip = {self._far:g},\n"
                f"  exposure = [{p.t_open:g}, {p.t_close:g}] ms,"
                f" time_window = {p.window},\n"
                f"  open_fraction = {p.open_fraction:g}, exposure_factor = "
                f"{p.exposure_factor:g},\n"
                f"  mean weight (image / thinlens) = {p.mean_weight():.6g},\n"
                f"  film = {self.film()},\n"
                f"  to_world = {self._to_world.matrix}\n"
                "]"
            )

    ProgrammableApertureCamera.__name__ = f"ProgrammableApertureCamera_{variant}"
    return ProgrammableApertureCamera


def sensor_class(variant: str | None = None) -> type:
    """The sensor class for a Mitsuba variant (default: the active one), created once."""
    import mitsuba as mi

    variant = variant or mi.variant()
    if variant is None:
        raise ParameterError("no Mitsuba variant is active: call backend.select_variant() first")
    if variant not in _CLASSES:
        _CLASSES[variant] = _make_class(variant)
    return _CLASSES[variant]


def register() -> str:
    """Register ``programmable_aperture`` for the active variant (choosing one if none is).

    Idempotent; call it again after switching variants (or use :func:`install`, which does so
    automatically). Returns the variant name.
    """
    import mitsuba as mi

    variant = mi.variant()
    if variant is None:
        from .backend import select_variant

        variant = select_variant()
    cls = sensor_class(variant)
    mi.register_sensor(PLUGIN_NAME, lambda props: cls(props))
    return variant


def _on_variant_change(old, new):
    if new is not None:
        register()


def install() -> None:
    """Register now if a variant is active, and again after every variant switch.

    This is what ``import pacam_render`` calls; it does not choose a variant itself.
    """
    import mitsuba as mi

    mi.detail.add_variant_callback(_on_variant_change)  # a set: adding twice is harmless
    if mi.variant() is not None:
        register()


def sensor_dict(**params) -> dict:
    """A ``mi.load_dict`` entry for the sensor: numpy centres/masks become Dr.Jit tensors.

    Example: ``sensor_dict(fov=40, focus_distance=500, lens_radius=4.5,
    aperture_radius=1.3, schedule="parabolic", shutter_open=0, shutter_close=45,
    film={...})``.
    """
    import mitsuba as mi

    # validate here, so that bad input raises ParameterError itself (inside mi.load_dict it
    # arrives wrapped in a RuntimeError)
    cfg = {k: params[k] for k in _PROP_KEYS if k in params}
    if "lens_radius" not in cfg:
        raise ParameterError("lens_radius (R_max, mm) is required")
    t0 = float(params.get("shutter_open", 0.0))
    t1 = float(params.get("shutter_close", t0))
    width = float((params.get("film") or {}).get("width", 768))
    focus = params.get("focus_distance", params.get("far_clip", 1e4))
    focus = check_positive("focus_distance", focus, "mm")
    focal_px = None
    if "fov" in params and (params.get("fov_axis", "x") == "x"):
        fov = float(params["fov"])
        if not 0.0 < fov < 180.0:
            raise ParameterError(f"fov must be in (0, 180) deg, got {fov!r}")
        focal_px = 0.5 * width / math.tan(math.radians(fov) / 2.0)
    if focal_px is not None or cfg.get("image_acceleration") is None:
        build_plan(cfg, t0, t1, focal_px=focal_px, focus_mm=focus)

    out = {"type": PLUGIN_NAME}
    for k, v in params.items():
        if k in ("centres", "masks") and not isinstance(v, str) and not hasattr(v, "shape"):
            v = np.asarray(v)
        if isinstance(v, np.ndarray):
            v = mi.TensorXf(np.ascontiguousarray(v, dtype=np.float32))
        elif isinstance(v, (list, tuple)) and k in ("centres", "masks"):
            v = mi.TensorXf(np.asarray(v, dtype=np.float32))
        out[k] = v
    return out
