"""Registration of the Mitsuba sensors ``programmable_aperture`` and ``pacam_psf_camera``.

Mitsuba's Python plugins are module-level classes that derive from the *active* variant's
``mi.Sensor``; after a variant switch, Mitsuba re-imports them (``ad/integrators/__init__``).
This module does the same for ours: :mod:`.aperture_camera` and :mod:`.psf_camera` are imported
on the first :func:`register` (or :func:`~.backend.select_variant`, or render), and re-imported and
registered again after every variant switch. Nothing here imports Mitsuba at import time, so
``import pacam_render`` stays light.

:func:`sensor_dict` is the ``mi.load_dict`` entry of our sensor; :func:`sensor_entry` is a
capture's whole camera: that sensor (or a pinhole for the reference) with its film and sampler.
"""

from __future__ import annotations

import importlib
import sys

import numpy as np

from ..errors import ParameterError, check_positive
from ..model import paper
from ..model.camera import CameraDesign
from ..model.illumination import film_tan_max, parse_relative_illumination
from ..model.optics import focal_length_px
from .plan import PROP_KEYS, build_plan, hand_over
from .samplers import quantum, sampler_dict
from .variant import activate_variant

PLUGIN_NAME = "programmable_aperture"
"""The Mitsuba plugin name of the programmable-aperture camera (``type`` in a scene)."""
PSF_PLUGIN_NAME = "pacam_psf_camera"
"""The Mitsuba plugin name of the camera that PSF renders trace particles into."""
_MODULES = (
    ("aperture_camera", "ProgrammableApertureCamera", PLUGIN_NAME),
    ("psf_camera", "PSFCamera", PSF_PLUGIN_NAME),
)
_registered: str | None = None  # the variant the plugins were last registered for


_DEPENDENCIES = {
    "aperture_camera": (
        "kernels.types",
        "kernels.schedule_lookup",
        "kernels.aperture_sampling",
        "kernels.relative_illumination",
        "kernels.aperture_optics",
        "kernels.defocus_draw",
    )
}
"""Variant-bound modules a plugin module imports: re-imported first, in this order."""


def _module(name: str, variant: str):
    """Our plugin module, imported (or re-imported) for ``variant``, after the variant-bound
    modules it imports (:data:`_DEPENDENCIES`)."""
    for dep in _DEPENDENCIES.get(name, ()):
        _module(dep, variant)
    full = f"{__package__}.{name}"
    mod = sys.modules.get(full)
    if mod is None:
        return importlib.import_module(full)
    return mod if mod.VARIANT == variant else importlib.reload(mod)


def sensor_class(variant: str | None = None) -> type:
    """The ``programmable_aperture`` class of the active variant (``variant`` must be it).

    Parameters
    ----------
    variant : str, optional
        A Mitsuba variant name; None means the active one.

    Returns
    -------
    type
        ``ProgrammableApertureCamera`` from :mod:`pacam_render.render.aperture_camera`, imported (or
        re-imported) for the active variant.

    Raises
    ------
    ParameterError
        If no Mitsuba variant is active, or ``variant`` is not the active one.
    """
    import mitsuba as mi

    active = mi.variant()
    if active is None:
        raise ParameterError("no Mitsuba variant is active: call backend.select_variant() first")
    if variant not in (None, active):
        raise ParameterError(
            f"the sensor class exists for the active variant {active!r} only, not {variant!r}"
        )
    return _module("aperture_camera", active).ProgrammableApertureCamera


def register() -> str:
    """Register both sensors for the active variant (choosing one if none is).

    Idempotent; :func:`install` makes it follow variant switches. Returns the variant name.

    Returns
    -------
    str
        The active Mitsuba variant, for which ``programmable_aperture`` and
        ``pacam_psf_camera`` are now registered.

    Notes
    -----
    With no variant active, :func:`~pacam_render.render.variant.activate_variant` chooses and
    activates one (as :func:`~pacam_render.render.backend.select_variant` does), and
    :func:`install` registers.
    """
    global _registered
    import mitsuba as mi

    variant = mi.variant()
    if variant is None:
        activate_variant()
        install()  # which registers
        return mi.variant()
    for name, cls_name, plugin in _MODULES:
        cls = getattr(_module(name, variant), cls_name)
        mi.register_sensor(plugin, lambda props, cls=cls: cls(props))
    _registered = variant
    return variant


