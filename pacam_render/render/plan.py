"""The host side of the ``programmable_aperture`` sensor: a schedule resolved into plain data.

:func:`build_plan` parses the plugin's parameters once into an :class:`AperturePlan` of numpy
arrays (pbrt-v4's ``Create`` idea: parsing and checking are separate from rendering). The
Mitsuba kernels (:mod:`pacam_render.render.aperture_camera`) read only the plan; nothing here
imports Mitsuba, so plans can be built, checked and tested without a renderer.

Conventions, units and the radiometry are described in :mod:`pacam_render.render.aperture_camera`.
"""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from ..model import schedule as sch
from ..model.optics import LCOS_PITCH_MM
from ..model.paper import N_PATTERNS as DEFAULT_N_PATTERNS
from .masks import MaskTables, build_tables, check_masks, load_masks

SCHEDULES = ("static", "parabolic", "centres", "bitmap", "flutter", "camera_parabolic")
"""The aperture schedules the plugin's ``schedule`` parameter takes."""
TIME_VARYING = ("parabolic", "flutter", "camera_parabolic")  # centres, bitmap: if N > 1
_TOL = 1e-9  # relative tolerance for "opening inside the lens"


def f32_up(x) -> np.ndarray:
    """float32 values >= x (round up): t >= result <=> t >= x for every float32 t."""
    x = np.asarray(x, dtype=np.float64)
    y = x.astype(np.float32)
    low = y.astype(np.float64) < x
    y[low] = np.nextafter(y[low], np.float32(np.inf))
    return y


def index_bias(t_open: float, t_close: float, n: int) -> float:
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
    window_at: float | None = None
    """With a window: the one time every ray takes in it (the window's weight unchanged)."""
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
    def ray_times(self) -> tuple[float, float]:
        """(start, length) of the ray times: the window, the one time in it, or the exposure."""
        a, b = self.integration_interval
        return (a, b - a) if self.window_at is None else (self.window_at, 0.0)

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
        Time window [a, b]: (b - a) / E_ref (rays uniform in the window, or all at its one
        time ``window_at``; closed chops weigh 0).
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

    def mean_weight(self, contrast: float | None = None) -> float:
        """Expected ray weight: the image's scale relative to thinlens (exact). With an LCoS
        of finite ``contrast`` C, an open pattern also passes 1/C of the light on the rest of
        the lens (as the rays do)."""
        a, b = self.integration_interval
        area = self.area_ratio
        if contrast is not None:
            area = np.where(self.is_open, area + (1.0 - area) / float(contrast), 0.0)
        if self.duration <= 0:
            return float(area[0])
        # the open area is constant between these times
        cuts = np.unique(np.clip(np.concatenate([[a, b], self.pattern_edges]), a, b))
        k = self.pattern_at(0.5 * (cuts[:-1] + cuts[1:]))
        collected = float(np.sum(area[k] * np.diff(cuts)))  # ms
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
    n_patterns=None,  # DEFAULT_N_PATTERNS where it matters
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
    tables: MaskTables | None = None,
) -> AperturePlan:
    """Resolve a configuration (the plugin's parameters) into an :class:`AperturePlan`.

    Parameters
    ----------
    cfg : dict
        Plugin parameters (see :data:`PROP_KEYS`); missing ones take :data:`DEFAULTS`.
    t_open, t_close : float
        The shutter interval, ms.
    focal_px, focus_mm : float, optional
        (W/2)/tan(fov/2) and the focus distance; needed only to turn an
        ``image_acceleration`` into a camera acceleration (Levin's a_i(Z_f) = f_px a_c / Z_f).
    tables : MaskTables, optional
        A ``bitmap`` schedule's tables, built and checked for the same masks, pitch and lens.

    Returns
    -------
    AperturePlan

    Raises
    ------
    ParameterError
        Naming the parameter and its valid range.
    """
    c = {**DEFAULTS, **cfg}
    kind = str(c["schedule"]).strip().lower()
    if kind not in SCHEDULES:
        raise ParameterError(f"schedule must be one of {', '.join(SCHEDULES)}, got {kind!r}")
    R_max, R = _radii(c)
    t0, t1 = _exposure(t_open, t_close)
    n_given = c["n_patterns"]
    n = DEFAULT_N_PATTERNS if n_given is None else sch.check_n_patterns(n_given)
    e_ref = _reference_exposure(c, t1 - t0)
    window, window_at = _time_window(c["time_window"], t0, t1)
    if kind in TIME_VARYING:
        _need_time(kind, t0, t1, "by definition")
    continuous = c["continuous"]
    continuous = (kind == "camera_parabolic") if continuous is None else bool(continuous)
    if continuous and kind not in ("parabolic", "camera_parabolic"):
        raise ParameterError(
            f"continuous applies to the parabolic and camera_parabolic schedules, not {kind!r}"
        )
    s = _Shape(n=n, tables=tables if kind == "bitmap" else None)
    _SHAPERS[kind](s, c, kind, R_max, R, 0.5 * (t1 - t0), continuous, (focal_px, focus_mm))
    n = s.n
    if n > 1:
        _need_time(kind, t0, t1, f"{n} patterns")
        index_bias(t0, t1, n)  # raises if float32 ray times cannot tell the patterns apart
    if kind != "bitmap":
        _check_inside(s.centres, R, R_max, "centres" if kind == "centres" else "aperture_radius")
        s.centres = np.broadcast_to(s.centres, (n, 2)).copy() if len(s.centres) != n else s.centres
        s.area = np.full(n, math.pi * R * R) * np.broadcast_to(s.gate, (n,))
    cam_x = np.broadcast_to(s.cam_x, (n,)).copy() if len(s.cam_x) != n else s.cam_x
    return AperturePlan(
        schedule=kind,
        kind="bitmap" if kind == "bitmap" else "disc",
        t_open=t0,
        t_close=t1,
        lens_radius_mm=R_max,
        radius_mm=R,
        n_patterns=n,
        centres_mm=s.centres,
        aperture_quad=s.a_quad,
        camera_x_mm=cam_x,
        camera_quad=s.c_quad,
        area_mm2=np.asarray(s.area, dtype=float),
        reference_exposure=e_ref,
        window=window,
        window_at=window_at,
        continuous=continuous,
        tables=s.tables,
    )


