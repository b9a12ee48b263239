"""Relative illumination (natural vignetting): the share of the on-axis irradiance that a film
position receives from a scene of uniform radiance. Numpy only.

A renderer (and Mitsuba's ``thinlens``) returns radiance; a sensor integrates irradiance, which
falls off away from the optical axis. The ``programmable_aperture`` sensor multiplies each
camera ray's weight by the factor of its film position
(:mod:`pacam_render.render.aperture_camera`); this module parses the setting, evaluates the
factor and builds the per-pixel map that a capture records and flat-fields with.

Settings (the plugin's ``relative_illumination``)
--------------------------------------------------
``off``
    1 everywhere: radiance, exactly Mitsuba's ``thinlens`` (the default).
``cos4``
    cos^4 of the chief ray's field angle theta_c, the thin lens's natural vignetting:
    0.610 at the corners of the prototype's 1280x960 frame (27.9 deg).
``FILE``
    A lens's own curve, interpolated linearly (format below; :func:`read_curve`).

Derivation (why the chief ray)
------------------------------
A film point x at distance d behind a thin lens whose pupil P lies in the parallel plane z = 0
receives, from a scene of radiance L (conserved through the lens),

    E(x) = L integral_P cos(theta_f) cos(theta_p) / |x - a|^2 dA(a)
         = (L / d^2) integral_P cos^4 theta(x, a) dA(a),

as cos(theta_f) = cos(theta_p) = d / |x - a| between parallel planes; theta(x, a) is the
image-side angle of the ray from x to the pupil point a. As R / d -> 0 this tends to
(L A / d^2) cos^4 theta_c, theta_c the angle of the chief ray (through the pupil's centre): the
cos^4 law. ``cos4`` applies cos^4 theta_c of the film position, the same factor for every ray
that reaches it:

    w_RI = cos^4 theta_c = (1 + tan^2 theta_c)^-2,   tan^2 theta_c = (x^2 + y^2) / z^2

for any camera-space point (x, y, z) on the chief ray. Not a per-ray angle, because the angle
the integral needs is on the image side of the real camera's exit pupil. The plugin's thin lens
is a scaled stand-in whose image side is at F0.70 where the camera is at F2.8 (PHYSICS.md,
"Wave optics and radiometry"), so its per-ray image-side angle would be wrong; and the
object-side angle a Mitsuba ray carries differs from theta_c by about a / Z (< 0.01 rad):
theta_c plus noise. The factor then depends on the film position alone, so a capture is exactly
the radiance image times the map (pixel-averaged), and dividing by the map (flat-fielding,
:func:`relative_illumination_map`) undoes it, leaving the analytic PSFs valid.

What the chief ray leaves out (:func:`thin_lens_relative_illumination`, the exact integral for a
centred disc pupil at working F-number N = d / 2R): at the 1280x960 frame's corner (27.9 deg)
it exceeds cos^4 theta_c by +2.29 % at F2.8, +0.19 % at F9.85 and +0.07 % at F16; at the
crossover window's far corner (18.4 deg) by +1.14 %, +0.09 % and +0.04 %. At F2.8 that is
0.014 on white = 1, several times the captures' Monte Carlo floor (0.2 x the sensor's
0.0027-0.0094); at F9.85 it is 0.0011, at the floor. For an opening away from the pupil's
centre (the parabolic schedule's 145.5 px disc on the F2.8 LCoS) the exact integral also
depends on where the opening is: at the middle of the frame's left and right edges (23 deg)
-15 % and +22 % of cos^4 for the two ends of the parabola, and, averaged over the exposure,
-4.6 % at one edge and +7.6 % at the other. Those numbers hold for an exit pupil at the lens;
the prototype's LCoS sits in a relay, whose exit pupil no thin lens represents, so a measured
curve (``FILE``) is the way to a real lens.

Curve files
-----------
CSV: ``#`` starts a comment; the first other line is the header, two names, the abscissa
(``height_px``, ``height_mm`` or ``field_deg``) and ``relative_illumination``; then one row of
two numbers per point::

    # my lens at F4
    height_mm,relative_illumination
    0,1.0
    2.0,0.93
    4.2,0.74

JSON: an object with one abscissa key and ``relative_illumination``, two lists of numbers, and
optionally ``"comment"``::

    {"field_deg": [0, 10, 20, 30], "relative_illumination": [1, 0.95, 0.83, 0.66]}

Abscissae: ``height_px``, the distance from the optical axis (the film's centre) in px of the
rendered film; ``height_mm``, the same on the sensor in mm (it needs the pixel pitch, the
plugin's ``pixel_pitch``); ``field_deg``, the chief ray's field angle, deg (< 90). They start
at 0, increase strictly, and must reach the film's farthest corner. Values are finite and
>= 0; they are divided by the value at 0 (so 100 at the centre, i.e. percent, is fine).
Between points the curve is linear in the abscissa; the plugin and the map evaluate it through
the same table of :data:`TABLE_SIZE` entries, uniform in tan theta_c from 0 to the curve's last
point (so a curve that ends far beyond the film's corner is sampled more coarsely on it).

References
----------
.. [1] W. J. Smith, *Modern Optical Engineering*, 4th ed., Sec. 9.8 (cos^4 law).
.. [2] ISETCam, ``opticalimage/optics/cos4th.m``: cos^4 of the chief ray, per pixel.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FileKeyError, ParameterError, check_positive
from ..limits import note
from .optics import focal_length_px

RELATIVE_ILLUMINATION_MODES = ("off", "cos4")
"""The built-in settings; any other value is a curve file's path."""
DEFAULT_RELATIVE_ILLUMINATION = "off"
"""Radiance, exactly Mitsuba's ``thinlens``: the sensor plugin's default (a drop-in for
``thinlens`` in any scene file). A capture's defaults are the spec's
(:data:`~pacam_render.exposure.spec.GEOMETRIC_OPTICS` and, for a camera's captures,
:data:`~pacam_render.exposure.spec.CAMERA_OPTICS`)."""
ABSCISSAE = {"height_px": "px", "height_mm": "mm", "field_deg": "deg"}
"""A curve's abscissa names and their units."""
CURVE_SUFFIXES = (".csv", ".json")
TABLE_SIZE = 4096
"""Entries of the uniform table (in tan theta_c) that a curve is evaluated through."""
VALID = "off, cos4, or the path of a .csv or .json curve file"


