"""Render time of the ``programmable_aperture`` sensor vs Mitsuba's built-in ``thinlens``.

Same scene, film, spp, shutter and integrator; only the sensor differs. Sensors are measured
side by side in one run: after one untimed warm-up render each (kernel compilation), every
round renders each sensor once (order rotated per round), and the ratio to ``thinlens`` is
taken within the round. The table gives the median ratio and half its min-max spread.

Sensors:
- ``thinlens``: the reference, aperture radius = lens radius;
- ``parabolic``: 16 discs on the paper's parabola, R = R_max * 2.8/9.85 (target <= 1.03);
- ``bitmap``: the same 16 discs as 1280x1024 LCoS masks (importance-sampled tables).

With ``--relative-illumination`` (issue 36) the sensors are instead ``thinlens``, ``static`` (the
plugin's full opening, ``off``: ray for ray thinlens), ``parabolic``, and each of the two with
``relative_illumination=cos4`` (``+cos4``); the table then also gives each ``+cos4`` sensor's
time over the same sensor with ``off`` in the same round (``vs off``; goal < 1.05), and a fourth
case, ``camera/rays``: ``sample_ray`` alone for N film positions (its ``spp`` column is N),
nothing traced, the bound on the factor's cost when the camera is all the work. With
``--diffraction`` the same set is timed with diffraction in the rays (``+diff``: the Airy pattern
of an F9.85 opening at 611/549/464 nm, 6.45 um pixels) against none.

Scenes:
- ``cornell/path``: Mitsuba's Cornell box, path tracer (a typical render: the camera's share
  of the work is small);
- ``plane/direct``: one textured quad lit by a constant environment, ``direct`` integrator with
  one emitter sample (little work per camera ray: the camera's overhead shows most);
- ``psf/ptracer``: a small disc emitter seen by the particle tracer (``sample_direction``).

    python benchmarks/bench_aperture_camera.py [--quick] [--relative-illumination | --diffraction]
"""

from __future__ import annotations

import argparse
import os
import time

import drjit as dr
import mitsuba as mi
import numpy as np
from common import median_spread, record, timeit

from pacam_render import render as ac
from pacam_render.model import schedule as sch
from pacam_render.render.backend import select_variant
from pacam_render.render.masks import DISPLAY_SHAPE, disc_masks

SHUTTER = dict(shutter_open=0.0, shutter_close=45.0)


def sensors(
    fov: float, focus: float, R_max: float, to_world, size: int, ri: bool = False
) -> dict[str, dict]:
    """The three sensors, sharing film, shutter, optics and pose; with ``ri`` the
    relative-illumination set (module docstring)."""
    film = {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}}
    R = R_max * 2.8 / 9.85
    common = dict(fov=fov, focus_distance=focus, to_world=to_world, film=film, **SHUTTER)
    pitch = R_max / (DISPLAY_SHAPE[0] / 2)  # the display's height spans the lens
    if ri:
        return {
            "thinlens": dict(type="thinlens", aperture_radius=R_max, **common),
            **{
                name + suffix: ac.sensor_dict(lens_radius=R_max, **extra, **kw, **common)
                for name, kw in (
                    ("static", {}),
                    ("parabolic", dict(aperture_radius=R, schedule="parabolic")),
                )
                for suffix, extra in _optics_variants(ri, R)
            },
        }
    masks = disc_masks(sch.pattern_centres_mm(R_max, R, 22.5, 16), R, pitch_mm=pitch)
    return {
        "thinlens": dict(type="thinlens", aperture_radius=R_max, **common),
        "parabolic": ac.sensor_dict(
            lens_radius=R_max, aperture_radius=R, schedule="parabolic", **common
        ),
        "bitmap": ac.sensor_dict(
            lens_radius=R_max, schedule="bitmap", masks=masks, mask_pitch=pitch, **common
        ),
    }


def cornell(sensor: dict) -> dict:
    d = mi.cornell_box()
    d["sensor"] = sensor
    d["integrator"] = {"type": "path", "max_depth": 6}
    return d


