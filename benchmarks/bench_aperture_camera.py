"""Render time of the ``programmable_aperture`` sensor vs Mitsuba's built-in ``thinlens``.

Same scene, film, spp, shutter and integrator; only the sensor differs. Sensors are measured
side by side in one run: after one untimed warm-up render each (kernel compilation), every
round renders each sensor once (order rotated per round), and the ratio to ``thinlens`` is
taken within the round. The table gives the median ratio and half its min-max spread.

Sensors:
- ``thinlens``: the reference, aperture radius = lens radius;
- ``parabolic``: 16 discs on the paper's parabola, R = R_max * 2.8/9.85 (target <= 1.03);
- ``bitmap``: the same 16 discs as 1280x1024 LCoS masks (importance-sampled tables).

Scenes:
- ``cornell/path``: Mitsuba's Cornell box, path tracer (a typical render: the camera's share
  of the work is small);
- ``plane/direct``: one textured quad lit by a constant environment, ``direct`` integrator with
  one emitter sample (little work per camera ray: the camera's overhead shows most);
- ``psf/ptracer``: a small disc emitter seen by the particle tracer (``sample_direction``).

    python benchmarks/bench_aperture_camera.py [--quick]
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


def sensors(fov: float, focus: float, R_max: float, to_world, size: int) -> dict[str, dict]:
    """The three sensors, sharing film, shutter, optics and pose."""
    film = {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}}
    R = R_max * 2.8 / 9.85
    common = dict(fov=fov, focus_distance=focus, to_world=to_world, film=film, **SHUTTER)
    pitch = R_max / (DISPLAY_SHAPE[0] / 2)  # the display's height spans the lens
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


def case_sets(quick: bool):
    T = mi.ScalarTransform4f
    size = 128 if quick else 256
    cb = mi.cornell_box()["sensor"]
    return [
        (
            "cornell/path",
            cornell,
            sensors(cb["fov"], 3.9, 0.05, cb["to_world"], size),
            16 if quick else 64,
        ),
        ("plane/direct", plane, sensors(30.0, 800.0, 4.46, T(), size), 64 if quick else 256),
        ("psf/ptracer", psf, sensors(30.0, 800.0, 4.46, T(), size), 64 if quick else 512),
    ]


def render_once(scene, spp: int) -> None:
    img = mi.render(scene, spp=spp)
    dr.eval(img)
    dr.sync_thread()  # LLVM kernels run asynchronously: wait for this one


def timed(scene, spp: int) -> tuple[float, float]:
    """Wall-clock seconds (common.timeit) and CPU seconds of all threads, for one render."""
    c0 = time.process_time()
    (wall,) = timeit(lambda: render_once(scene, spp), repeat=1, warmup=0)
    return wall, time.process_time() - c0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller films, fewer rounds")
    ap.add_argument("--rounds", type=int, default=None)
    args = ap.parse_args()
    variant = select_variant()
    ac.register()
    os.environ.setdefault("PACAM_BENCH_VARIANT", variant)
    rounds = args.rounds or (5 if args.quick else 9)

    rows = []
    for scene_name, make, sens, spp in case_sets(args.quick):
        scenes = {k: mi.load_dict(make(v)) for k, v in sens.items()}
        names = list(scenes)
        wall: dict[str, list[float]] = {k: [] for k in names}
        cpu: dict[str, list[float]] = {k: [] for k in names}
        for k in names:  # compile
            render_once(scenes[k], spp)
        for r in range(rounds):
            order = names[r % len(names) :] + names[: r % len(names)]
            for k in order:
                w, c = timed(scenes[k], spp)
                wall[k].append(w)
                cpu[k].append(c)
        size = sens["thinlens"]["film"]["width"]
        for k in names:
            med, spread = median_spread(wall[k])
            rw = median_spread(list(np.array(wall[k]) / np.array(wall["thinlens"])))
            rc = median_spread(list(np.array(cpu[k]) / np.array(cpu["thinlens"])))
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
                    "target": "<= 1.03" if k == "parabolic" else "",
                }
            )
        print(f"{scene_name}: done", flush=True)
    notes = (
        f"{rounds} interleaved rounds after one warm-up render each; ratio = time / thinlens "
        "time in the same round (median, ± half the min-max range); wall = common.timeit, "
        "CPU = process CPU time of all threads (less sensitive to other load on the machine); "
        f"bitmap: 16 masks of {DISPLAY_SHAPE[1]}x{DISPLAY_SHAPE[0]}"
    )
    record("programmable_aperture vs thinlens render time (issue 3)", rows, notes)
    for r in rows:
        if r["sensor"] == "parabolic":
            print(
                f"parabolic, {r['scene']}: {r['ratio (wall)']:.3f} wall, "
                f"{r['ratio (CPU)']:.3f} CPU (target <= 1.03)"
            )


if __name__ == "__main__":
    main()
