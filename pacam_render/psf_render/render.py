"""Ray-traced PSFs of a :class:`~pacam_render.model.camera.CameraDesign`, registered with the
analytic ones of :mod:`pacam_render.psf` (issue 6).

What is rendered
----------------
A tiny one-sided disk emitter (:func:`pacam_render.scenes.psf_scene`) on black, seen by the
``programmable_aperture`` sensor, traced with ``ptracer`` (``max_depth`` 2; ``path`` with
``max_depth`` 2 is offered for comparisons), a box pixel filter, float32, one channel. Every
pattern window of the exposure is rendered separately (the sensor's ``time_window``); the windows
tile the exposure, so their sum is the PSF, and each window's centroid gives the measured image
trajectory over the patterns, from which a_i (Eq. 18) is fitted.

Registration
------------
The kernel is an odd-sized (h, w) array whose centre pixel (h//2, w//2) is centred on where the
point images at mid-exposure t = 0, exactly as :func:`pacam_render.psf.design_psf` draws it
(for the coded modes: where the continuous parabola's vertex is; the aperture would be at
X_a(0) = -(R_max - R), so on the prototype film that is column W/2 - beta_px (R_max - R)).
Two film set-ups give the same registration:

* ``film="window"`` (default): a film of exactly the kernel's size whose field of view gives the
  prototype's focal length in pixels, (W/2)/tan(fov/2). Its centre is a pixel centre (odd
  size); the source is displaced sideways in the scene by the t = 0 image offset, so its t = 0
  image lands there. The thin lens is shift-invariant (Eq. 8's parallax term does not depend
  on the point's position), so this is the prototype film's PSF, moved by a few pixels.
* ``film="crop"``: a crop window (``crop_width`` ...) of the full 1280x960 prototype film; the
  source sits on the optical axis, displaced by the sub-pixel amounts that put its t = 0 image
  on a pixel centre.

Why "window" is the default: Mitsuba 3.9.1's particle tracer traces ``spp`` x the *full* film's
pixel count of particles whatever the crop (read in ``integrator.cpp``, ``AdjointIntegrator``:
``samples_per_pass = film_size.x * film_size.y * spp``; measured: a 47x47 crop of the
1280x960 film costs as much as the whole film). So a crop does not save time with ``ptracer``;
the window film does. ``spp`` keeps Mitsuba's meaning in both: particles (or camera rays for
``path``) per film pixel, per window.

Float32 accumulation
--------------------
``ptracer`` splats with float32 atomics. Millions of equal-weight particles added to one pixel
in float32 drift: a 2 px pillbox rendered with 2^24 particles in one call summed 0.25 % high,
one of radius 0.6 px 3.5 %; 16 windows of 64 spp of the 1280x960 film (79M particles per call)
gave a coded PSF with an L1 error of 0.010 against a noise floor of 0.0002. Each window is
therefore rendered in passes sized so that the brightest pixel expects at most
:data:`ADDS_PER_PIXEL` particles (drift ~1e-4), with their own seeds, summed in float64.

Moving source
-------------
Mitsuba 3 moves no geometry with ray time. For one point source on black (everything that moves
shares one velocity), moving the whole scene by v (t - t_mid) is exact and continuous in a single
render: this module's sensor ``pacam_psf_camera`` is ``programmable_aperture`` plus that one
rigid velocity (:meth:`set_scene_velocity`): camera rays start at o - v tau and particle-tracer
connections see the scene point at p + v tau, tau = t - t_mid the ray's (window-mapped) time.
The plugin file itself is unchanged; the subclass overrides two of its methods.

Source size
-----------
The emitter is a disc of radius ``source_radius_px`` (default 0.02 px in the image, instead of
psf_scene's 0.25 px). Its image is convolved with the PSF; after pixel integration the change is
second order in the radius (:func:`source_blur_l1`: 1.1e-3 of L1 for a 0.6 px pillbox, at most
4e-4 for r >= 1 px; 0.25 px would give 0.18 and 0.013 for r = 0.6 and 2 px). The particle
tracer's noise does not depend on the emitter's size (its power is fixed), so the small source
costs nothing. The camera-ray ``path`` tracer must hit the source: use a larger one there.

Determinism: the same seed gives the same particles, but with several Dr.Jit threads the float32
atomic adds run in a thread-dependent order (6e-6 relative differences seen between two runs).
Renders therefore use one thread by default (``threads=1``): the same seed then gives a
bit-identical kernel, and on this 2-core machine it was no slower (ptracer's atomics contend).

Units: mm, ms, px; velocities px/ms in the image (+ to the right), accelerations px/ms^2.

The parts: what to render and its checks (:mod:`.spec`), each mode's windows and model
(:mod:`.mode_setup`), the film (:mod:`.film`), the result (:mod:`.result`); this module
renders.
"""

