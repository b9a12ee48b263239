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
``time_window``      "start, end" (ms): render only this part of the exposure, or
                     "start, end, at": every ray at time ``at`` in it (see :meth:`configure`)
``near_clip``, ``far_clip``  as thinlens (defaults 0.01 and 10000 scene units, near < far)
``relative_illumination`` ``off`` (default: radiance, exactly thinlens) | ``cos4`` | the path
                     of a ``.csv`` or ``.json`` curve (see Radiometry)
``pixel_pitch``      the film's pixel pitch, mm: needed by a ``height_mm`` curve and by
                     diffraction
``diffraction_wavelengths`` nm, one per colour channel (``"611, 549, 464"`` RGB, one value
                     mono): each ray's film position is moved by a draw from the disc
                     opening's Airy pattern (see Diffraction); absent: no diffraction
``lcos_contrast``    the LCoS's contrast ratio C >= 1 (default inf, ideal): the lens outside the
                     disc opening passes 1/C of the light (disc schedules: static, parabolic,
                     centres); 1 is the full aperture
``lcos_fill_factor`` the LCoS pixels' linear fill factor in (0, 1] (default 1): with diffraction,
                     the pixel grid's orders m at m lambda D / ``mask_pitch`` px, f sinc^2(m f)
                     of the light each; the display passes f^2
``lcos_switching``   ms (default 0): the first ``lcos_switching`` of each pattern's window
                     changes linearly from the previous pattern (discrete parabolic, centres)
``pupil_distance``   D = 2 F_min R_max, mm: the pupil's distance, which with the opening's
                     radius sets the F-number D / 2R of the Airy pattern (with diffraction)
==================== ======================================================================

Conventions (see also PHYSICS.md)
---------------------------------
* The aperture plane is the camera's local z = 0 plane (Mitsuba camera space: +z forward, +y up,
  +x to the image's *left*: Mitsuba's perspective projection flips x and y, so the rendered image
  is upright and not mirrored). Aperture coordinates (X_a, Y_a) are along local +x and +y.
  Film column u (px) grows to the image's right, i.e. along local -x.
* With these, the paper's Eq. 8 holds with the paper's image x read as the film column u:
  an opening displaced by X_a shifts the image of a point at depth Z by ``-beta_px * X_a`` px,
  beta_px = (1/Z_f - 1/Z) (W/2)/tan(fov/2) (:func:`pacam_render.model.optics.beta_px_per_mm`).
  The parabolic schedule runs along the image's +u axis (local -x): its local centre is
  -(a_a t^2/2 - (R_max - R)), so the image accelerates by ``+beta_px * a_a`` in film columns:
  the a_i of Eq. 18 with its sign, as Eq. 10 states it in the upright image frame that
  :mod:`pacam_render.model.optics` uses, and as :func:`pacam_render.psf.design_psf` draws it.
* ``camera_parabolic`` (Levin et al. 2008): the camera body translates along its local +x axis
  by X_c(t) = a_c (t^2/2 - T^2/4) mm (centred like the aperture parabola), the aperture is a
  centred disc of radius R, and the lens stays focused at ``focus_distance``. A static point at
  depth Z then moves on the film by ``+f_px X_c(t) / Z`` px: image acceleration
  a_i(Z) = f_px a_c / Z, with f_px = (W/2)/tan(fov/2).
