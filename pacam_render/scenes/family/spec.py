"""The families and their parameters: :data:`FAMILIES`, :data:`FAMILY_VERSION`, the defaults
of each family (:func:`default_params`), their validation (:func:`resolve_params`) and
scene names of the form ``family:NAME:SEED`` (:func:`parse_family_name`).

Every parameter is checked before any drawing, with a :class:`~pacam_render.errors.ParameterError`
that names it and its valid range; nothing is clamped.
"""

from __future__ import annotations

from typing import Any

from ...errors import ParameterError, check_finite, check_integer, check_range, did_you_mean
from ...model.camera import MIN_FOCUS_MM, CameraDesign, prototype

FAMILY_VERSION = 2
"""The version of the drawing rules: a scene's card records it, and the asset cache keys on it.
Raise it whenever the same seed and parameters would draw a different scene, or write it
differently. 2: cylinders as an exact matrix (1 wrote ``p0``/``p1``, whose float32 frame made
Mitsuba warn of shear for some lengths; the same geometry to 1e-7)."""

FAMILY_PREFIX = "family:"
"""How a family scene is named where a scene is taken: ``family:NAME:SEED``."""

TEXTURE_SOURCES = ("procedural", "photos")
"""Where the textures come from: seeded numpy patterns, or scikit-image's bundled photographs."""

MAX_OBJECTS = 12
"""The most objects a scene may hold."""

MIN_WINDOW_PX = 16
"""The smallest window side, px."""

MIN_SIZE_PX = 4.0
"""The smallest object size, px at the camera's scale."""

_COMMON = {
    "size_range_px": (40.0, 120.0),
    "direction_spread_deg": 0.0,
    "textures": "procedural",
    "window": (480, 360, 320, 240),
}
FAMILIES: dict[str, dict[str, Any]] = {
    "occluders": {
        **_COMMON,
        "depth_range_mm": (400.0, 900.0),
        "speed_range_px_per_ms": (0.2, 1.4),
        "object_count": (2, 6),
        "wall_depth_mm": 1000.0,
    },
    "depths": {
        **_COMMON,
        "depth_range_mm": (250.0, 2500.0),
        "speed_range_px_per_ms": (0.0, 0.3),
        "object_count": (3, 6),
        "wall_depth_mm": 3000.0,
    },
    "still": {
        **_COMMON,
        "depth_range_mm": (400.0, 900.0),
        "speed_range_px_per_ms": (0.0, 0.0),
        "object_count": (2, 6),
        "wall_depth_mm": 1000.0,
    },
}
"""Each family's default parameters, which suit the prototype (1280x960, 2T = 45 ms):

- ``occluders``: objects at depths uniform in ``depth_range_mm``, moving, with at least one
  occlusion inside the window during the exposure, guaranteed;
- ``depths``: objects at depths uniform in inverse depth (dioptres, so defocus is spread
  evenly) over a wide range, slow or still;
- ``still``: nothing moves (``speed_range_px_per_ms`` must stay (0, 0)): the control.
"""

DEPTH_SAMPLING = {"occluders": "uniform", "depths": "inverse", "still": "uniform"}
"""How each family draws depths in ``depth_range_mm``: uniform in depth or in inverse depth."""


def family_camera() -> CameraDesign:
    """The camera whose scale the parameters are in: the prototype (1280x960, its exposure)."""
    return prototype()


def check_family(family: object) -> str:
    """``family`` if it is a known family, else an error listing them."""
    if family not in FAMILIES:
        raise ParameterError(
            f"unknown `family` {family!r}{did_you_mean(family, FAMILIES)}; valid: "
            f"{', '.join(FAMILIES)}"
        )
    return str(family)


def check_seed(seed: object) -> int:
    """``seed`` as an int if it is a non-negative integer (a numeral string is accepted)."""
    if isinstance(seed, str) and seed.strip().isdigit():
        seed = int(seed.strip())
    return check_integer("seed", seed, 0, 2**63 - 1)


def parse_family_name(name: str) -> tuple[str, int]:
    """The family and the seed of a scene name ``family:NAME:SEED``.

    Parameters
    ----------
    name : str
        E.g. ``"family:occluders:12"``.

    Returns
    -------
    tuple of (str, int)
        The family's name and the seed.

    Raises
    ------
    ParameterError
        If the name is not of that form, the family is unknown, or the seed is not a
        non-negative integer.

    Examples
    --------
    >>> parse_family_name("family:occluders:12")
    ('occluders', 12)
    """
    text = str(name)
    parts = text.split(":")
    if not text.startswith(FAMILY_PREFIX) or len(parts) != 3:
        raise ParameterError(
            f"a family scene is named family:NAME:SEED (e.g. family:occluders:12), got {text!r}"
        )
    family = check_family(parts[1])
    if not parts[2].strip().isdigit():
        raise ParameterError(
            f"the seed of scene {text!r} must be a non-negative integer, got {parts[2]!r}"
        )
    return family, check_seed(parts[2])