from __future__ import annotations

import math
import time
from contextlib import contextmanager

import numpy as np

from ..errors import ParameterError, check_positive
from ..exposure.render_time import Work, count_step, metered
from ..io.signals import deferred_signals
from ..model.camera import CameraDesign
from ..render.registry import PSF_PLUGIN_NAME, ensure_registered, sensor_dict
from ..render.variant import choose_variant
from ..restore.metrics import kernel_centroid
from ..scenes import image_to_scene_velocity, psf_scene
from .diffraction import channels, sensor_params
from .film import Film
from .mode_setup import ModeSetup, model_window_centroids
from .result import RenderedPSF
from .spec import PSFSpec, check_render_budget, check_request, plan_render  # noqa: F401 - cli

DEFAULT_SOURCE_RADIUS_PX = 0.02
"""Radius of the emitter's image, px: small enough that it does not show (see source_blur_l1)."""
ADDS_PER_PIXEL = 1 << 15
"""Render calls are sized so that the brightest pixel expects at most this many particles: it
bounds the float32 drift (2^16 equal adds to one pixel drifted 4.5e-4, 2^14 1e-4)."""
PARTICLES_PER_PASS = 1 << 22
"""At most this many particles (or camera rays) per render call (memory)."""
NEAR_CLIP_MM = 1.0
FAR_CLIP_MM = 1.0e7


def _seed(seed: int, *keys: int) -> int:
    """An independent uint32 Mitsuba seed for (seed, window, pass)."""
    return int(np.random.SeedSequence([seed, *keys]).generate_state(1)[0])