def _on_variant_change(old, new):
    if new is not None:
        register()


def ensure_registered() -> str:
    """Make sure both sensors exist for the active variant (choosing one if none is).

    Returns
    -------
    str
        The active Mitsuba variant.

    Notes
    -----
    With no variant active, :func:`~pacam_render.render.variant.activate_variant` chooses one
    (as :func:`~pacam_render.render.backend.select_variant` does); then :func:`install`
    registers the sensors if they are not yet registered for it.
    """
    import mitsuba as mi

    if mi.variant() is None:
        activate_variant()
    install()
    return mi.variant()


def install() -> None:
    """Register now if a variant is active, and again after every variant switch.

    Adds a Mitsuba variant callback (adding it twice is harmless) and calls :func:`register`
    if a variant is active and the sensors are not registered for it yet.
    """
    import mitsuba as mi

    mi.detail.add_variant_callback(_on_variant_change)  # a set: adding twice is harmless
    if mi.variant() is not None and _registered != mi.variant():
        register()


def sensor_dict(**params) -> dict:
    """A ``mi.load_dict`` entry for the sensor: numpy centres/masks become Dr.Jit tensors.

    Example: ``sensor_dict(fov=40, focus_distance=500, lens_radius=4.5,
    aperture_radius=1.3, schedule="parabolic", shutter_open=0, shutter_close=45,
    film={...})``.

    The parameters are checked here, so that bad input raises :class:`ParameterError` itself
    rather than wrapped in Mitsuba's ``RuntimeError``.

    Parameters
    ----------
    **params
        The sensor's properties (see :mod:`pacam_render.render.aperture_camera`): the plugin's own
        (:data:`~pacam_render.render.plan.PROP_KEYS`, e.g. ``lens_radius`` R_max and
        ``aperture_radius`` R in mm, ``schedule``, ``n_patterns``, ``image_acceleration`` in
        px/ms^2, ``reference_exposure`` in ms, ``relative_illumination`` off, cos4 or a curve
        file, and ``pixel_pitch`` in mm for a ``height_mm`` curve) and the camera's (``fov`` in
        deg, ``fov_axis``, ``focus_distance`` in mm, ``shutter_open`` and ``shutter_close`` in
        ms, ``film``, ``sampler``, ...).

    Returns
    -------
    dict
        ``{"type": "programmable_aperture", **params}``, with numpy arrays (and list or tuple
        ``centres`` and ``masks``) converted to float32 ``mi.TensorXf``.

    Raises
    ------
    ParameterError
        If ``lens_radius`` is missing, the focus distance (``focus_distance``, else
        ``far_clip``) is not > 0 mm, ``fov`` is not in (0, 180) deg, the schedule's
        parameters are invalid (:func:`~pacam_render.render.plan.build_plan`), or
        ``relative_illumination`` is not off, cos4 or a valid curve file that reaches the
        film's corner (:mod:`pacam_render.model.illumination`).

    Notes
    -----
    Imports Mitsuba, activates a variant if none is active and registers the sensors
    (:func:`ensure_registered`). The schedule is checked with :func:`build_plan` over the
    shutter interval, except for an ``image_acceleration`` without a horizontal ``fov``:
    turning it into a camera acceleration, a_c = a_i Z_f / f_px, needs the focal length in px,
    f_px = (W/2) / tan(fov/2).
    """

    ensure_registered()
    # validate here, so that bad input raises ParameterError itself (inside mi.load_dict it
    # arrives wrapped in a RuntimeError)
    cfg = {k: params[k] for k in PROP_KEYS if k in params}
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
        focal_px = focal_length_px(fov, width)
    tables = None
    if focal_px is not None or cfg.get("image_acceleration") is None:
        tables = build_plan(cfg, t0, t1, focal_px=focal_px, focus_mm=focus).tables
    if "relative_illumination" in params:
        _check_illumination(params, focal_px)

    out = {"type": PLUGIN_NAME, **{k: _property(k, v) for k, v in params.items()}}
    if tables is not None:  # the plugin takes the bitmaps' tables built here
        out["mask_tables"] = hand_over(tables, cfg)
    return out


