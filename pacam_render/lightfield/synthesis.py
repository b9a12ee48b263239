"""A capture synthesised from a light-field store: any design, no ray tracing.

The design is resolved as a direct capture's (:func:`~pacam_render.exposure.plan.plan_capture`),
so the same plan gives the same camera, sensor parameters and record. Each of the store's
samples is moved to where the design's camera sees its ray (its focus, :mod:`.geometry`),
weighed by the design's transmission at its lens point and time (:mod:`.codes`) and by its
step's share of the exposure, and added into its pixel; each store pass gives one pass of the
capture, so the capture's Monte Carlo error is measured as a render's is, from the samples the
design actually uses. The result is a :class:`~pacam_render.capture.result.Capture` with the
store's truth layers and a record that names the store and its digest.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
from tqdm import tqdm

from ..errors import ParameterError
from ..exposure.assemble import Passes, assemble_capture
from ..exposure.estimate import PassGroup, PassStats
from ..exposure.plan import CapturePlan, plan_capture
from ..model.illumination import cos4_at_film
from ..scenes import load_scene
from . import geometry as geo
from .codes import check_served, design_aperture, transmission
from .store import Store, scene_digest

APPROXIMATION = "exact: the store's rays reweighted (same estimator as a direct render)"


def check_fits(store: Store, spec) -> None:
    """Refuse a capture the store cannot give, naming the field that differs."""
    s = store.manifest.capture
    _check_scene_name(store, spec)
    for key in ("width", "height", "grey"):
        if s[key] != getattr(spec, key):
            raise ParameterError(
                f"`{key}` {getattr(spec, key)!r} differs from the store's {s[key]!r}: a store "
                "serves captures of its own scene, sensor size and channels"
            )
    crop = list(spec.crop) if spec.crop else None
    if (list(s["crop"]) if s["crop"] else None) != crop:
        raise ParameterError(f"`crop` {crop} differs from the store's window {s['crop']}")
    if spec.diffraction == "on" or spec.lcos_fill_factor is not None:
        raise ParameterError(
            "diffraction on: a synthesised capture is geometric (diffraction is not linear in "
            "the aperture); give diffraction off or auto (its effect is then measured and "
            "stated in the capture's optics_error)"
        )


def synthesize(store: Store, spec, progress: bool = True, description=None, passes=None):
    """The capture ``spec`` asks for, from ``store`` (module docstring).

    Parameters
    ----------
    store : Store
        A finished light-field store.
    spec : CapturePlan or CaptureSpec
        The capture, resolved (:func:`~pacam_render.exposure.plan.plan_capture`, as ``pacam
        render --from`` does before it opens its output), or a spec resolved here: its scene,
        size, window and channels must be the store's; its design, mode and optics are free,
        within :func:`check_fits` and :func:`~.codes.check_served`. ``seed``, ``spp`` and
        ``passes`` are the store's.
    progress : bool, optional
        A progress bar over the store's shards.
    description : SceneDescription, optional
        The scene the store was rendered from, when it is not ``spec.scene`` by name (checked
        against the store's digest).
    passes : sequence of int, optional
        Only these store passes (:func:`check_passes`; default all): a capture from samples a
        search never read, e.g. to choose among its results. Its sigma is these passes'.

    Returns
    -------
    Capture
        The image (radiance x light factor, as a render's), its per-pixel Monte Carlo sigma,
        the store's truth layers, and a record with ``lightfield`` (the store, its digest and
        the samples used), assembled as a direct render's
        (:func:`~pacam_render.exposure.assemble.assemble_capture`).

    Raises
    ------
    ParameterError
        If the store cannot serve the design (another window, Levin's moving camera, a
        refocus beyond the store's margin, diffraction on, a switching continuous schedule).
    """
    t_start = time.perf_counter()
    desc = _scene(store, _spec_of(spec), description)
    plan, params, design_plan = _resolve(store, spec)
    images, used = pass_images(store, plan, params, design_plan, progress, passes)
    stats = PassStats([PassGroup(store.manifest.samples_per_pass)])
    for img in images:
        stats.add(0, img)
    seconds = time.perf_counter() - t_start
    n_steps = len(store.manifest.steps[0])
    layers, objects, sharp_sigma = store.truth(moving=not desc.is_static)
    lightfield = {
        "store": str(store.folder), "digest": store.digest, "samples_used": used,
        "passes": list(check_passes(store, passes)),
        "approximation": APPROXIMATION, "store_seconds": store.manifest.seconds,
    }  # fmt: skip
    passes = Passes(
        stats, design_plan, seconds, seconds, SAMPLER, n_steps,
        time_steps_per_pass=n_steps if desc.is_static is False else 0,
        time_sampling=TIME_SAMPLING, sharp_mc_sigma=sharp_sigma, extra={"lightfield": lightfield},
    )  # fmt: skip
    return assemble_capture(plan, desc, passes, layers, objects)


SAMPLER = "light-field store"
"""``render_error.sampler`` of a synthesised capture."""
TIME_SAMPLING = (
    "the store's: one random time per step and pass, or uniform times for a still scene; "
    "unbiased, their noise is in mc_sigma"
)
"""``render_error.time_sampling`` of a synthesised capture."""


RENDER_NOISE_SHARE = 0.3
"""The render noise a synthesised capture should stay under, as a share of the sensor's noise:
at 0.3x it adds 4 % to the noise its scores see, sqrt(1 + 0.3^2) = 1.04."""


def store_noise_note(
    cap, sensor_sigma: float | None = None, sensor: str | None = None, spp_name: str = "`spp`"
):
    """A note, or None, for a capture synthesised from a store whose Monte Carlo sigma exceeds
    :data:`RENDER_NOISE_SHARE` of the sensor's noise: the ratio, and the samples per pass of a
    store that would meet that share (a store's independent samples: sigma ~ 1/sqrt(spp)).

    ``sensor_sigma`` is the sensor's noise in the capture's units, ``sensor`` names it; by
    default the capture's own sensor, else its optics budget's stand-in (the design's sensor
    at the default light level). ``spp_name`` names the store's samples per pass (a flag)."""
    rec = cap.record
    err = rec.render_error
    if sensor_sigma is None and rec.noise_sigma:
        sensor_sigma, sensor = rec.noise_sigma, rec.sensor.preset if rec.sensor else "the sensor"
    if sensor_sigma is None:
        ref = (rec.optics_error or {}).get("reference_noise") or {}
        sensor_sigma, sensor = ref.get("sigma"), ref.get("sensor")
    if err is None or not sensor_sigma or sensor_sigma <= 0:
        return None
    ratio = err.mc_sigma / sensor_sigma
    if ratio <= RENDER_NOISE_SHARE:
        return None
    per_pass = -(-err.spp // max(err.passes, 1))
    need = int(math.ceil(per_pass * (ratio / RENDER_NOISE_SHARE) ** 2))
    return (
        f"the light-field store's render noise in this capture is {ratio:.2g}x the sensor's "
        f"({sensor}): its figures carry it; a store of {need} spp per pass ({spp_name}, now "
        f"{per_pass}) would bring it to {RENDER_NOISE_SHARE:g}x"
    )


def _spec_of(spec):
    """The spec of a plan, or the spec itself."""
    return spec.spec if isinstance(spec, CapturePlan) else spec


def _resolve(store: Store, spec):
    """The capture's plan (the store's seed, samples and passes), its sensor parameters and
    aperture plan, each checked against what the store can serve (its scene is checked by
    the caller, :func:`_scene`, once). A plan is not resolved again: the store's sampling
    replaces its own, which changes no camera."""
    check_fits(store, _spec_of(spec))
    s = store.manifest.capture
    sampling = dict(seed=s["seed"], spp=s["spp"], passes=s["passes"], sampler="independent",
                    max_step_px=s["max_step_px"])  # fmt: skip
    if isinstance(spec, CapturePlan):
        plan = replace(spec, spec=replace(spec.spec, **sampling), diffraction=None)
    else:
        plan = plan_capture(replace(spec, **sampling))
    decision = "off: a synthesised capture is geometric" if plan.spec.diffraction == "off" else (
        "left out: a capture synthesised from a light-field store is geometric; its effect is "
        "measured below"
    )  # fmt: skip
    plan = plan.with_diffraction(False, decision)
    params = plan.sensor_params()
    design_plan = design_aperture(plan, params)
    check_served(design_plan, params)
    _shear(store, plan)
    return plan, params, design_plan


def paired_difference(store: Store, a, b, description=None) -> tuple[np.ndarray, np.ndarray]:
    """Capture ``a`` minus capture ``b`` from one store, and the per-pixel Monte Carlo sigma
    of that difference, from the spread of the passes' differences: the two designs share the
    store's rays, so most of their noise cancels.

    Parameters
    ----------
    store : Store
    a, b : CaptureSpec
        Two captures the store serves (:func:`synthesize`).
    description : SceneDescription, optional
        As :func:`synthesize`'s.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The difference (capture units) and its sigma.
    """
    _scene(store, a, description)
    per = []
    for spec in (a, b):
        plan, params, design_plan = _resolve(store, spec)
        per.append(pass_images(store, plan, params, design_plan, False)[0])
    stats = PassStats([PassGroup(1)])
    for ia, ib in zip(*per):
        stats.add(0, ia - ib)
    return stats.mean(), stats.sigma_px()


def _shear(store: Store, plan) -> float:
    """k (px/mm) of the design's focus against the store's, checked against its margin."""
    info = store.manifest.camera
    if abs(plan.cam.fov_deg - info.fov_deg) > 1e-9 or plan.cam.R_max_mm > info.lens_radius_mm * (
        1 + 1e-9
    ):
        raise ParameterError(
            f"the design's lens (fov {plan.cam.fov_deg:g} deg, R_max {plan.cam.R_max_mm:g} mm) "
            f"is not the store's ({info.fov_deg:g} deg, {info.lens_radius_mm:g} mm)"
        )
    return refocus_shear(store, plan.sensor_params()["focus_distance"], plan.cam.R_max_mm)


def refocus_shear(store: Store, focus_mm: float, R_max_mm: float) -> float:
    """k (px/mm) of a camera focused at ``focus_mm`` against the store's, refused (naming the
    margin it needs) where its lens of radius ``R_max_mm`` refocuses beyond the store's margin."""
    info = store.manifest.camera
    k = geo.shear_px_per_mm(info.f_px, info.focus_mm, focus_mm)
    need = geo.margin_px(k, R_max_mm)
    if need > info.margin_px:
        raise ParameterError(
            f"the design focuses at {focus_mm:g} mm, {need} px of refocus from the store's "
            f"{info.focus_mm:g} mm, beyond its margin of {info.margin_px} px: render the "
            f"store with margin_px >= {need}"
        )
    return k


def check_passes(store: Store, passes=None) -> tuple[int, ...]:
    """``passes`` (default: all the store's), checked: distinct store pass indices, at least
    one."""
    n = store.manifest.passes
    if passes is None:
        return tuple(range(n))
    got = tuple(int(p) for p in passes)
    if not got or len(set(got)) != len(got) or not all(0 <= p < n for p in got):
        raise ParameterError(f"passes: distinct store passes in 0..{n - 1}, got {list(passes)!r}")
    return got


def weighted_samples(store: Store, plan, params, design_plan, progress: bool = False,
                     passes=None):  # fmt: skip
    """The store's samples as the design's camera sees them, shard by shard.

    Yields
    ------
    (int, dict, numpy.ndarray, numpy.ndarray, numpy.ndarray)
        The store pass, the shard's records (``u``, ``v`` lens points in mm, ``L`` radiance
        (channels, n)), each sample's time on the design's shutter clock (ms), its pixel in
        the window (h * w for a point outside it) and its weight before the design's
        transmission: its step's share of the exposure / (spp p pi R_max^2), times cos^4 where
        the design has it. Only ``passes`` (:func:`check_passes`; default all).
    """
    info = store.manifest.camera
    k = _shear(store, plan)
    x0, y0, w, h = info.window
    steps = store.manifest.steps
    cos4 = params.get("relative_illumination") == "cos4"
    offset = design_plan.t_mid - store.manifest.mid_ms  # the paper's t = 0 is shared
    lens_area = np.pi * info.lens_radius_mm**2
    chosen = check_passes(store, passes)
    bar = tqdm(total=sum(len(steps[p]) for p in chosen), desc="synthesis", disable=not progress)
    for p in chosen:
        for rec, meta in store.shards(p):
            t = rec["t"] + offset if "t" in rec else meta["time"] + offset  # a step: one time
            x = geo.shifted(rec["x"], rec["u"], k) - np.float32(x0)
            y = geo.shifted(rec["y"], rec["v"], k) - np.float32(y0)
            share = (meta["t1"] - meta["t0"]) / info.exposure_ms / meta["spp"]
            weight = np.float32(share / lens_area) / rec["p"]
            if cos4:
                weight = weight * cos4_at_film(x + x0, y + y0, info.sensor_px, info.f_px)
            yield p, rec, t, _pixels(x, y, w, h), weight
            bar.update()
    bar.close()


def pass_images(store: Store, plan, params, design_plan, progress: bool = False, passes=None):
    """Each store pass (of ``passes``, default all) binned into one pass of the capture (a
    list of images), and the number of samples with weight > 0."""
    masks = params.get("masks")
    masks = None if masks is None else np.asarray(masks, np.float32)
    contrast = params.get("lcos_contrast")
    switch = params.get("lcos_switching")
    _, _, w, h = store.manifest.camera.window
    c, n = store.manifest.channels, store.manifest.passes
    sums = np.zeros((n, c, h * w + 1))  # the last bin takes what falls outside the window
    used = 0
    for p, rec, t, pix, weight in weighted_samples(store, plan, params, design_plan, progress,
                                                   passes):  # fmt: skip
        a = transmission(design_plan, rec["u"], rec["v"], t, masks, contrast, switch)
        for ch in range(c):  # L is (channels, n): each row a contiguous weight
            sums[p, ch] += np.bincount(pix, rec["L"][ch] * (a * weight), minlength=h * w + 1)
        used += int(np.count_nonzero((a > 0) & (pix < h * w)))
    images = []
    for image in sums[list(check_passes(store, passes))]:
        img = np.moveaxis(image[:, :-1].reshape(c, h, w), 0, -1)
        images.append(img[..., 0] if c == 1 else img)
    return images, used


def _pixels(x: np.ndarray, y: np.ndarray, w: int, h: int) -> np.ndarray:
    """The window's pixel index of each film point (px from the window's corner); h * w for a
    point outside it."""
    ix, iy = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    inside = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
    return np.where(inside, iy * w + ix, h * w)


def _check_scene_name(store: Store, spec) -> None:
    """Refuse a capture of another scene than the store's, naming the store's scene."""
    theirs = store.manifest.capture["scene"]
    if spec.scene != theirs:
        raise ParameterError(
            f"the store at {store.folder} is of scene {theirs!r}, not `scene` {spec.scene!r}: a "
            f"store serves captures of its own scene only; synthesise from it with scene "
            f"{theirs!r}, or render a store of {spec.scene!r}"
        )


def _scene(store: Store, spec, description):
    """The store's scene description, checked against the digest it was rendered with (its
    name first: another scene's digest differs too, and says less)."""
    _check_scene_name(store, spec)
    desc = description if description is not None else load_scene(spec.scene)
    if scene_digest(desc) != store.manifest.scene_digest:
        raise ParameterError(
            f"the scene {spec.scene!r} is not the one the store at {store.folder} was rendered "
            "from (its digest differs: edited since, or another description)"
        )
    return desc