def _spp_per_pass(spp: int, film: Film, integrator: str, peak: float) -> int:
    """Samples per pixel of one render call: a power of two (few distinct kernels to compile),
    at most ``spp``, with at most PARTICLES_PER_PASS samples and, for ptracer, at most
    ADDS_PER_PIXEL particles expected in the brightest pixel (``peak``: the largest fraction
    of one window's particles that one pixel receives)."""
    pixels = film.sample_pixels(integrator)
    budget = PARTICLES_PER_PASS
    if integrator == "ptracer":
        budget = min(budget, ADDS_PER_PIXEL / max(min(peak, 1.0), 1e-12))
    n = int(budget // pixels)
    n = 2 ** int(math.log2(n)) if n >= 1 else 1
    return max(1, min(spp, n))


@contextmanager
def _threads(n: int | None):
    """Run with n Dr.Jit worker threads (None: leave them), restoring the count afterwards."""
    import drjit as dr

    if n is None:
        yield
        return
    old = dr.thread_count()
    dr.set_thread_count(int(n))
    try:
        yield
    finally:
        dr.set_thread_count(old)


class PSFRenderer:
    """Renders PSFs, reusing loaded scenes (and so Dr.Jit's compiled kernels) across calls.

    A scene is loaded per Mitsuba variant, film size, exposure and integrator; depth, opening,
    focus, schedule, velocity and source move through opaque parameters, so sweeping them never
    recompiles.
    """

    def __init__(self, source_radius_px: float = DEFAULT_SOURCE_RADIUS_PX):
        ensure_registered()
        self.source_radius_px = check_positive("source_radius_px", source_radius_px, "px")
        self._scenes: dict[tuple, tuple] = {}

    def _scene(self, design, setup: ModeSetup, film: Film, integrator: str, diffraction=False,
               pitch_mm=None):  # fmt: skip
        import mitsuba as mi

        # a scene is made for one variant (mono or RGB): a switch between calls loads anew
        key = (mi.variant(), film.key(integrator, setup.exposure_ms), diffraction)
        if diffraction:  # the pupil's size and the pitch are load-time parameters
            extra = sensor_params(design, setup.mode, channels(mi.variant()), pitch_mm)
            key += tuple(sorted(extra.items()))
        else:
            extra = {}
        if key not in self._scenes:
            Z = design.object_depth_mm
            desc = psf_scene(Z, 0.0, camera=design)
            sensor = sensor_dict(
                fov=film.fov_deg,
                shutter_open=0.0,
                shutter_close=setup.exposure_ms,
                near_clip=NEAR_CLIP_MM,
                far_clip=FAR_CLIP_MM,
                film=film.mitsuba(),
                **setup.sensor,
                **extra,
            )
            sensor["type"] = PSF_PLUGIN_NAME
            integ = {"type": integrator, "max_depth": 2}
            scene = desc.load(sensor=sensor, integrator=integ)
            params = mi.traverse(scene)
            params.keep(["psf_disk.to_world", "psf_disk.emitter.radiance.value"])
            self._scenes[key] = (scene, params)
        return self._scenes[key]

    def _place(self, design, setup, film, velocity, scene, params):
        Z, f = design.object_depth_mm, design.focal_length_px
        rs_px = self.source_radius_px
        rs = rs_px * Z / f
        x, y = film.source_xy_mm
        m = [[-rs, 0.0, 0.0, x], [0.0, rs, 0.0, y], [0.0, 0.0, -1.0, Z], [0.0, 0.0, 0.0, 1.0]]
        params["psf_disk.to_world"] = type(params["psf_disk.to_world"])(m)
        key = "psf_disk.emitter.radiance.value"  # Color3f in RGB variants, Float in mono ones
        params[key] = type(params[key])(1.0 / (math.pi * rs_px**2))
        params.update()
        sensor = scene.sensors()[0]
        sensor.configure(time_window=None, **setup.sensor)
        sensor.set_scene_velocity(image_to_scene_velocity(velocity, Z, design))
        return sensor

    def render(
        self,
        design: CameraDesign,
        spec: PSFSpec | None = None,
        *,
        model: np.ndarray | None = None,
        progress: bool = False,
    ) -> RenderedPSF:
        """Render the analytic kernel ``design_psf(design, spec.mode, spec.velocity, spec.size)``
        by ray tracing (see the module docstring).

        Parameters
        ----------
        design : CameraDesign
            The camera.
        spec : PSFSpec, optional
            What to render (default: the coded PSF at rest).
        model : numpy.ndarray, optional
            That analytic kernel, if already computed (saves its computation).
        progress : bool, optional
            Show a progress bar over the render calls.

        Returns
        -------
        RenderedPSF

        Raises
        ------
        ParameterError
            Naming the field of ``spec`` that is out of range, before any rendering.
        KeyboardInterrupt
            On SIGINT or SIGTERM, after the render call under way (its partial image is never
            used).
        """
        spec = PSFSpec() if spec is None else spec
        req = plan_render(design, spec, model)
        check_render_budget(req, spec.integrator, spec.per_window, spec.max_samples)
        pitch = spec.pixel_pitch_mm if spec.diffraction else None
        scene, params = self._scene(
            design, req.setup, req.film, spec.integrator, spec.diffraction, pitch
        )
        sensor = self._place(design, req.setup, req.film, req.velocity, scene, params)
        windows, is_open, plan = render_plan(req, spec)
        t0 = time.perf_counter()
        with _threads(spec.threads), metered(psf_history_key()):
            desc = f"render {spec.mode} PSF"
            mpx = req.film.sample_pixels(spec.integrator) / 1e6  # particles per spp, millions
            images = self._render_passes(
                scene, sensor, req, windows, plan, spec.per_window, desc, progress, mpx
            )
        seconds = time.perf_counter() - t0
        return self._result(req, spec, windows, is_open, images, plan, seconds, design)

    def _render_passes(self, scene, sensor, req, windows, plan, per_window, desc, progress, mpx):
        """Render every (window, pass) of ``plan``; returns the windows' images (float64).
        Each call's ``mpx`` x samples million particles go to the cost model's history."""
        import mitsuba as mi

        h, w = req.shape
        images = [np.zeros((h, w)) for _ in windows]
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=len(plan), desc=desc, unit="pass", leave=False)
        current = None
        integ = scene.integrator()
        try:
            with deferred_signals() as flag:
                for k, p, n in plan:
                    if current != k:
                        sensor.configure(time_window=None if not per_window else windows[k])
                        current = k
                    img = _render_call(mi, scene, n, _seed(req.seed, k, p))
                    # Mitsuba's own SIGINT handler cuts a render short and returns it: unusable
                    if flag["signal"] is not None or integ.should_stop():
                        raise KeyboardInterrupt
                    images[k] += np.array(img, dtype=np.float64).reshape(h, w) * (n / req.spp)
                    count_step(n * mpx)
                    if bar is not None:
                        bar.update()
        finally:
            if bar is not None:
                bar.close()
            sensor.configure(time_window=None)
        return images

    def _result(self, req, spec: PSFSpec, windows, is_open, images, plan, seconds, design):
        """Normalise the windows' images into a :class:`RenderedPSF` with its trajectory."""
        setup = req.setup
        total = sum(images)
        raw = float(total.sum())
        if not raw > 0:
            raise ParameterError(
                "the rendered PSF is black: the source is outside the view (check depth and size)"
            )
        T = setup.T_ms
        mass = np.array([im.sum() for im in images]) / raw
        cents = np.array(
            [kernel_centroid(im) if im.sum() > 0 else (np.nan, np.nan) for im in images]
        )
        if spec.per_window:
            model_u = model_window_centroids(setup, req.velocity) + (setup.origin_px - req.centre)
            model_u = np.where(is_open, model_u, np.nan)
        else:
            model_u = np.array([np.nan])
        return RenderedPSF(
            kernel=total / raw,
            raw_sum=raw,
            mode=spec.mode,
            velocity_px_per_ms=req.velocity,
            spp=req.spp,
            seed=req.seed,
            integrator=spec.integrator,
            seconds=seconds,
            particles=int(sum(n for *_, n in plan) * req.film.sample_pixels(spec.integrator)),
            threads=spec.threads,
            passes=len(plan),
            film=req.film.describe(design),
            source_radius_px=self.source_radius_px,
            t_start_ms=np.array([a for a, _ in windows]) - T,
            t_end_ms=np.array([b for _, b in windows]) - T,
            mass=mass,
            centroid_u_px=cents[:, 0],
            centroid_v_px=cents[:, 1],
            model_u_px=model_u,
            model_a_i=setup.a_i,
            origin=spec.origin,
            window_kernels=[im / raw for im in images] if spec.keep_windows else None,
            model=req.model,
        )