def _radii(c: dict) -> tuple[float, float]:
    """(R_max, R) in mm, checked: the opening inside the lens."""
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
    return R_max, min(R, R_max)


def _exposure(t_open: float, t_close: float) -> tuple[float, float]:
    t0 = check_finite("shutter_open", t_open)
    t1 = check_finite("shutter_close", t_close)
    if t1 - t0 < 0:
        raise ParameterError(f"shutter_close must be >= shutter_open = {t0:g} ms, got {t1:g}")
    return t0, t1


def _reference_exposure(c: dict, dur: float) -> float | None:
    """E_ref, ms; None: the shutter interval."""
    if c["reference_exposure"] is None:
        return None
    e_ref = check_positive("reference_exposure", c["reference_exposure"], "ms")
    if dur <= 0:
        raise ParameterError(
            "reference_exposure needs an exposure: shutter_close must be > shutter_open"
        )
    return e_ref


def _time_window(window, t0: float, t1: float) -> tuple[tuple[float, float] | None, float | None]:
    """The rendered part of the exposure, (start, end) ms inside [t0, t1], or None; and the one
    time its rays take (a third value ``at`` in [start, end]), or None for times uniform in it.
    """
    if isinstance(window, str):
        window = [v for v in re.split(r"[,\s]+", window.strip()) if v] or None
    if window is None:
        return None, None
    try:
        values = [float(v) for v in window]
        if len(values) not in (2, 3):
            raise ValueError
    except (TypeError, ValueError):
        raise ParameterError(
            f"time_window must be (start, end) or (start, end, at) in ms, got {window!r}"
        ) from None
    wa, wb = values[:2]
    eps = 1e-9 * max(1.0, abs(t0), abs(t1))
    if not (t1 - t0 > 0 and t0 - eps <= wa < wb <= t1 + eps):
        raise ParameterError(
            f"time_window must satisfy shutter_open <= start < end <= shutter_close = "
            f"[{t0:g}, {t1:g}] ms, got ({wa:g}, {wb:g})"
        )
    at = values[2] if len(values) == 3 else None
    if at is not None and not wa <= at <= wb:
        raise ParameterError(f"time_window's time must lie in [{wa:g}, {wb:g}] ms, got {at:g}")
    return (max(wa, t0), min(wb, t1)), at


def _need_time(kind: str, t0: float, t1: float, what: str) -> None:
    if not t1 - t0 > 0:
        raise ParameterError(
            f"schedule={kind!r} varies in time ({what}) and needs shutter_close > "
            f"shutter_open (ms), got shutter_open = {t0:g}, shutter_close = {t1:g}: "
            f"Mitsuba would give every ray the same time and the pattern would never change"
        )


def _fixed_n(c: dict, kind: str, count: int, what: str) -> int:
    n_given = c["n_patterns"]
    if n_given is not None and int(n_given) != count:
        raise ParameterError(
            f"n_patterns = {n_given} disagrees with the {count} {what} of schedule={kind!r}"
        )
    return count


@dataclass
class _Shape:
    """The per-pattern geometry a schedule resolves to (filled in by one of ``_SHAPERS``)."""

    n: int
    centres: np.ndarray = field(default_factory=lambda: np.zeros((1, 2)))
    cam_x: np.ndarray = field(default_factory=lambda: np.zeros(1))
    a_quad: float = 0.0
    c_quad: float = 0.0
    gate: np.ndarray = field(default_factory=lambda: np.ones(1, dtype=bool))
    area: np.ndarray | None = None
    tables: MaskTables | None = None


def _shape_static(s: _Shape, c, kind, R_max, R, T, continuous, focal) -> None:
    s.n = 1