def plane(sensor: dict) -> dict:
    T = mi.ScalarTransform4f
    return {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": sensor,
        "env": {"type": "constant"},
        "quad": {
            "type": "rectangle",
            "to_world": T().translate([0, 0, 1000]) @ T().rotate([1, 0, 0], 180) @ T().scale(600),
            "bsdf": {
                "type": "diffuse",
                "reflectance": {"type": "checkerboard", "to_uv": mi.ScalarTransform3f().scale(8)},
            },
        },
    }


def psf(sensor: dict) -> dict:
    T = mi.ScalarTransform4f
    return {
        "type": "scene",
        "integrator": {"type": "ptracer", "max_depth": 2},
        "sensor": sensor,
        "emitter": {
            "type": "disk",
            "to_world": T().translate([0, 0, 1000]) @ T().rotate([1, 0, 0], 180) @ T().scale(0.5),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 1.0}},
        },
    }


def rays(sensor: dict) -> dict:
    """``camera/rays``: the sensor alone (:func:`rays_once` times its ``sample_ray``)."""
    return sensor


def rays_once(sensor, n: int) -> None:
    """``sample_ray`` for ``n`` random film and lens samples, evaluated: the camera's own
    work, nothing traced."""
    u = dr.arange(mi.Float, n) * (1.0 / n)
    v = u * 7919.0 - dr.floor(u * 7919.0)
    ray, w = sensor.sample_ray(u * 45.0, v, mi.Point2f(u, v), mi.Point2f(v, u))
    # one stored value per ray for every sensor: a weight that is one scalar (off) would
    # otherwise be stored once, and a per-ray one (cos4) 4M times, timing memory, not the factor
    dr.eval(ray.o + ray.d * w[0])
    dr.sync_thread()


def _optics_variants(ri, R: float):
    """("", off) and the one effect on: ``+cos4`` (``ri`` is ``"ri"``) or ``+diff`` (rays'
    diffraction at the R/G/B wavelengths, the F9.85 opening at 6.45 um pixels)."""
    if ri == "diffraction":
        on = dict(
            diffraction_wavelengths="611, 549, 464",
            pupil_distance=2 * 9.85 * R,  # R is the F9.85 opening
            pixel_pitch=0.00645,
        )
        return (("", {}), (SUFFIX[ri], on))
    return (("", {"relative_illumination": "off"}), ("+cos4", {"relative_illumination": "cos4"}))


SUFFIX = {"ri": "+cos4", "diffraction": "+diff"}


def case_sets(quick: bool, ri=False):
    T = mi.ScalarTransform4f
    size = 128 if quick else 256
    cb = mi.cornell_box()["sensor"]
    extra = [("camera/rays", rays, sensors(30.0, 800.0, 4.46, T(), size, ri), 1 << 22)]
    return (extra if ri else []) + [
        (
            "cornell/path",
            cornell,
            sensors(cb["fov"], 3.9, 0.05, cb["to_world"], size, ri),
            16 if quick else 64,
        ),
        ("plane/direct", plane, sensors(30.0, 800.0, 4.46, T(), size, ri), 64 if quick else 256),
        ("psf/ptracer", psf, sensors(30.0, 800.0, 4.46, T(), size, ri), 64 if quick else 512),
    ]


def render_once(scene, spp: int) -> None:
    img = mi.render(scene, spp=spp)
    dr.eval(img)
    dr.sync_thread()  # LLVM kernels run asynchronously: wait for this one