def _render_call(mi, scene, spp: int, seed: int):
    """``mi.render``; a KeyboardInterrupt that Dr.Jit wrapped in a RuntimeError (a second
    Ctrl-C inside the render) is raised as itself."""
    try:
        return mi.render(scene, spp=spp, seed=seed)
    except RuntimeError as exc:
        if isinstance(exc.__cause__, KeyboardInterrupt):
            raise KeyboardInterrupt from None
        raise


def render_plan(req, spec: PSFSpec):
    """A render's time windows, whether each lets light in, and its (window, pass, samples)
    render calls, sized so that float32 splats do not drift (:data:`ADDS_PER_PIXEL`)."""
    windows, is_open = _windows(req.setup, spec.per_window)
    peak = req.model.max() * int(is_open.sum())
    spp_pass = _spp_per_pass(req.spp, req.film, spec.integrator, peak)
    return windows, is_open, _pass_plan(req.spp, spp_pass, is_open)


def psf_work(design: CameraDesign, spec: PSFSpec, model: np.ndarray | None = None) -> Work:
    """What :meth:`PSFRenderer.render` of ``spec`` does, for the planner's cost model
    (:mod:`~pacam_render.exposure.render_time`): one call, its particles (millions) and render
    calls; nothing is rendered."""
    req = plan_render(design, spec, model)
    plan = render_plan(req, spec)[2]
    particles = sum(n for *_, n in plan) * req.film.sample_pixels(spec.integrator)
    return Work(calls=1, msamples=particles / 1e6, renders=len(plan))


def psf_history_key() -> str:
    """The cost model's history key of PSF renders: ``psf`` and the variant that renders them
    (their rates are a particle tracer's, not a capture's): the active one, else the one
    :func:`~pacam_render.render.variant.choose_variant` would pick. The active variant is
    never changed here (a scene belongs to the variant it was loaded in)."""
    import mitsuba as mi

    return f"psf {mi.variant() or choose_variant()}"


def _windows(setup: ModeSetup, per_window: bool):
    """The time windows to render (sensor ms) and whether each lets light in."""
    edges = setup.edges_ms
    if not per_window:
        return [(edges[0], edges[-1])], np.array([True])
    return [(edges[k], edges[k + 1]) for k in range(len(edges) - 1)], setup.open


def _pass_plan(spp: int, spp_pass: int, is_open: np.ndarray) -> list[tuple[int, int, int]]:
    """(window, pass, samples) for every render call: each open window gets ``spp`` in passes
    of at most ``spp_pass``."""
    plan = []
    for k in np.flatnonzero(is_open):
        left, p = spp, 0
        while left > 0:
            n = min(spp_pass, left)
            plan.append((int(k), p, n))
            left -= n
            p += 1
    return plan


_DEFAULT: PSFRenderer | None = None


def render_psf(
    design: CameraDesign,
    mode: str = "coded",
    velocity: float = 0.0,
    *,
    source_radius_px: float = DEFAULT_SOURCE_RADIUS_PX,
    model: np.ndarray | None = None,
    progress: bool = False,
    **fields,
) -> RenderedPSF:
    """:meth:`PSFRenderer.render` of ``PSFSpec(mode, velocity, **fields)`` on a shared
    renderer (its scenes are reused between calls)."""
    global _DEFAULT
    if _DEFAULT is None or _DEFAULT.source_radius_px != source_radius_px:
        _DEFAULT = PSFRenderer(source_radius_px)
    spec = PSFSpec(mode, velocity, **fields)
    return _DEFAULT.render(design, spec, model=model, progress=progress)