* Masks (``bitmap``): see :mod:`pacam_render.render.masks` for their orientation (the display
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

Relative illumination (natural vignetting): with ``relative_illumination`` other than ``off``
each ray's weight is also multiplied by the factor of its film position, w_RI, the same in
``sample_ray`` and ``sample_direction``. ``cos4``: w_RI = cos^4 theta_c, theta_c the angle of the
film position's chief ray (through the lens centre) to the axis,

    w_RI = (z^2 / (x^2 + y^2 + z^2))^2   for any camera-space point (x, y, z) on that ray,

so it tends to 0, never NaN, towards 90 deg. A curve file (relative illumination against
``height_px``, ``height_mm`` or ``field_deg``) is interpolated linearly. Why the chief ray and
not each ray's own angle, the format of the files and the exact thin-lens integral's departure
from cos^4 (+2.3 % at the 1280x960 frame's corner at F2.8): :mod:`pacam_render.model.illumination`.
The image is then irradiance relative to the axis, exactly the radiance image times the map
:func:`~pacam_render.model.illumination.relative_illumination_map` (a function of the film
position alone). ``off`` leaves the kernels as they were: ray for ray thinlens.

LCoS contrast
-------------
With ``lcos_contrast`` C, the display's "off" pixels leak: the transmittance is 1 in the disc
and 1/C on the rest of the lens, so the image is (1 - 1/C) x the coded image + (1/C) x the
full aperture's over the same exposure. Each ray's aperture sample picks, with probability p
(the leak's share of the light, at least 5 %), a uniform point on the whole lens, weighing
(1/C) x the full lens's weight / p outside the disc and 0 inside it; otherwise the disc's
point, weighing 1 / (1 - p). The split of the sample keeps both branches stratified.

LCoS grid and switching
-----------------------
With ``lcos_fill_factor`` f < 1 (and diffraction), each ray also draws the grid's order
(m_x, m_y) by its inverse CDF on each axis and moves m lambda_c D / pitch px further; a ghost
(m != 0) lands only where its channel's light goes, so it weighs 3 on the drawn channel and
0 on the others (the zero order keeps the Airy weights); the weight carries the transmission
f^2. With ``lcos_switching`` t, a ray in the first t of pattern k's window (tau into it) sees
pattern k - 1 with probability 1 - tau / t, the pixels' linear change; the display shows
pattern 0 before the exposure.

Diffraction
-----------
With ``diffraction_wavelengths``, a ray through film position x carries the radiance seen
from x + d, d drawn from the opening's Airy pattern (lambda N px, N = D / 2R): the film then
integrates the geometric image convolved with the continuous Airy pattern, so an in-focus
point renders as the pixel-integrated Airy pattern, while defocus, motion and occlusion stay
the rays'. One pattern serves every disc schedule (a shifted disc diffracts alike); a bitmap
schedule is refused (its captures are diffracted after the render, per pattern window). In
RGB a channel is drawn per ray and each channel weighted by its pattern's density over the
mixture's; particle tracing moves the landing film position the same way. Tables, random
numbers and their cost: :mod:`pacam_render.render.ray_diffraction`.

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
axis and z the point's depth: exactly ``thinlens`` for the full opening (times w_RI of the film
position, when a relative illumination is on).

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

The kernels' named pieces have modules of their own, whose methods the class binds (a nanobind
type takes one base): the schedule look-up, a ray's time to its pattern and that pattern's
weight, centre and camera offset (:mod:`.schedule_lookup`); the aperture sampling, a point of the
disc or bitmap opening (:mod:`.aperture_sampling`); the relative illumination
(:mod:`.relative_illumination`); the LCoS's flaws and the opening's diffraction
(:mod:`.aperture_optics`); and the Dr.Jit types and helpers they share (:mod:`.types`).

Mitsuba's sensor contract
-------------------------
The sensor behaves as ``thinlens`` wherever Mitsuba's own sensor tests use one: the methods take
Python numbers, lists and tuples (``sample_ray(0, 0, [0.5, 0.5], [0.5, 0.5])``) and convert them
as the C++ bindings do; ``near_clip()``, ``far_clip()`` and ``focus_distance()`` are methods;
``bbox()`` works in every variant; ``mi.traverse`` exposes ``near_clip``, ``far_clip`` and
``x_fov`` (deg) besides ``to_world``, ``focus_distance`` and the swept scalars, and every
``params.update()`` rebuilds the projection from the film as it then is, so a crop or film size
changed at run time renders exactly what the same film given at load time renders. As for
thinlens, ``eval``, ``pdf_direction`` and ``sample_position`` are not implemented.

Known Mitsuba 3.9.1 limitation: with ``ptracer``, light leaving a *textured* area emitter carries
time = shutter_open (its position sampling drops the time), so every such particle sees the
first pattern. Uniform emitters, reflected light and the ``path`` integrator are unaffected.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..errors import ParameterError, check_finite, check_positive
from ..model.optics import focal_length_px
from .kernels.aperture_optics import LCoSOptics
from .kernels.aperture_sampling import ApertureSampling
from .kernels.defocus_draw import ExactDefocus
from .kernels.relative_illumination import RelativeIllumination
from .kernels.schedule_lookup import ScheduleLookup
from .kernels.types import (
    JIT,
    VARIANT,  # noqa: F401 - the registry reads it here
    Float,
    Point2f,
    Point3f,
    Vector3f,
    as_type,
    first,
    gather,
    held,
    make_opaque,
    opaque_scalar,
    traversable,
)
from .plan import PROP_KEYS, AperturePlan, build_plan, config_from_props, handed

PROJECTION_KEYS = ("x_fov", "near_clip", "far_clip")
"""Traversed parameters of the projection (as Mitsuba's projective cameras expose them)."""
_MASK_KEYS = {"schedule", "masks", "mask_file", "mask_pitch", "lens_radius"}
"""What a bitmap schedule's sampling tables depend on: ``configure`` keeps them otherwise."""


class ProgrammableApertureCamera(mi.Sensor):
    """Thin-lens camera with a programmable aperture (see the module docstring)."""

    # The kernels' named pieces live in their own modules; nanobind types take a single base,
    # so their methods are bound here rather than inherited.
    # The schedule look-up (:mod:`.schedule_lookup`): time -> pattern, weight, centre, camera.
    _set_schedule = ScheduleLookup._set_schedule
    _time_and_pattern = ScheduleLookup._time_and_pattern
    _pattern = ScheduleLookup._pattern
    _weight_at = ScheduleLookup._weight_at
    _camera_x = ScheduleLookup._camera_x
    _centre = ScheduleLookup._centre
    # The aperture sampling (:mod:`.aperture_sampling`): a point of the disc or bitmap opening.
    _set_openings = ApertureSampling._set_openings
    _aperture = ApertureSampling._aperture
    _rec = ApertureSampling._rec
    _sample_mask = ApertureSampling._sample_mask
    # The relative illumination (:mod:`.relative_illumination`): the film position's factor.
    _set_illumination = RelativeIllumination._set_illumination
    _illumination = RelativeIllumination._illumination
    # The LCoS's flaws and the opening's diffraction (:mod:`.aperture_optics`).
    _leaky_aperture = LCoSOptics._leaky_aperture
    _set_switching = LCoSOptics._set_switching
    _check_switching = LCoSOptics._check_switching
    _switched = LCoSOptics._switched
    _set_contrast = LCoSOptics._set_contrast
    _update_contrast = LCoSOptics._update_contrast
    _set_diffraction = LCoSOptics._set_diffraction
    _set_grid = LCoSOptics._set_grid
    _update_diffraction = LCoSOptics._update_diffraction
    _diffraction_text = LCoSOptics._diffraction_text
    _diffraction_draw = LCoSOptics._diffraction_draw
    _grid_draw = LCoSOptics._grid_draw
    # The exact defocused PSF in the rays (:mod:`.defocus_draw`).
    _set_defocus = ExactDefocus._set_defocus
    _exact_defocus_on = ExactDefocus._exact_defocus_on
    _landing = ExactDefocus._landing
    _defocus_landing = ExactDefocus._defocus_landing
    set_probe_scene = ExactDefocus.set_probe_scene
    _exact_ray_on = ExactDefocus._exact_ray_on
    _blur_radius_px = ExactDefocus._blur_radius_px
    _probe_depth = ExactDefocus._probe_depth
    _exact_jitter = ExactDefocus._exact_jitter
    _hashed = ExactDefocus._hashed
    _defocus_radius = ExactDefocus._defocus_radius
    _defocus_draw = ExactDefocus._defocus_draw
    _row = ExactDefocus._row
    _defocus_quantile = ExactDefocus._defocus_quantile
    _defocus_pdf = ExactDefocus._defocus_pdf

    def __init__(self, props):
        mi.Sensor.__init__(self, props)
        size = self.film().size()
        self._set_projection(
            mi.parse_fov(props, size.x / size.y),
            props.get("near_clip", 1e-2),
            props.get("far_clip", 1e4),
        )
        focus = props.get("focus_distance", self._far_clip)
        self.m_needs_sample_3 = True
        self._update_projection()

        self._to_world = mi.AffineTransform4f(self.m_to_world)
        self._check_to_world()
        self._focus = opaque_scalar(check_positive("focus_distance", focus, "mm"))
        self._traversed_cfg = {}
        # the exposure as written (double precision); Mitsuba keeps float32 copies
        t_open = float(props.get("shutter_open", self.shutter_open()))
        t_close = float(props.get("shutter_close", t_open + self.shutter_open_time()))
        self._exposure = (t_open, t_close)
        self._cfg = config_from_props(props)
        token = props.get("mask_tables", "") if "mask_tables" in props else None
        tables = handed(token, self._cfg)
        self._set_plan(self._build(self._cfg, tables=tables))
        self._sync_traversed()
        self._set_illumination(props)
        self._set_diffraction(props)
        self._set_defocus()
        self._set_contrast(props)
        self._set_switching(props)

    # ---------------------------------------------------------------- projection
    def _set_projection(self, x_fov, near, far):
        """Check and set the field of view (deg) and the clip planes (scene units).

        Raises :class:`ParameterError` (nothing changed) unless 0 < x_fov < 180 and
        0 < near < far, as Mitsuba's projective cameras require. Call
        :meth:`_update_projection` after it.
        """
        x_fov = check_finite("x_fov", x_fov)
        if not 0.0 < x_fov < 180.0:
            raise ParameterError(f"x_fov (the horizontal fov) must be in (0, 180) deg, got {x_fov}")
        near = check_positive("near_clip", near)
        far = check_positive("far_clip", far)
        if not near < far:
            raise ParameterError(f"near_clip ({near:g}) must be smaller than far_clip ({far:g})")
        self._x_fov, self._near_clip, self._far_clip = x_fov, near, far
        self._near = opaque_scalar(near)  # the kernels' copies: a new value never recompiles
        self._far = opaque_scalar(far)

    def _update_projection(self):
        """(Re)build the projection from the film as it is now (size, crop size and offset),
        the field of view and the clip planes, as thinlens' ``update_camera_transforms``.

        Called at load time and on every ``parameters_changed``: a crop or film size changed
        through ``mi.traverse`` then renders what the same film given at load time renders.
        The sensor's values are opaque (a new fov or clip plane recompiles nothing), but
        Mitsuba's integrators bake the film's crop into their kernels: a new crop or film size
        recompiles them, with thinlens too.
        """
        film = self.film()
        size, crop = film.size(), film.crop_size()
        self._resolution = mi.ScalarVector2f(crop)
        self._focal_px = focal_length_px(float(self._x_fov), int(size.x))
        proj = mi.perspective_projection(
            size, crop, film.crop_offset(), self._x_fov, self._near_clip, self._far_clip
        )
        self._camera_to_sample = mi.ProjectiveTransform4f(proj)
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

    def _build(self, cfg: dict, changed=(), tables=None) -> AperturePlan:
        """The plan of ``cfg``; a bitmap's tables are kept while the masks, their pitch and
        the lens stay (``changed`` names what a ``configure`` changes), or taken as built
        (``tables``)."""
        old = getattr(self, "_plan", None)
        if tables is None and old is not None and not set(changed) & _MASK_KEYS:
            tables = old.tables
        return build_plan(
            cfg, *self._exposure, focal_px=self._focal_px, focus_mm=first(self._focus),
            tables=tables,
        )  # fmt: skip

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
        ``time_window=(start, end, at)`` gives every ray the time ``at`` and the window's
        weight: with the scene posed at ``at`` too, a uniform random ``at`` makes the window's
        image an unbiased estimate of the moving scene's (the captures' stratified time steps).
        """
        focus = changes.pop("focus_distance", None)
        unknown = set(changes) - set(PROP_KEYS)
        if unknown:
            raise ParameterError(
                f"configure: unknown parameter(s) {sorted(unknown)}; valid: "
                f"{', '.join(PROP_KEYS)}, focus_distance"
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
            plan = self._build(cfg, changes)
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

    def focus_distance(self) -> float:
        """Distance from the lens to the plane in focus (mm), as thinlens' method."""
        return first(self._focus)

    def near_clip(self) -> float:
        """Distance to the near clip plane (scene units), as Mitsuba's projective cameras."""
        return self._near_clip

    def far_clip(self) -> float:
        """Distance to the far clip plane (scene units), as Mitsuba's projective cameras."""
        return self._far_clip

    def _set_plan(self, plan: AperturePlan):
        self._plan = plan
        self._features = plan.kernel_features
        self._set_schedule(plan)  # the look-up's tables (:mod:`.schedule_lookup`)
        self._set_openings(plan)  # the disc's radius, a bitmap's runs (:mod:`.aperture_sampling`)
        # camera travel, for bbox()
        ts = np.linspace(plan.t_open, plan.t_close, 4 * plan.n_patterns + 1)
        xs = plan.camera_offset_at(ts)
        self._travel = (float(np.min(xs)), float(np.max(xs)))
        if getattr(self, "_diff", None) is not None:
            self._update_diffraction(plan)
        if getattr(self, "_leak", None) is not None:
            self._update_contrast(plan)
        if getattr(self, "_switch", None) is not None:
            self._check_switching(plan)

    # ---- traversal: to_world, the projection and the swept scalars
    def _sync_traversed(self):
        """Write the current values into the holders that ``mi.traverse`` exposes."""
        p = self._plan
        c = self._cfg
        vals = {
            "aperture_radius": p.radius_mm,
            "lens_radius": p.lens_radius_mm,
            "focus_distance": first(self._focus),
            "camera_acceleration": float(c.get("camera_acceleration") or 0.0)
            if c.get("image_acceleration") is None
            else float(c["image_acceleration"]) * first(self._focus) / self._focal_px,
            "x_fov": self._x_fov,
            "near_clip": self._near_clip,
            "far_clip": self._far_clip,
        }
        for k, v in vals.items():
            if k in self._traversed_cfg:
                mi.set_property(self._traversed_cfg[k], traversable(v))
            else:
                self._traversed_cfg[k] = traversable(v)
        # as held (float32): a value read back unchanged is not a change
        self._traversed_vals = {k: held(h) for k, h in self._traversed_cfg.items()}

    def traverse(self, callback):
        """Expose, besides Mitsuba's sensor parameters (shutter, film, sampler), ``to_world``,
        the projection's ``near_clip``, ``far_clip`` and ``x_fov`` (as Mitsuba's projective
        cameras do), ``focus_distance``, ``aperture_radius``, ``lens_radius`` and
        ``camera_acceleration``; all non-differentiable. Values are ``Float`` holders in JIT
        variants and one-element ``Array1f`` in scalar ones."""
        super().traverse(callback)
        flags = mi.ParamFlags.NonDifferentiable
        callback.put("to_world", self._to_world, flags)
        for k, v in self._traversed_cfg.items():
            callback.put(k, v, flags)

    def parameters_changed(self, keys):
        """Apply changes made through ``mi.traverse``: ``to_world``, the film (crop, size),
        the projection, the shutter and the swept scalars.

        The projection is rebuilt on every call, as thinlens does, so a run-time crop or
        film size renders as if given at load time. A bad value raises
        :class:`ParameterError` and changes nothing of ours (the film's own change stands,
        and the projection follows it).
        """
        super().parameters_changed(keys)
        old_tw = mi.AffineTransform4f(self._from_world.inverse())
        if not keys or "to_world" in keys:
            try:
                self._check_to_world()
            except ParameterError:
                self._to_world.assign(old_tw)
                self._check_to_world()
                raise
        old_projection = (self._x_fov, self._near_clip, self._far_clip)

        def restore():
            self._set_projection(*old_projection)
            self._update_projection()
            self._sync_traversed()

        changes = {}
        for k, holder in self._traversed_cfg.items():
            v = held(holder)
            if v != self._traversed_vals[k]:
                changes[k] = v
        projection = {k: changes.pop(k, v) for k, v in zip(PROJECTION_KEYS, old_projection)}
        try:
            self._set_projection(*(projection[k] for k in PROJECTION_KEYS))
        except ParameterError:
            restore()
            raise
        self._update_projection()  # film, fov or clip planes: before the plan (f_px)
        if "camera_acceleration" in changes:
            changes["image_acceleration"] = None
        shutter = (self.shutter_open(), self.shutter_open() + self.shutter_open_time())
        old_exposure = self._exposure
        if not np.allclose(shutter, self._exposure, rtol=1e-6, atol=1e-6):
            # a new exposure: the schedule is re-timed
            self._exposure = shutter
            changes["time_window"] = None
        try:
            self.configure(**changes)  # also rebuilds for a changed shutter or f_px
        except ParameterError:
            self._exposure = old_exposure
            restore()
            raise

    # ---------------------------------------------------------------- kernels
    def _ray_setup(self, time, position_sample, aperture_sample, active):
        """The ray's time, weight, film point (camera frame, jittered by diffraction), lens
        point and origin."""
        time, k = self._time_and_pattern(time, active)
        if self._switch is not None:
            seeds = (position_sample.x, aperture_sample.y, time)
            k = self._switched(k, time, seeds, active)
        weight = self._weight_at(k, active)
        near_p = self._sample_to_camera @ Point3f(position_sample.x, position_sample.y, 0.0)
        if self._ri.kind != "off":  # off: the kernel is thinlens', untouched
            weight = weight * self._illumination(near_p)  # the pixel's, where the light lands
        if self._leak is None:
            a, _ = self._aperture(k, time, aperture_sample, active)
        else:  # light through the "off" pixels too
            a, _, factor = self._leaky_aperture(k, time, aperture_sample, active)
            weight = weight * factor
        aperture_p = Point3f(a.x, a.y, 0.0)
        origin = Point3f(a.x + self._camera_x(k, time, active), a.y, 0.0)
        if self._diff is not None:  # the film position moves by a draw from the Airy pattern
            seeds = (position_sample.x, position_sample.y, aperture_sample.x, aperture_sample.y)
            off, w_diff = self._diffraction_draw(seeds, active)
            if self._exact_ray_on():  # or by the exact PSF's jitter at the probed depth
                jitter, w_exact, use = self._exact_jitter(
                    k, time, position_sample, aperture_p, origin, seeds, active
                )
                off = Point2f(dr.select(use, jitter.x, off.x), dr.select(use, jitter.y, off.y))
                w_diff = dr.select(use, w_exact, w_diff)
            near_p = near_p + self._dx * off.x + self._dy * off.y  # the near plane is affine
            weight = weight * w_diff
        return time, weight, near_p, aperture_p, origin

    def _finish(self, ray, d, origin):
        ray.o = self._to_world @ origin
        ray.d = self._to_world @ d
        inv_z = dr.rcp(d.z)
        near_t = self._near * inv_z
        far_t = self._far * inv_z
        ray.o += ray.d * near_t
        ray.maxt = far_t - near_t
        shift = self.scene_shift(ray.time - self._t_mid)
        if shift is not None:
            ray.o = ray.o - shift  # the scene moved by +shift: meet it at o - shift

    def _ray_args(self, time, sample1, sample2, sample3, active):
        """The arguments of ``sample_ray*`` as Mitsuba types (see :func:`as_type`)."""
        return (
            as_type(Float, time),
            as_type(Float, sample1),
            as_type(Point2f, sample2),
            as_type(Point2f, sample3),
            as_type(mi.Bool, active),
        )

    def sample_ray(self, time, sample1, sample2, sample3, active=True):
        """A camera ray: wavelengths from ``sample1``, film position ``sample2``, lens point
        ``sample3``, at integrator time ``time``; returns (ray, weight)."""
        time, sample1, sample2, sample3, active = self._ray_args(
            time, sample1, sample2, sample3, active
        )
        wavelengths, wav_weight = self.sample_wavelengths(
            dr.zeros(mi.SurfaceInteraction3f), sample1, active
        )
        time, weight, near_p, aperture_p, origin = self._ray_setup(time, sample2, sample3, active)
        focus_p = near_p * (self._focus / near_p.z)
        d = dr.normalize(Vector3f(focus_p - aperture_p))
        ray = mi.Ray3f(Point3f(0.0), Vector3f(0.0, 0.0, 1.0), time, wavelengths)
        self._finish(ray, d, origin)
        return ray, wav_weight * weight

    def sample_ray_differential(self, time, sample1, sample2, sample3, active=True):
        """:meth:`sample_ray` with the differentials of one pixel step in x and y, through the
        same lens point (as thinlens.cpp's own differentials)."""
        time, sample1, sample2, sample3, active = self._ray_args(
            time, sample1, sample2, sample3, active
        )
        wavelengths, wav_weight = self.sample_wavelengths(
            dr.zeros(mi.SurfaceInteraction3f), sample1, active
        )
        time, weight, near_p, aperture_p, origin = self._ray_setup(time, sample2, sample3, active)
        f_dist = self._focus / near_p.z
        focus_p = near_p * f_dist
        d = dr.normalize(Vector3f(focus_p - aperture_p))
        ray = mi.RayDifferential3f(
            mi.Ray3f(Point3f(0.0), Vector3f(0.0, 0.0, 1.0), time, wavelengths)
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
        sample, active = as_type(Point2f, sample), as_type(mi.Bool, active)
        time, k = self._time_and_pattern(it.time, active)
        if self._switch is not None:
            k = self._switched(k, time, (sample.x, sample.y, time), active)
        shift = self.scene_shift(time - self._t_mid)
        p = it.p if shift is None else it.p + shift  # where the moving scene puts the point
        cam_x = self._camera_x(k, time, active)
        ref_p = self._from_world @ p
        ref_p = Point3f(ref_p.x - cam_x, ref_p.y, ref_p.z)
        active = active & (ref_p.z >= self._near) & (ref_p.z <= self._far)
        factor = None
        if self._leak is None:
            a, pdf_area = self._aperture(k, time, Point2f(sample.x, sample.y), active)
        else:
            a, pdf_area, factor = self._leaky_aperture(k, time, Point2f(sample.x, sample.y), active)
        aperture_p = Point3f(a.x, a.y, 0.0)
        v = Vector3f(ref_p - aperture_p)
        z = dr.select(active, ref_p.z, 1.0)  # > 0 where active (scalar mode: no 1/0)
        # the ray from the lens point through ref_p meets the focal plane at focus_p;
        # the film pixel is where the lens centre projects focus_p
        focus_p = Point3f(aperture_p + v * (self._focus / z))
        screen = self._camera_to_sample @ focus_p
        uv = Point2f(screen.x, screen.y)
        w_diff = None
        if self._diff is not None:  # the light lands a draw from the Airy pattern away
            seeds = (sample.x, sample.y, ref_p.x, ref_p.y)
            off, w_diff = self._diffraction_draw(seeds, active)
            uv = uv + Point2f(off.x / self._resolution.x, off.y / self._resolution.y)
            if self._exact_defocus_on():  # or, up to 4 waves, the exact defocused PSF's
                exact, w_exact, inside = self._defocus_landing(ref_p, z, k, time, seeds, active)
                uv = Point2f(dr.select(inside, exact.x, uv.x), dr.select(inside, exact.y, uv.y))
                w_diff = dr.select(inside, w_exact, w_diff)
            landed = self._sample_to_camera @ Point3f(uv.x, uv.y, 0.0)
            focus_p = landed * (self._focus / landed.z)  # for the landing pixel's factor
        active &= (uv.x >= 0.0) & (uv.x <= 1.0) & (uv.y >= 0.0) & (uv.y <= 1.0)
        dist = dr.norm(v)
        inv_dist = dr.rcp(dr.maximum(dist, 1e-20))
        cos_t = dr.maximum(v.z * inv_dist, 1e-20)  # v.z = z > 0 where active
        active &= pdf_area > 0.0
        # W_e cos / (dist^2 p_A): with W_e cos = p_A p_omega w (the camera-ray estimator)
        # and p_omega = |focus_p - a|^2 / (cos A' F^2) = dist^2 / (cos A' z^2) on the
        # ray through a (collinear: |focus_p - a| / dist = F / z), this is w / (A' cos z^2)
        weight = self._weight_at(k, active)
        if factor is not None:
            weight = weight * factor
        weight = weight * self._inv_image_area * dr.rcp(cos_t * z * z)
        if self._ri.kind != "off":  # the film position's factor, as in sample_ray
            weight = weight * self._illumination(focus_p)

        if JIT:
            ds = dr.zeros(mi.DirectionSample3f)
        else:
            ds = mi.DirectionSample3f()
            ds.delta = False
        ds.p = self._to_world @ Point3f(a.x + cam_x, a.y, 0.0)
        ds.d = (ds.p - p) * inv_dist
        ds.dist = dist
        ds.n = self._to_world @ Vector3f(0.0, 0.0, 1.0)
        ds.uv = uv * self._resolution
        ds.time = time
        ds.pdf = dr.select(active, pdf_area * dist * dist / cos_t, 0.0)
        spectrum = mi.Spectrum(dr.select(active, weight, 0.0))
        return ds, spectrum if w_diff is None else spectrum * w_diff

    # ---------------------------------------------------------------- extension hook
    def scene_shift(self, tau):
        """Rigid displacement (world mm) of everything the sensor sees at ray time ``tau``.

        The extension hook for subclasses (:class:`~pacam_render.render.psf_camera.PSFCamera`
        overrides it). ``tau`` is the ray's paper time, ms from mid-exposure, after the time
        window and chop maps. Return ``None`` (the default: a still scene, nothing traced) or
        a ``mi.Vector3f``: camera rays then start at o - shift, and particle-tracer connections
        see each scene point at p + shift, which is exact continuous motion of a scene that
        moves as one (Mitsuba 3 moves no geometry with ray time).
        """
        return None

    # ---------------------------------------------------------------- misc
    def pattern_index(self, time):
        """Pattern shown at each ray time (the kernels' own lookup), as numpy."""
        t = Float(np.asarray(time, dtype=np.float32)) if JIT else Float(time)
        return np.array(self._pattern(t, True), dtype=np.int64)

    def sample_aperture(self, time, u1, u2):
        """Aperture points (local mm) that the kernels sample at ray times ``time`` from
        uniforms (u1, u2), and each ray's weight (without the wavelength weight); numpy.
        ``time`` is used as is (no window or chop remapping)."""
        if not JIT:
            raise ParameterError("sample_aperture needs a JIT (llvm/cuda) variant")
        t, a, b = (Float(np.asarray(v, dtype=np.float32)) for v in (time, u1, u2))
        active = mi.Bool(True)
        k = self._pattern(t, active)
        p, _ = self._aperture(k, t, Point2f(a, b), active)
        w = gather(Float, self._weight, k, active) * self._time_scale
        return np.array(p.x), np.array(p.y), np.array(w)

    def bbox(self):
        """The lens centre's path over the exposure, in world space (a point for a camera
        that does not move, as thinlens), as a scalar bounding box in every variant."""
        lo = self._to_world @ Point3f(self._travel[0], 0.0, 0.0)
        hi = self._to_world @ Point3f(self._travel[1], 0.0, 0.0)
        # scalar variants have no Scalar* aliases of their own (only after a JIT variant
        # was loaded in the process)
        box_t = mi.ScalarBoundingBox3f if JIT else mi.BoundingBox3f
        point_t = mi.ScalarPoint3f if JIT else mi.Point3f
        box = box_t()
        for p in (lo, hi):
            box.expand(point_t(first(p.x), first(p.y), first(p.z)))
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
            f"  near_clip = {self._near_clip:g}, far_clip = {self._far_clip:g},\n"
            f"  exposure = [{p.t_open:g}, {p.t_close:g}] ms,"
            f" time_window = {p.window},\n"
            f"  open_fraction = {p.open_fraction:g}, exposure_factor = "
            f"{p.exposure_factor:g},\n"
            f"  mean weight (image / thinlens) = {p.mean_weight():.6g},\n"
            f"  relative_illumination = {self._ri.source},\n"
            f"  diffraction = {self._diffraction_text()},\n"
            f"  film = {self.film()},\n"
            f"  to_world = {self._to_world.matrix}\n"
            "]"
        )