MAX_SEEDS_LISTED = 10_000
"""The most seeds one ``family:NAME:FIRST-LAST`` range may list."""


def family_seeds(name: str) -> list[str]:
    """The scene names a ``family:NAME:FIRST-LAST`` range lists (inclusive), or ``[name]``.

    Examples
    --------
    >>> family_seeds("family:occluders:3-5")
    ['family:occluders:3', 'family:occluders:4', 'family:occluders:5']
    >>> family_seeds("family:still:7")
    ['family:still:7']
    """
    head, _, tail = name.rpartition(":")
    if not is_family_name(name) or "-" not in tail:
        return [name]
    first, _, last = tail.partition("-")
    if not (first.isdigit() and last.isdigit()) or int(last) < int(first):
        raise ParameterError(
            f"a family range is family:NAME:FIRST-LAST with integers FIRST <= LAST, got {name!r}"
        )
    if int(last) - int(first) + 1 > MAX_SEEDS_LISTED:
        raise ParameterError(f"{name!r} lists more than {MAX_SEEDS_LISTED} seeds")
    names = [f"{head}:{s}" for s in range(int(first), int(last) + 1)]
    parse_family_name(names[0])  # the family itself is known
    return names


def is_family_name(name: object) -> bool:
    """Whether ``name`` is meant as a family scene (starts with ``family:``)."""
    return isinstance(name, str) and name.startswith(FAMILY_PREFIX)


def _pair(name: str, value: Any, unit: str) -> tuple[float, float]:
    """(lo, hi) from a 2-sequence of finite numbers with lo <= hi."""
    try:
        lo, hi = (check_finite(name, v) for v in value)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ParameterError):
            raise
        raise ParameterError(f"{name} must be (min, max) in {unit}, got {value!r}") from None
    if lo > hi:
        raise ParameterError(f"{name} must be (min, max) with min <= max {unit}, got {value!r}")
    return lo, hi


def _window(value: Any, cam: CameraDesign) -> tuple[int, int, int, int]:
    """(x, y, w, h): integers, inside the camera's sensor, each side >= MIN_WINDOW_PX."""
    W, H = cam.width_px, cam.height_px
    what = f"`window` must be (x, y, w, h) px inside the {W}x{H} sensor"
    try:
        x, y, w, h = value
    except (TypeError, ValueError):
        raise ParameterError(f"{what}, got {value!r}") from None
    x, y = check_integer("`window` x", x, 0, W - 1), check_integer("`window` y", y, 0, H - 1)
    w = check_integer("`window` w", w, MIN_WINDOW_PX, W - x)
    h = check_integer("`window` h", h, MIN_WINDOW_PX, H - y)
    return x, y, w, h


def _count(value: Any) -> tuple[int, int]:
    """(min, max) object counts, integers in 1..MAX_OBJECTS with min <= max."""
    try:
        lo, hi = value
    except (TypeError, ValueError):
        raise ParameterError(f"object_count must be (min, max), got {value!r}") from None
    lo = check_integer("object_count min", lo, 1, MAX_OBJECTS)
    hi = check_integer("object_count max", hi, lo, MAX_OBJECTS)
    return lo, hi


def _check_speeds(family: str, p: dict, cam: CameraDesign) -> None:
    """Speeds >= 0, (0, 0) for ``still``, and slow enough for the window to show the motion."""
    lo, hi = p["speed_range_px_per_ms"]
    if lo < 0:
        raise ParameterError(
            f"speed_range_px_per_ms must be >= 0 px/ms (magnitudes: both signs are drawn), "
            f"got {p['speed_range_px_per_ms']!r}"
        )
    if family == "still" and hi > 0:
        raise ParameterError(
            f"speed_range_px_per_ms must be (0, 0) for family 'still' (nothing moves), got "
            f"{p['speed_range_px_per_ms']!r}; use 'depths' or 'occluders' for motion"
        )
    if family == "occluders" and hi <= 0:
        raise ParameterError(
            "speed_range_px_per_ms must have max > 0 px/ms for family 'occluders' (an object "
            "passes in front of another), got (0, 0)"
        )
    x, y, w, h = p["window"]
    side = w if p["direction_spread_deg"] == 0 else min(w, h)
    most = side / cam.exposure_ms
    if hi > most:
        raise ParameterError(
            f"speed_range_px_per_ms max must be <= {most:.4g} px/ms: the {w}x{h} px window "
            f"cannot show an object moving {hi:g} px/ms x {cam.exposure_ms:g} ms = "
            f"{hi * cam.exposure_ms:.4g} px (more than its {side} px side); widen the window"
        )