@dataclass(frozen=True)
class RelativeIllumination:
    """A parsed ``relative_illumination`` setting (:func:`parse_relative_illumination`).

    Attributes
    ----------
    kind : {"off", "cos4", "curve"}
    source : str
        As given: ``off``, ``cos4`` or the curve file's path.
    abscissa : str or None
        A curve's abscissa, a key of :data:`ABSCISSAE`.
    x, values : numpy.ndarray or None
        A curve's points, ``values`` normalised to 1 at x = 0.
    """

    kind: str
    source: str
    abscissa: str | None = None
    x: np.ndarray | None = None
    values: np.ndarray | None = None

    @property
    def off(self) -> bool:
        return self.kind == "off"

    def knots_tan(self, focal_px: float, pixel_pitch_mm: float | None = None) -> np.ndarray:
        """A curve's abscissae as tan theta_c (f_px is the film's focal length in px,
        (W/2) / tan(fov/2)); ``height_mm`` needs ``pixel_pitch_mm``, the film's pixel pitch."""
        if self.abscissa == "field_deg":
            return np.tan(np.radians(self.x))
        if self.abscissa == "height_px":
            return self.x / check_positive("focal_px", focal_px, "px")
        if pixel_pitch_mm is None:
            raise ParameterError(
                f"relative_illumination {self.source}: a height_mm curve needs the pixel "
                "pitch (the sensor's pixel_pitch, mm) to convert mm into px"
            )
        pitch = check_positive("pixel_pitch", pixel_pitch_mm, "mm")
        return self.x / (pitch * check_positive("focal_px", focal_px, "px"))

    def check_covers(
        self, tan_max: float, focal_px: float, pixel_pitch_mm: float | None = None
    ) -> None:
        """Refuse a curve that stops short of ``tan_max`` (the film's farthest corner).

        Raises
        ------
        ParameterError
            Naming the file, where the curve ends and where the corner is.
        """
        if self.kind != "curve":
            return
        t = self.knots_tan(focal_px, pixel_pitch_mm)
        if t[-1] < tan_max * (1.0 - 1e-6):
            raise ParameterError(
                f"relative_illumination {self.source}: the curve ends at "
                f"{self.x[-1]:g} {ABSCISSAE[self.abscissa]} (field "
                f"{math.degrees(math.atan(t[-1])):.2f} deg), short of the film's farthest "
                f"corner at {_describe(self.abscissa, tan_max, focal_px, pixel_pitch_mm)}: "
                "extend the curve to the corner"
            )

    def table(self, focal_px: float, pixel_pitch_mm: float | None = None) -> np.ndarray:
        """The curve on :data:`TABLE_SIZE` points uniform in tan theta_c, from 0 to its last
        point (what the plugin interpolates in)."""
        t = self.knots_tan(focal_px, pixel_pitch_mm)
        grid = np.linspace(0.0, t[-1], TABLE_SIZE)
        # linear in the curve's own abscissa (px and mm are proportional to tan theta_c)
        x = np.degrees(np.arctan(grid)) if self.abscissa == "field_deg" else grid
        return np.interp(x, self.x if self.abscissa == "field_deg" else t, self.values)

    def factor(
        self,
        tan_theta: np.ndarray,
        focal_px: float | None = None,
        pixel_pitch_mm: float | None = None,
    ) -> np.ndarray:
        """The factor at chief-ray tangents ``tan_theta`` (numpy), as the plugin computes it:
        a curve through :meth:`table`, holding its last value past its last point."""
        t = np.asarray(tan_theta, dtype=float)
        if self.kind == "off":
            return np.ones_like(t)
        if self.kind == "cos4":
            c2 = 1.0 / (1.0 + t * t)
            return c2 * c2
        tab = self.table(focal_px, pixel_pitch_mm)
        t_last = self.knots_tan(focal_px, pixel_pitch_mm)[-1]
        return np.interp(t, np.linspace(0.0, t_last, TABLE_SIZE), tab)