def timed(scene, spp: int, once=render_once) -> tuple[float, float]:
    """Wall-clock seconds (common.timeit) and CPU seconds of all threads, for one render."""
    c0 = time.process_time()
    (wall,) = timeit(lambda: once(scene, spp), repeat=1, warmup=0)
    return wall, time.process_time() - c0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller films, fewer rounds")
    ap.add_argument("--rounds", type=int, default=None)
    ap.add_argument(
        "--relative-illumination",
        action="store_true",
        help="time relative_illumination=cos4 against off (issue 36) instead of bitmap",
    )
    ap.add_argument(
        "--diffraction",
        action="store_true",
        help="time diffraction in the rays against none (issue 36) instead of bitmap",
    )
    args = ap.parse_args()
    variant = select_variant()
    ac.register()
    os.environ.setdefault("PACAM_BENCH_VARIANT", variant)
    rounds = args.rounds or (5 if args.quick else 9)

    rows = []
    ri = "diffraction" if args.diffraction else ("ri" if args.relative_illumination else False)
    suffix = SUFFIX.get(ri, "")
    for scene_name, make, sens, spp in case_sets(args.quick, ri):
        scenes = {k: mi.load_dict(make(v)) for k, v in sens.items()}
        names = list(scenes)
        once = rays_once if make is rays else render_once
        wall: dict[str, list[float]] = {k: [] for k in names}
        cpu: dict[str, list[float]] = {k: [] for k in names}
        for k in names:  # compile
            once(scenes[k], spp)
        for r in range(rounds):
            order = names[r % len(names) :] + names[: r % len(names)]
            for k in order:
                w, c = timed(scenes[k], spp, once)
                wall[k].append(w)
                cpu[k].append(c)
        size = sens["thinlens"]["film"]["width"]
        for k in names:
            med, spread = median_spread(wall[k])
            rw = median_spread(list(np.array(wall[k]) / np.array(wall["thinlens"])))
            rc = median_spread(list(np.array(cpu[k]) / np.array(cpu["thinlens"])))
            base = k.removesuffix(suffix) if suffix else k
            vs_off = {}
            if ri:  # each sensor with the effect against the same one without, round by round
                off_w = median_spread(list(np.array(wall[k]) / np.array(wall[base])))
                off_c = median_spread(list(np.array(cpu[k]) / np.array(cpu[base])))
                vs_off = {
                    "vs off (wall)": float(off_w[0]) if k != base else "",
                    "± (vs off)": float(off_w[1]) if k != base else "",
                    "vs off (CPU)": float(off_c[0]) if k != base else "",
                }
            rows.append(
                {
                    "scene": scene_name,
                    "sensor": k,
                    "film": f"{size}x{size}",
                    "spp": spp,
                    "median s": med,
                    "± s": spread,
                    "ratio (wall)": float(rw[0]),
                    "± (wall)": float(rw[1]),
                    "ratio (CPU)": float(rc[0]),
                    "± (CPU)": float(rc[1]),
                    **vs_off,
                    "target": _target(k, ri, suffix),
                }
            )
        print(f"{scene_name}: done", flush=True)
    notes = (
        f"{rounds} interleaved rounds after one warm-up render each; ratio = time / thinlens "
        "time in the same round (median, ± half the min-max range); wall = common.timeit, "
        "CPU = process CPU time of all threads (less sensitive to other load on the machine); "
        + (
            f"vs off = time / the same sensor's time without {suffix[1:]}, same round"
            if ri
            else f"bitmap: 16 masks of {DISPLAY_SHAPE[1]}x{DISPLAY_SHAPE[0]}"
        )
    )
    title = {
        "ri": "relative_illumination cos4 vs off render time (issue 36)",
        "diffraction": "diffraction in the rays vs none: render time (issue 36)",
    }.get(ri, "programmable_aperture vs thinlens render time (issue 3)")
    record(title, rows, notes)
    for r in rows:
        if ri and r["sensor"].endswith(suffix):
            print(
                f"{r['sensor']}, {r['scene']}: {r['vs off (wall)']:.3f} wall, "
                f"{r['vs off (CPU)']:.3f} CPU against off"
            )
        if r["sensor"] == "parabolic":
            print(
                f"parabolic, {r['scene']}: {r['ratio (wall)']:.3f} wall, "
                f"{r['ratio (CPU)']:.3f} CPU (target <= 1.03)"
            )


def _target(sensor: str, ri, suffix: str) -> str:
    if ri:
        return "vs off < 1.05" if sensor.endswith(suffix) else ""
    return "<= 1.03" if sensor == "parabolic" else ""


if __name__ == "__main__":
    main()