def _check_depths(p: dict, cam: CameraDesign) -> None:
    """Depths at or beyond the lens's closest focus, and a wall behind every object."""
    lo, hi = p["depth_range_mm"]
    if lo < MIN_FOCUS_MM:
        raise ParameterError(
            f"depth_range_mm must be >= {MIN_FOCUS_MM:g} mm (in front of the camera, no closer "
            f"than the lens's closest focus), got {p['depth_range_mm']!r}"
        )
    far_mm = hi + 0.5 * p["size_range_px"][1] * hi / cam.focal_length_px
    if p["wall_depth_mm"] <= far_mm:
        raise ParameterError(
            f"wall_depth_mm must be > {far_mm:.5g} mm (behind the farthest object's back: depth "
            f"{hi:g} mm plus half its largest size), got {p['wall_depth_mm']!r}"
        )


def resolve_params(family: str, **params) -> dict:
    """The family's defaults updated with ``params``, every value checked and normalised.

    Parameters
    ----------
    family : str
        A key of :data:`FAMILIES`.
    **params
        Any of ``depth_range_mm``, ``speed_range_px_per_ms``, ``object_count``,
        ``size_range_px``, ``direction_spread_deg``, ``textures``, ``wall_depth_mm`` and
        ``window`` (see :data:`FAMILIES`).

    Returns
    -------
    dict
        All parameters, ranges as tuples of floats (counts and the window as ints).

    Raises
    ------
    ParameterError
        Naming the first parameter that is unknown or out of its range.
    """
    family = check_family(family)
    defaults = FAMILIES[family]
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        raise ParameterError(
            f"unknown family parameter {unknown[0]!r}{did_you_mean(unknown[0], defaults)}; "
            f"valid: {', '.join(sorted(defaults))}"
        )
    raw = {**defaults, **{k: v for k, v in params.items() if v is not None}}
    cam = family_camera()
    p = {
        "window": _window(raw["window"], cam),
        "object_count": _count(raw["object_count"]),
        "depth_range_mm": _pair("depth_range_mm", raw["depth_range_mm"], "mm"),
        "speed_range_px_per_ms": _pair(
            "speed_range_px_per_ms", raw["speed_range_px_per_ms"], "px/ms"
        ),
        "size_range_px": _pair("size_range_px", raw["size_range_px"], "px"),
        "direction_spread_deg": check_range(
            "direction_spread_deg", raw["direction_spread_deg"], 0.0, 90.0, "deg"
        ),
        "wall_depth_mm": check_finite("wall_depth_mm", raw["wall_depth_mm"]),
        "textures": _textures(raw["textures"]),
    }
    if family == "occluders" and p["object_count"][0] < 2:
        raise ParameterError(
            f"object_count min must be >= 2 for family 'occluders' (one passes in front of "
            f"another), got {p['object_count']!r}"
        )
    _check_sizes(p)
    _check_speeds(family, p, cam)
    _check_depths(p, cam)
    return p


def _check_sizes(p: dict) -> None:
    lo, hi = p["size_range_px"]
    x, y, w, h = p["window"]
    if lo < MIN_SIZE_PX or hi > min(w, h):
        raise ParameterError(
            f"size_range_px must lie in [{MIN_SIZE_PX:g}, {min(w, h)}] px (the window's smaller "
            f"side), got {p['size_range_px']!r}"
        )


def _textures(value: object) -> str:
    if value not in TEXTURE_SOURCES:
        raise ParameterError(
            f"`textures` must be one of {', '.join(TEXTURE_SOURCES)}, got {value!r}"
        )
    if value == "photos" and not photos_available():
        raise ParameterError(
            "`textures` 'photos' needs scikit-image (pip install scikit-image); use 'procedural'"
        )
    return str(value)


def photos_available() -> bool:
    """Whether scikit-image, whose bundled photographs the ``photos`` textures use, imports."""
    try:
        import skimage.data  # noqa: F401  (a third-party package, not ours)
    except ImportError:
        return False
    return True


def default_params(family: str) -> dict:
    """The family's default parameters, checked (:func:`resolve_params` with none given)."""
    return resolve_params(family)


def params_to_json(params: dict) -> dict:
    """Parameters as JSON values (tuples as lists), for the card and the cache key."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in sorted(params.items())}