def _describe(abscissa: str, tan: float, focal_px: float, pitch: float | None) -> str:
    if abscissa == "field_deg":
        return f"{math.degrees(math.atan(tan)):.3f} deg"
    px = tan * focal_px
    if abscissa == "height_px":
        return f"{px:.2f} px"
    return f"{px * pitch:.4g} mm ({px:.1f} px)"


def parse_relative_illumination(value) -> RelativeIllumination:
    """The ``relative_illumination`` setting: ``off``, ``cos4`` or a curve file.

    Parameters
    ----------
    value : str, os.PathLike, RelativeIllumination or None
        None means :data:`DEFAULT_RELATIVE_ILLUMINATION`.

    Returns
    -------
    RelativeIllumination

    Raises
    ------
    ParameterError
        Naming ``relative_illumination``, the valid values, and for a file the file and what
        is wrong with it (:func:`read_curve`).

    Examples
    --------
    >>> parse_relative_illumination("cos4").factor([0.0, 1.0]).tolist()
    [1.0, 0.25]
    >>> parse_relative_illumination("cos5")
    Traceback (most recent call last):
    ...
    pacam_render.errors.ParameterError: relative_illumination must be off, cos4, or the path ...
    """
    if isinstance(value, RelativeIllumination):
        return value
    text = DEFAULT_RELATIVE_ILLUMINATION if value is None else str(value).strip()
    if text.lower() in RELATIVE_ILLUMINATION_MODES:
        return RelativeIllumination(text.lower(), text.lower())
    path = Path(text)
    if path.suffix.lower() not in CURVE_SUFFIXES:
        raise ParameterError(f"relative_illumination must be {VALID}; got {text!r}")
    abscissa, x, y = read_curve(path)
    return RelativeIllumination("curve", text, abscissa, x, y)


def read_curve(path: str | Path) -> tuple[str, np.ndarray, np.ndarray]:
    """A relative-illumination curve file (CSV or JSON; format in the module docstring).

    Returns
    -------
    abscissa : str
        ``height_px``, ``height_mm`` or ``field_deg``.
    x, values : numpy.ndarray
        The points, float64; ``values`` divided by the value at x = 0.

    Raises
    ------
    ParameterError
        Naming the file and the problem: missing or unreadable, a bad header or row, fewer
        than two points, abscissae not starting at 0 or not strictly increasing, a field angle
        >= 90 deg, values not finite or < 0, 0 at the centre, or over :data:`MAX_RISE` times
        the centre's (a :class:`~pacam_render.errors.FileKeyError` for the file's contents).
    """
    path = Path(path)
    where = f"relative_illumination file {path}"
    if not path.is_file():
        raise ParameterError(f"{where}: no such file (relative_illumination must be {VALID})")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{where}: cannot be read ({exc})") from None
    try:  # the file's columns and keys, not the command line's flag of the same name
        if path.suffix.lower() == ".json":
            abscissa, x, y = _read_json(text, where)
        else:
            abscissa, x, y = _read_csv(text, where)
        return abscissa, *_check_curve(abscissa, x, y, where)
    except FileKeyError:
        raise
    except ParameterError as exc:
        raise FileKeyError(str(exc)) from None


