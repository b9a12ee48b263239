"""Ground-truth layers of a capture: the scene at t = 0, seen through a pinhole.

Every capture can carry, beside its image, what a study scores it against:

========== ========== ==========================================================================
layer      channels   meaning
========== ========== ==========================================================================
sharp      R, G, B    the t = 0 pinhole image in passes like the capture's: its spp and seed
           (Y: grey)  (bit for bit the ``reference`` capture of the same spec), or its noise
                      target in white units
depth      Y          z of the surface seen at the pixel's centre, mm (the camera looks down +z);
                      0 where no surface is seen
object_id  Y          1 + the shape's index in the scene (``objects`` in the JSON names it);
                      0 where no surface is seen
velocity   U, V       the image velocity of that surface point at t = 0, px/ms of the capture's
                      pixels, from the scene's motions (0 for still shapes)
========== ========== ==========================================================================

``depth`` and ``object_id`` come from Mitsuba's ``aov`` integrator (``position`` and
``shape_index``) with one sample at each pixel's centre (a ``stratified`` sampler without
jitter), so an id is never a blend of two shapes at an edge. ``velocity`` differentiates the
pinhole projection of each pixel's surface point through its shape's motion.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..render.registry import sensor_entry
from ..render.samplers import quantum
from ..scenes.motion import project_px
from .checkpoint import Checkpoint
from .estimate import AbsoluteTarget
from .integrate import Run, integrate
from .steps import Exposure

TRUTH_LAYERS = ("sharp", "depth", "object_id", "velocity")
"""The ground-truth layers, in the order they are written."""
_DT_MS = 1e-3
"""Half-step of the central difference for the velocity, ms (exact for translations)."""


def render_truth(
    scene, desc, spec, design, sharp: bool = True, run=None, target_sigma: float | None = None
) -> tuple[dict, dict, object]:
    """The ground-truth layers of a capture of ``scene`` (its shapes at their t = 0 pose).

    Parameters
    ----------
    scene : mitsuba.Scene
        The capture's loaded scene, with every moving shape back at t = 0.
    desc : SceneDescription
        Its description (the motions).
    spec : CaptureSpec
        The capture (size, crop, spp, passes, sampler and seed).
    design : CameraDesign
        The capture's design at the capture's resolution (field of view, pixel scale).
    sharp : bool, optional
        Render the ``sharp`` layer (a ``reference`` capture is its own, so it skips it).
    run : Run, optional
        Signals (:class:`~pacam_render.exposure.integrate.Run`); None: none are watched.
    target_sigma : float, optional
        Render ``sharp`` to this Monte Carlo sigma (white = 1) instead of ``spec.spp``.

    Returns
    -------
    layers : dict of str to ndarray
        ``sharp`` (H, W, 3) if asked ((H, W) for a grey ``spec``), ``depth`` (H, W) mm,
        ``object_id`` (H, W) and ``velocity`` (H, W, 2) px/ms.
    objects : dict of str to str
        The legend: object id (as a string, JSON's keys) to shape id.
    sharp_stats : PassStats or None
        The sharp layer's passes (its Monte Carlo error), if rendered.

    Raises
    ------
    CaptureInterrupted
        On a signal during the sharp render.
    """
    import mitsuba as mi

    pinhole = sensor_entry(replace(spec, mode="reference"), design, {}, 0.0)
    layers, stats = {}, None
    if sharp:
        stats = _sharp_passes(scene, mi.load_dict(pinhole), spec, run, target_sigma)
        layers["sharp"] = stats.mean()
    position, registry = _surface_aovs(scene, pinhole)
    ids, objects = _object_ids(scene, registry)
    layers["depth"] = np.where(ids > 0, position[..., 2], 0.0)
    layers["object_id"] = ids.astype(np.float64)
    layers["velocity"] = velocity_layer(position, ids, objects, desc, design)
    return layers, objects, stats


def _sharp_passes(scene, sensor, spec, run, target_sigma):
    """The t = 0 pinhole image's passes, as a static capture's (same seeds and sizes)."""

    w, h = (int(v) for v in sensor.film().crop_size())
    exp = Exposure(scene, sensor, quantum=quantum(spec.sampler), pixels=w * h)
    run = run if run is not None else Run(None, False, 1e9, None)
    target = None if target_sigma is None else AbsoluteTarget(target_sigma)
    return integrate(exp, spec, run, Checkpoint(None, {}), target).stats


def _surface_aovs(scene, pinhole: dict) -> tuple[np.ndarray, np.ndarray]:
    """World position (H, W, 3) mm and Mitsuba's shape registry id (H, W) at pixel centres."""
    import mitsuba as mi

    centre = {**pinhole, "sampler": {"type": "stratified", "sample_count": 1, "jitter": False}}
    aov = mi.load_dict({"type": "aov", "aovs": "p:position,s:shape_index"})
    img = np.array(mi.render(scene, sensor=mi.load_dict(centre), integrator=aov, spp=1))
    return img[..., :3].astype(np.float64), np.rint(img[..., 3]).astype(np.int64)


def _object_ids(scene, registry: np.ndarray) -> tuple[np.ndarray, dict]:
    """Registry ids as 1 + the index in ``scene.shapes()``, and the legend."""
    import drjit as dr
    import mitsuba as mi

    shapes = scene.shapes()
    if not shapes:  # an empty scene: no surface anywhere
        return np.zeros_like(registry), {}
    reg = np.array(dr.reinterpret_array(mi.UInt32, scene.shapes_dr()), dtype=np.int64)
    lut = np.zeros(max(int(reg.max()), int(registry.max())) + 1, dtype=np.int64)
    lut[reg] = np.arange(1, len(shapes) + 1)
    objects = {str(k + 1): s.id() or f"shape_{k}" for k, s in enumerate(shapes)}
    return lut[registry], objects


def velocity_layer(position, ids, objects: dict, desc, design) -> np.ndarray:
    """Image velocity (u, v) at t = 0 of each pixel's surface point, px/ms.

    Parameters
    ----------
    position : ndarray
        (H, W, 3) world positions at t = 0, mm.
    ids : ndarray
        (H, W) object ids (0: no surface).
    objects : dict
        Object id (str) to shape id.
    desc : SceneDescription
        Its ``motions`` move the shapes.
    design : CameraDesign
        The pinhole projection (:func:`~pacam_render.scenes.motion.project_px`).

    Returns
    -------
    ndarray
        (H, W, 2): d/dt of the projected position at t = 0, by a central difference of
        +-1 us (exact for translations up to rounding); 0 for still shapes and no surface.
    """

    out = np.zeros(ids.shape + (2,))
    for key, name in objects.items():
        motion = desc.motions.get(name)
        mask = ids == int(key)
        if motion is None or motion.is_static or not mask.any():
            continue
        p = position[mask]
        ahead = project_px(motion.apply(p, _DT_MS), design)
        behind = project_px(motion.apply(p, -_DT_MS), design)
        out[mask] = (ahead - behind) / (2 * _DT_MS)
    return out