def _property(key: str, v):
    """A parameter as Mitsuba's properties hold it: arrays (and list or tuple ``centres`` and
    ``masks``) as float32 ``mi.TensorXf``."""
    import mitsuba as mi

    if key in ("centres", "masks") and not isinstance(v, str) and not hasattr(v, "shape"):
        v = np.asarray(v)
    if isinstance(v, np.ndarray):
        return mi.TensorXf(np.ascontiguousarray(v, dtype=np.float32))
    if isinstance(v, (list, tuple)) and key in ("centres", "masks"):
        return mi.TensorXf(np.asarray(v, dtype=np.float32))
    return v


def _check_illumination(params: dict, focal_px: float | None) -> None:
    """``relative_illumination`` (and ``pixel_pitch``) as the plugin will parse them, and a
    curve against the film's farthest corner when the horizontal fov is known."""

    ri = parse_relative_illumination(params["relative_illumination"])
    pitch = params.get("pixel_pitch")
    pitch = None if pitch is None else check_positive("pixel_pitch", pitch, "mm")
    if ri.kind != "curve" or focal_px is None:
        return
    film = params.get("film") or {}
    w, h = int(film.get("width", 768)), int(film.get("height", 576))
    crop = (
        int(film.get("crop_offset_x", 0)),
        int(film.get("crop_offset_y", 0)),
        int(film.get("crop_width", w)),
        int(film.get("crop_height", h)),
    )
    ri.check_covers(film_tan_max(w, h, float(params["fov"]), crop), focal_px, pitch)


def sensor_entry(spec, design: CameraDesign, params: dict, exposure_ms: float) -> dict:
    """The scene's sensor: programmable_aperture, or a pinhole for the reference.

    Parameters
    ----------
    spec : CaptureSpec
        The capture (:class:`~pacam_render.exposure.spec.CaptureSpec`): uses ``mode``,
        ``width`` and ``height`` (px), ``crop`` and ``sampler``.
    design : CameraDesign
        The mode's camera (its field of view, deg).
    params : dict
        The sensor's schedule parameters
        (:func:`~pacam_render.exposure.camera.mode_camera`).
    exposure_ms : float
        The exposure 2T, ms: the shutter is open over [0, exposure_ms], and the paper's time is
        t = shutter time - T.

    Returns
    -------
    dict
        A ``mi.load_dict`` entry with an RGB float32 ``hdrfilm`` (luminance for ``spec.grey``,
        one channel in any variant) of width x height px, a box
        reconstruction filter (samples stay in their pixel, as the analytic PSFs assume) and the
        spec's sampler (each render sets its own sample count). For ``reference`` it is a
        ``perspective`` (pinhole) sensor; otherwise :func:`sensor_dict` with pixel values
        scaled to the paper's exposure (:data:`~pacam_render.model.paper.EXPOSURE_MS`).

    Raises
    ------
    ParameterError
        If :func:`sensor_dict` rejects the parameters.

    Notes
    -----
    Except for the reference, this activates a Mitsuba variant if none is active and registers
    the sensor plugins.
    """
    film = {
        "type": "hdrfilm",
        "width": spec.width,
        "height": spec.height,
        "rfilter": {"type": "box"},  # samples stay in their pixel, as the analytic PSFs assume
        "pixel_format": "luminance" if spec.grey else "rgb",
        "component_format": "float32",
    }
    if spec.crop is not None:
        x, y, w, h = spec.crop
        film.update(crop_offset_x=x, crop_offset_y=y, crop_width=w, crop_height=h)
    sampler = sampler_dict(spec.sampler, quantum(spec.sampler))  # each render sets its count
    if spec.mode == "reference":
        return {"type": "perspective", "fov": design.fov_deg, "film": film, "sampler": sampler}
    return sensor_dict(
        fov=design.fov_deg,
        shutter_open=0.0,
        shutter_close=exposure_ms,
        reference_exposure=paper.EXPOSURE_MS,
        film=film,
        sampler=sampler,
        **params,
    )