def _read_json(text: str, where: str):
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParameterError(f"{where}: not valid JSON ({exc})") from None
    except RecursionError:
        raise ParameterError(f"{where}: nested too deep to be a curve") from None
    if not isinstance(doc, dict):
        raise ParameterError(f"{where}: expected a JSON object, got {type(doc).__name__}")
    keys = [k for k in ABSCISSAE if k in doc]
    unknown = set(doc) - set(ABSCISSAE) - {"relative_illumination", "comment"}
    if len(keys) != 1 or "relative_illumination" not in doc or unknown:
        raise ParameterError(
            f"{where}: expected one of {', '.join(ABSCISSAE)} and relative_illumination "
            f"(two lists of numbers; optionally comment), got keys {sorted(doc)}"
        )
    out = []
    for k in (keys[0], "relative_illumination"):
        try:
            out.append(np.asarray(doc[k], dtype=float))
        except (TypeError, ValueError):
            raise ParameterError(f"{where}: {k} must be a list of numbers") from None
        if out[-1].ndim != 1:
            raise ParameterError(f"{where}: {k} must be a list of numbers")
    if len(out[0]) != len(out[1]):
        raise ParameterError(
            f"{where}: {keys[0]} has {len(out[0])} values and relative_illumination "
            f"{len(out[1])}; they must pair up"
        )
    return keys[0], out[0], out[1]