def _shape_parabolic(s: _Shape, c, kind, R_max, R, T, continuous, focal) -> None:
    # The parabola runs along local -x, the image's +u axis, so that in film columns the
    # image accelerates by +beta a_a: Eq. 18 with its sign (Eq. 10 in the upright frame).
    a_a = sch.aperture_acceleration(R_max, R, T)  # mm/ms^2
    if continuous:
        s.centres = np.array([[R_max - R, 0.0]])
        s.a_quad, s.n = -0.5 * a_a, 1
    else:
        xs = -sch.pattern_centres_mm(R_max, R, T, s.n)
        s.centres = np.stack([xs, np.zeros(s.n)], axis=1)


def _shape_centres(s: _Shape, c, kind, R_max, R, T, continuous, focal) -> None:
    if c["centres"] is None:
        raise ParameterError("centres: schedule='centres' needs a list of centres (mm)")
    s.centres = parse_centres(c["centres"])
    s.n = _fixed_n(c, kind, len(s.centres), "centres")


def _shape_flutter(s: _Shape, c, kind, R_max, R, T, continuous, focal) -> None:
    s.gate = sch.flutter_code(str(c["flutter_code"]).strip()).astype(bool)
    s.n = _fixed_n(c, kind, len(s.gate), "chops")  # a pattern per chop: the disc, or shut


def _shape_camera_parabolic(s: _Shape, c, kind, R_max, R, T, continuous, focal) -> None:
    a_c = _camera_acceleration(c, *focal)
    if continuous:
        s.cam_x = np.array([-0.25 * a_c * T**2])
        s.c_quad, s.n = 0.5 * a_c, 1
    else:
        tm = sch.pattern_mid_times_ms(T, s.n)
        s.cam_x = a_c * (0.5 * tm**2 - 0.25 * T**2)


def _shape_bitmap(s: _Shape, c, kind, R_max, R, T, continuous, focal) -> None:
    source = c["masks"] if c["masks"] is not None else c["mask_file"]
    if source is None:
        raise ParameterError("masks: schedule='bitmap' needs masks (array) or mask_file")
    if s.tables is None:
        pitch = check_positive("mask_pitch", c["mask_pitch"], "mm")
        masks = load_masks(source)
        check_masks(masks, R_max, pitch)
        s.tables = build_tables(masks, pitch)
    s.n = _fixed_n(c, kind, s.tables.n_patterns, "masks")
    s.area = s.tables.area_mm2
    s.centres = np.zeros((s.n, 2))


_SHAPERS = {
    "static": _shape_static,
    "parabolic": _shape_parabolic,
    "centres": _shape_centres,
    "flutter": _shape_flutter,
    "camera_parabolic": _shape_camera_parabolic,
    "bitmap": _shape_bitmap,
}


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


PROP_KEYS = (
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


_HANDED: dict[str, tuple] = {}  # token -> (what the tables were built from, the tables)
_HANDED_KEPT = 8
_TOKENS = itertools.count()


def hand_over(tables: MaskTables, cfg: dict) -> str:
    """A token for the sampling tables :func:`~.registry.sensor_dict` built from ``cfg`` while
    checking the schedule, which the plugin it describes takes instead of tabulating the masks
    again (a Mitsuba property holds no Python object; 64 full-display masks take 0.5-1.2 s).
    Tokens are never reused: one evicted is rebuilt from its masks."""
    token = f"pacam-mask-tables-{next(_TOKENS)}"
    if len(_HANDED) >= _HANDED_KEPT:
        _HANDED.pop(next(iter(_HANDED)))
    _HANDED[token] = (_source(cfg), tables)
    return token


def handed(token, cfg: dict) -> MaskTables | None:
    """The tables :func:`hand_over` kept for ``token``, if ``cfg`` names the same masks (their
    shape), pitch and lens; else None (tabulate the masks)."""
    kept = _HANDED.get(str(token)) if token else None
    return kept[1] if kept is not None and kept[0] == _source(cfg) else None


def _source(cfg: dict) -> tuple:
    m = cfg.get("masks")
    shape = tuple(int(v) for v in m.shape) if hasattr(m, "shape") else m
    pitch = cfg.get("mask_pitch", LCOS_PITCH_MM)
    return (shape, cfg.get("mask_file"), float(pitch), float(cfg["lens_radius"]))


def config_from_props(props) -> dict:
    cfg = {}
    for key in PROP_KEYS:
        if key in props:
            cfg[key] = props.get(key)
    if "lens_radius" not in cfg:
        raise ParameterError("lens_radius (R_max, mm) is required")
    return cfg


def pad_table(a: np.ndarray, n: int = 2) -> np.ndarray:
    """At least n entries: a gather from a 1-element array is folded into a different kernel."""
    a = np.asarray(a)
    if len(a) >= n:
        return a
    fill = a[-1] if len(a) else 0
    return np.concatenate([a, np.full(n - len(a), fill, dtype=a.dtype)])