def _read_csv(text: str, where: str):
    rows = [
        (n, line)
        for n, line in enumerate(text.splitlines(), 1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise ParameterError(f"{where}: empty (expected a header and rows)")
    n0, head = rows[0]
    names = [c.strip() for c in next(csv.reader([head]))]
    if len(names) != 2 or names[0] not in ABSCISSAE or names[1] != "relative_illumination":
        raise ParameterError(
            f"{where} line {n0}: the header must be two names, one of "
            f"{', '.join(ABSCISSAE)} then relative_illumination; got {head.strip()!r}"
        )
    x, y = [], []
    for n, line in rows[1:]:
        cells = [c.strip() for c in next(csv.reader([line]))]
        try:
            if len(cells) != 2:
                raise ValueError
            a, b = float(cells[0]), float(cells[1])
        except ValueError:
            raise ParameterError(
                f"{where} line {n}: expected two numbers, got {line.strip()!r}"
            ) from None
        x.append(a)
        y.append(b)
    return names[0], np.array(x, dtype=float), np.array(y, dtype=float)


def _check_curve(abscissa: str, x: np.ndarray, y: np.ndarray, where: str):
    if len(x) < 2:
        raise ParameterError(f"{where}: needs at least two points, got {len(x)}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ParameterError(f"{where}: every value must be a finite number")
    if x[0] != 0.0:
        raise ParameterError(f"{where}: {abscissa} must start at 0 (the axis), got {x[0]:g}")
    if np.any(np.diff(x) <= 0):
        i = int(np.argmax(np.diff(x) <= 0))
        raise ParameterError(
            f"{where}: {abscissa} must increase strictly; point {i + 2} ({x[i + 1]:g}) does "
            f"not exceed point {i + 1} ({x[i]:g})"
        )
    if abscissa == "field_deg" and x[-1] >= 90.0:
        raise ParameterError(f"{where}: field_deg must be < 90, got {x[-1]:g}")
    if np.any(y < 0):
        raise ParameterError(f"{where}: relative_illumination must be >= 0, got {y.min():g}")
    if y[0] <= 0:
        raise ParameterError(
            f"{where}: relative_illumination at {abscissa} = 0 must be > 0 (the curve is "
            "divided by it)"
        )
    return x, _check_rise(y / y[0], where)


MAX_RISE = 10.0
"""The largest relative illumination a curve may reach against its axis value: a lens's falls
off the axis (a pupil that grows with the field lifts it a little above 1); 10x is a curve
whose axis value is wrong (1e-300 made the render's signal overflow after it had run)."""
NOTE_RISE = 1.1
"""Above this against the axis, a curve is noted: unusual for a lens, and worth a look."""


def _check_rise(y: np.ndarray, where: str) -> np.ndarray:
    """``y`` (the curve over its axis value), refused above :data:`MAX_RISE`, noted above
    :data:`NOTE_RISE`."""

    top = float(y.max())
    if top > MAX_RISE:
        raise ParameterError(
            f"{where}: relative_illumination reaches {top:.3g}x its value on the axis, over the "
            f"{MAX_RISE:g}x a lens's curve may (check the value at the axis)"
        )
    said = f"the curve in {where.split(' file ', 1)[-1]} rises to {top:.3g}x its value on the axis"
    if top > NOTE_RISE and said not in _NOTED:  # once: the curve is read more than once
        _NOTED.add(said)
        note(f"{said}, unusual for a lens (its light falls off the axis)")
    return y


_NOTED: set[str] = set()
"""Curve notes said already in this process."""


def film_tangents(
    width: int,
    height: int,
    fov_deg: float,
    crop: tuple[int, int, int, int] | None = None,
    sub: int = 1,
) -> np.ndarray:
    """tan theta_c of film positions: (h, w) pixel centres, or (h, w, sub^2) sub-pixel points.

    Parameters
    ----------
    width, height : int
        The whole film, px; the field of view ``fov_deg`` is horizontal.
    crop : (x, y, w, h), optional
        The rendered window, px.
    sub : int
        Points per pixel along each axis (midpoints of a sub x sub grid).
    """
    f_px = focal_length_px(fov_deg, width)
    x0, y0, w, h = crop if crop is not None else (0, 0, width, height)
    off = (np.arange(sub) + 0.5) / sub
    u = (x0 + np.arange(w)[:, None] + off[None, :] - 0.5 * width) / f_px  # (w, sub)
    v = (y0 + np.arange(h)[:, None] + off[None, :] - 0.5 * height) / f_px  # (h, sub)
    t2 = v[:, None, :, None] ** 2 + u[None, :, None, :] ** 2  # (h, w, sub, sub)
    t = np.sqrt(t2).reshape(h, w, sub * sub)
    return t[..., 0] if sub == 1 else t


def film_tan_max(width: int, height: int, fov_deg: float, crop=None) -> float:
    """tan theta_c at the rendered window's farthest corner (pixel edges, not centres)."""
    f_px = focal_length_px(fov_deg, width)
    x0, y0, w, h = crop if crop is not None else (0, 0, width, height)
    du = max(abs(x0 - 0.5 * width), abs(x0 + w - 0.5 * width))
    dv = max(abs(y0 - 0.5 * height), abs(y0 + h - 0.5 * height))
    return math.hypot(du, dv) / f_px


def cos4_at_film(x_px, y_px, film_px: tuple[int, int], f_px: float) -> np.ndarray:
    """cos^4 of the chief ray at film points ``(x_px, y_px)`` (px from the film's corner, float32
    arrays) of a ``film_px`` (W, H) film with focal length ``f_px``: the plugin's per-ray
    ``cos4`` factor (:mod:`pacam_render.render.kernels.relative_illumination`), float32."""
    W, H = film_px
    r2 = ((x_px - 0.5 * W) ** 2 + (y_px - 0.5 * H) ** 2) / f_px**2
    return (1.0 / (1.0 + r2) ** 2).astype(np.float32)


def relative_illumination_map(
    setting,
    width: int,
    height: int,
    fov_deg: float,
    crop: tuple[int, int, int, int] | None = None,
    pixel_pitch_mm: float | None = None,
    sub: int = 4,
) -> np.ndarray | None:
    """The per-pixel relative illumination of a film: what a capture is multiplied by.

    Each pixel's value is the factor averaged over its area (``sub`` x ``sub`` midpoints): a
    box-filtered render of a uniform-radiance scene, divided by its radiance. For ``cos4``,

        m(i, j) = mean over the pixel of (1 + (u^2 + v^2) / f_px^2)^-2,

    (u, v) px from the film's centre and f_px = (W/2) / tan(fov/2).

    Parameters
    ----------
    setting : str or RelativeIllumination
        ``off``, ``cos4`` or a curve (:func:`parse_relative_illumination`).
    width, height : int
        The whole film, px.
    fov_deg : float
        Horizontal field of view, deg.
    crop : (x, y, w, h), optional
        The rendered window, px.
    pixel_pitch_mm : float, optional
        For a ``height_mm`` curve: the film's pixel pitch, mm.
    sub : int, optional
        Midpoints per pixel along each axis; 4 puts the average within 1e-6 of the exact one on
        the prototype's films.

    Returns
    -------
    numpy.ndarray or None
        (h, w) float64 (1 at the axis), or None for ``off``.

    Examples
    --------
    >>> m = relative_illumination_map("cos4", 1280, 960, 46.0)
    >>> round(float(m[0, 0]), 3), round(float(m.max()), 5)  # corner 27.9 deg; the axis
    (0.609, 1.0)
    """
    ri = parse_relative_illumination(setting)
    if ri.off:
        return None
    f_px = focal_length_px(fov_deg, width)
    ri.check_covers(film_tan_max(width, height, fov_deg, crop), f_px, pixel_pitch_mm)
    t = film_tangents(width, height, fov_deg, crop, sub)
    return ri.factor(t, f_px, pixel_pitch_mm).mean(axis=-1)


def thin_lens_relative_illumination(tan_theta, f_number: float) -> np.ndarray:
    """The exact relative illumination of a thin lens with a centred disc pupil.

    The irradiance at a film point at field angle theta from a Lambertian disc of radius R at
    distance d (the pupil, radiance L; working F-number N = d / 2R, rho = R / d = 1 / 2N,
    h = tan theta):

        E(h) = (pi L / 2) [1 - (1 + h^2 - rho^2) / B],   B = sqrt((1 + h^2 + rho^2)^2 - 4 h^2 rho^2)
             = pi L 2 rho^2 / (B (B + 1 + h^2 - rho^2))   (the same, without cancellation),

    returned as E(h) / E(0), E(0) = pi L rho^2 / (1 + rho^2). It tends to cos^4 theta as
    N -> infinity and exceeds it at finite N (module docstring).

    Parameters
    ----------
    tan_theta : array_like
        tan of the chief ray's field angle.
    f_number : float
        Working F-number of the pupil, d / 2R (> 0).

    Returns
    -------
    numpy.ndarray

    References
    ----------
    .. [1] J. R. Howell, *A Catalog of Radiation Heat Transfer Configuration Factors*,
       B-13: differential element to a parallel coaxial disc, displaced.

    Examples
    --------
    >>> t = math.tan(math.radians(27.9))
    >>> round(float(thin_lens_relative_illumination(t, 2.8) / math.cos(math.radians(27.9)) ** 4), 4)
    1.0229
    """
    rho = 0.5 / check_positive("f_number", f_number)
    h2 = np.asarray(tan_theta, dtype=float) ** 2
    a = 1.0 + h2 - rho * rho
    b = np.sqrt((1.0 + h2 + rho * rho) ** 2 - 4.0 * h2 * rho * rho)
    e = 2.0 * rho * rho / (b * (b + a))
    return e / (rho * rho / (1.0 + rho * rho))


def flat_field(image: np.ndarray, ri_map: np.ndarray | None) -> np.ndarray:
    """A capture divided by its relative-illumination map: irradiance back to radiance.

    ``image`` is (h, w) or (h, w, c) and ``ri_map`` (h, w) (:func:`relative_illumination_map`),
    or None (``off``: ``image`` is returned as it is). Noise is divided by the map too, so it
    grows towards the corners, as in a camera pipeline's flat field. Where the map is 0 (a
    curve that reaches 0: no light) the result is 0.

    Examples
    --------
    >>> flat_field(np.full((2, 2, 3), 0.5), np.full((2, 2), 0.5))[0, 0].tolist()
    [1.0, 1.0, 1.0]
    """
    if ri_map is None:
        return image
    m = np.asarray(ri_map)
    if np.shape(image)[:2] != m.shape[:2]:
        raise ParameterError(
            f"the relative_illumination map is {m.shape[1]}x{m.shape[0]} px, the image "
            f"{np.shape(image)[1]}x{np.shape(image)[0]}: they are not one capture"
        )
    m = m.reshape(m.shape[:2])
    m = m[..., None] if np.ndim(image) == 3 else m
    dtype = np.result_type(image, np.float32)
    out = np.zeros(np.broadcast_shapes(np.shape(image), m.shape), dtype=dtype)
    return np.divide(image, m, out=out, where=m > 0)  # no light (a curve's 0): stays 0
