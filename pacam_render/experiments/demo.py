"""``pacam demo``: the train set captured as in the paper's Figs. 12-15, and deblurred.

Renders the train scene in ``reference``, ``normal``, ``coded`` and ``short`` modes, plus a
second coded capture whose design covers the near train's 1.4 px/ms (the published prototype
covers only |s| <= 0.9 px/ms, see the design report). Every capture except the reference goes
through the Grasshopper sensor model at a modest light level, so the short exposure is as noisy
as it would be. The coded captures are deconvolved with their analytic PSF (hyper-Laplacian
prior, :mod:`pacam_render.restore.sparse`; ``pacam reproduce train`` uses Wiener). One
side-by-side figure shows the full frames and magnified crops of both trains and the backdrop,
with PSNR and SSIM against the reference.

Alignment: a motion-invariant PSF moves each object by a speed-dependent amount (-s^2 / 2 a_i),
so each crop's PSNR is taken at the best whole-pixel horizontal shift within +-12 px; the
full-frame PSNR is not aligned.
"""

from __future__ import annotations

import textwrap
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..capture.kernels import analytic_psf
from ..errors import ParameterError
from ..exposure.direct import render_capture, write_capture
from ..exposure.plan import plan_capture
from ..exposure.render_time import overall_bar
from ..exposure.spec import CAMERA_OPTICS, CaptureSpec
from ..io.outputs import prepare_out_dir, save_figure, write_text
from ..model import paper
from ..model.camera import CameraDesign
from ..model.illumination import flat_field
from ..psf.analytic import design_psf
from ..psf_render.render import render_psf
from ..restore.capture_deblur import deblur_input
from ..restore.deconvolve import deconvolve
from ..restore.deconvolve_cost import deconvolve_cost
from ..restore.flat_field import RI_LAYER
from ..restore.metrics import aligned_psnr, crop, psnr, shift_search_px, ssim
from ..sensor.apply import add_sensor_layers
from ..sensor.model import SensorModel

SENSOR_PRESET = "grasshopper-icx285"
LIGHT_LEVEL = 300.0
"""photons/px/ms of white through F2.8: a dim indoor scene, dark enough that the short
exposure is noisy (Fig. 8: coding pays off when the coded capture's noise exceeds ~0.015)."""

CROPS = {  # (row0, row1, col0, col1) as fractions of the whole frame
    "far train": (0.27, 0.45, 0.10, 0.45),
    "near train": (0.57, 0.75, 0.15, 0.50),
    "backdrop": (0.02, 0.20, 0.02, 0.37),
}
DEMO_WINDOW = (0, 19, 672, 701)
"""The window of the prototype's 1280x960 sensor that the demo renders (x, y, w, h, px): every
crop of :data:`CROPS` with room for the alignment search. At this, the camera's own pixel
scale, r = 2 px and the trains blur over 45 and 63 px, as in the paper."""
DEMO_SPP = 1024
"""Samples per pixel of the full-scale demo: the moving captures keep one sampler render per
0.5 px time step (at 128 spp, which they used to inflate to about 1000, their steps would be
joined into one pose per pattern). 4.9 min on 2 idle cores, with a camera's optics (measured)."""


def window_crops(spec: CaptureSpec) -> dict[str, tuple[float, float, float, float]]:
    """:data:`CROPS` as fractions of the rendered image: the window's when ``spec.crop``."""
    if spec.crop is None:
        return dict(CROPS)
    x, y, w, h = spec.crop
    W, H = spec.width, spec.height
    return {
        name: ((r0 * H - y) / h, (r1 * H - y) / h, (c0 * W - x) / w, (c1 * W - x) / w)
        for name, (r0, r1, c0, c1) in CROPS.items()
    }


def max_shift_px(spec: CaptureSpec) -> int:
    """The alignment search for the capture's sensor (``restore.metrics.shift_search_px``)."""
    return shift_search_px(spec.width)


@dataclass
class Panel:
    title: str
    image: np.ndarray  # normalised: white ~ reflectance, like the reference
    note: str = ""


def _capture(plan, out: Path, seed: int, progress: bool = True):
    """Render one capture (a :class:`~pacam_render.exposure.plan.CapturePlan`); pass all but
    the reference through the sensor model."""

    partial = out / ".partial"  # no truth layers: the demo renders its own reference
    cap = render_capture(plan, partial_dir=partial, progress=progress, truth=False)
    if plan.spec.mode != "reference":
        model = SensorModel.from_preset(SENSOR_PRESET)
        add_sensor_layers(cap, model, SENSOR_PRESET, LIGHT_LEVEL, seed)
    return cap


@dataclass(frozen=True)
class Coded:
    """A coded design to capture: ``cover`` px/ms (preset pixels) or None for the preset."""

    label: str
    cover: float | None = None


DEMO_CODED = (Coded("prototype (F9.85, r=2)"), Coded("covers 1.4 px/ms", 1.4))


DEMO_METHOD = "hl"
"""The demo's deconvolution: at the full scale it gains 1.0 dB on the covering design's capture
where Wiener loses 1.7 (measured on the demo's own captures)."""


def _deconvolve(cap, rendered_psf: bool, spp_psf: int, method: str = DEMO_METHOD):
    """Estimates of a noisy coded capture (white = 1): analytic PSF, and rendered if asked;
    restored as ``pacam deconvolve`` restores it (the sensor's noise and the render's told,
    the layer flat-fielded: :func:`~pacam_render.restore.capture_deblur.deblur_input`)."""

    d = deblur_input({**cap.extra_layers, "capture": cap.image}, "noisy", cap.record, method)
    lf = cap.record.light_factor
    k = analytic_psf(cap.record)
    out = {"analytic PSF": deconvolve(d.image, k, method, **d.kw) / lf}
    if rendered_psf:
        cam = CameraDesign.from_inputs(cap.record.camera)
        rk = render_psf(cam, "coded", 0.0, size=k.shape, spp=spp_psf, origin="pinhole").kernel
        out["rendered PSF"] = deconvolve(d.image, rk, method, **d.kw) / lf
    return out


def _noisy(cap) -> np.ndarray:
    """The sensor's noisy image, normalised so that white reads about its reflectance, and
    flat-fielded by the capture's relative illumination, as a camera pipeline does."""

    raw = cap.extra_layers["noisy"] / cap.record.light_factor
    return flat_field(raw, cap.extra_layers.get(RI_LAYER))


def run_train(
    out: Path,
    width: int,
    height: int,
    spp: int,
    seed: int = 0,
    coded: tuple[Coded, ...] = DEMO_CODED,
    rendered_psf: bool = False,
    spp_psf: int = 1024,
    name: str = "demo",
    force: bool = False,
    crop: tuple[int, int, int, int] | None = None,
    method: str = DEMO_METHOD,
    progress: bool = True,
) -> tuple[Path, list[Panel], dict]:
    """Captures of the train set, deblurred, in one figure: returns (figure, panels, captures).

    ``crop`` renders that window of a width x height sensor (see :class:`CaptureSpec`). With
    ``progress``, the predicted time is said first and one bar covers every stage
    (:class:`~pacam_render.exposure.render_time.Overall`)."""

    out = prepare_out_dir(out, force)
    t0 = time.perf_counter()
    size = {"width": width, "height": height, "spp": spp, "seed": seed, "crop": crop}
    lens = {**size, **CAMERA_OPTICS}  # a camera's optics; the pinhole reference has none
    specs = {
        "reference": CaptureSpec.geometric(mode="reference", **size),
        "normal": CaptureSpec(mode="normal", **lens),
        **{
            f"coded_{i}": CaptureSpec(mode="coded", cover_px_per_ms=c.cover, **lens)
            for i, c in enumerate(coded)
        },
        "short": CaptureSpec(mode="short", **lens),
    }
    plans = {key: plan_capture(spec) for key, spec in specs.items()}
    overall = _overall(plans, method, name, progress)
    caps = {}
    with overall:
        for key, plan in plans.items():
            sub = out / key
            sub.mkdir(parents=True, exist_ok=True)
            with overall.stage(key):
                caps[key] = _capture(plan, sub, seed, progress)
            write_capture(caps[key], sub, force=True)  # the folder was cleared or created above
        with overall.stage("deblurring"):
            deblurred = [_deconvolve(caps[f"coded_{i}"], rendered_psf, spp_psf, method)
                         for i in range(len(coded))]  # fmt: skip
    ref = caps["reference"].image
    panels = [Panel("reference (pinhole, frozen)", ref)]
    panels.append(Panel("normal, 45 ms F9.85", _noisy(caps["normal"])))
    for i, c in enumerate(coded):
        panels.append(Panel(f"coded, {c.label}", _noisy(caps[f"coded_{i}"])))
        for how, est in deblurred[i].items():
            panels.append(Panel(f"deconvolved ({how}), {c.label}", est))
    short = caps["short"]
    panels.append(Panel(f"short, {paper.SHORT_EXPOSURE_MS} ms F{paper.F_MIN:g}", _noisy(short)))
    seconds = time.perf_counter() - t0
    fig_path = out / f"{name}.png"
    spec = specs["reference"]
    _figure(panels, ref, fig_path, window_crops(spec), max_shift_px(spec))
    caps["_seconds"] = seconds
    caps["_spec"] = spec
    return fig_path, panels, caps


def _overall(plans: dict, method: str, name: str, progress: bool):
    """One bar over the demo's captures (:func:`~pacam_render.exposure.render_time.overall_bar`) and
    its deblurring (:mod:`~pacam_render.restore.deconvolve_cost`), the estimate said first."""

    deblur = 0.0
    for plan in (p for p in plans.values() if p.spec.mode == "coded"):
        w, h = plan.window
        k = design_psf(plan.cam, "coded", 0.0, None, origin="pinhole")
        deblur += deconvolve_cost((h, w, 3), k.shape, method).seconds
    captures = {key: (plan, False) for key, plan in plans.items()}
    return overall_bar(captures, name, progress, {"deblurring": deblur})


def run_demo(
    out: Path,
    width: int | None = None,
    height: int | None = None,
    spp: int = DEMO_SPP,
    force: bool = False,
    seed: int = 0,
) -> Path:
    """The demo: normal, two coded designs (deblurred with the analytic PSF), short.

    By default it renders :data:`DEMO_WINDOW` of the prototype's full 1280x960 sensor, the
    camera at its real pixel scale. ``width`` and ``height`` render the whole frame of a binned
    sensor instead (fewer, larger pixels: r and the blur shrink with them).
    """
    crop = DEMO_WINDOW if width is None and height is None else None
    width, height = width or paper.WIDTH_PX, height or paper.HEIGHT_PX
    fig, panels, caps = run_train(out, width, height, spp, seed, force=force, crop=crop)
    text = _table(panels, caps["reference"].image, caps, spp, caps["_seconds"])
    write_text(out / "demo.md", text, force=True)
    return fig


def _figure(panels: list[Panel], ref: np.ndarray, path: Path, crops: dict, shift: int) -> None:
    """Full frames above, magnified crops below (one row each, named at the left); every
    panel but the reference's carries its PSNR against it, the crops' at their best shift."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h, w = ref.shape[:2]
    ratios = [h / w] + [(f[1] - f[0]) * h / ((f[3] - f[2]) * w) for f in crops.values()]
    n, col_in = len(panels), 2.3
    fig, axes = plt.subplots(1 + len(crops), n, figsize=(col_in * n, col_in * sum(ratios) + 1.6),
                             gridspec_kw={"height_ratios": ratios})  # fmt: skip
    for j, p in enumerate(panels):
        img = np.clip(p.image, 0, 1) ** (1 / 2.2)  # display gamma only
        axes[0, j].imshow(img)
        full = "" if j == 0 else f"\n{psnr(p.image, ref, 1.0):.1f} dB"
        axes[0, j].set_title(textwrap.fill(p.title, 24) + full, fontsize=10)
        for i, frac in enumerate(crops.values(), start=1):
            axes[i, j].imshow(crop(img, frac), interpolation="nearest")
            if j:
                score = aligned_psnr(p.image, ref, frac, shift)
                axes[i, j].set_title(f"{score:.1f} dB", fontsize=10, pad=2)
    axes[0, 0].set_ylabel(f"whole image\n{w}x{h} px", fontsize=10)
    for i, cname in enumerate(crops, start=1):
        axes[i, 0].set_ylabel(cname, fontsize=11)
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"PSNR against the reference (dB): whole image unaligned, crops at their "
                 f"best horizontal shift within +-{shift} px", fontsize=11)  # fmt: skip
    fig.tight_layout()
    save_figure(fig, path, 90)


def _table(panels, ref, caps, spp, seconds) -> str:
    spec = caps["_spec"]
    crops, shift = window_crops(spec), max_shift_px(spec)
    head = "| capture | PSNR (dB) | SSIM | " + " | ".join(f"{c} (dB, aligned)" for c in crops)
    lines = [head + " |", "|" + "---|" * (3 + len(crops))]
    for p in panels[1:]:
        cells = " | ".join(f"{aligned_psnr(p.image, ref, f, shift):.2f}" for f in crops.values())
        lines.append(
            f"| {p.title} | {psnr(p.image, ref, 1.0):.2f} | {ssim(p.image, ref):.3f} | {cells} |"
        )
    proto = caps["coded_0"].record.optics
    cover = caps["coded_1"].record.optics
    far, near = 1.0 * spec.width / 1280, 1.4 * spec.width / 1280
    text = [
        "# pacam demo: the train set (Figs. 12-15)",
        "",
        f"{_geometry(spec)}, {spp} spp, Grasshopper ICX285 sensor model at {LIGHT_LEVEL:g} "
        "photons/px/ms (white, F2.8), hyper-Laplacian deconvolution (Krishnan & Fergus 2009) "
        "with the analytic PSF and the "
        f"sensor's own noise model; {seconds:.0f} s in all.",
        "",
        f"The prototype's coded design (r = {proto['r_px']:.2f} px, a_i = "
        f"{proto['a_i_px_per_ms2']:.4f} px/ms^2 at this size) keeps speeds up to "
        f"{proto['velocity_range_px_per_ms']:.3f} px/ms invariant, less than the trains' "
        f"{far:.3f} and {near:.3f} px/ms here, so its trains stay blurred. The design that "
        f"covers 1.4 px/ms at full size (r = {cover['r_px']:.2f} px, a_i = "
        f"{cover['a_i_px_per_ms2']:.4f}) takes more defocus to reach them.",
        "",
        f"Crop PSNRs are taken at the best whole-pixel horizontal shift within +-{shift} px, "
        "because a motion-invariant PSF moves each object by -s^2 / (2 a_i). PSNR and SSIM "
        "without a crop are over the whole rendered image, not aligned.",
        "",
        *lines,
    ]
    return "\n".join(text) + "\n"


def _geometry(spec: CaptureSpec) -> str:
    if spec.crop is None:
        return f"the whole frame of a {spec.width}x{spec.height} px sensor (binned)"
    x, y, w, h = spec.crop
    return (
        f"a {w}x{h} px window at ({x}, {y}) of the {spec.width}x{spec.height} px sensor "
        "(the prototype's own pixels)"
    )


def check_size(width: int | None, height: int | None, spp: int) -> None:
    """Refuse a demo size before any work: --width, --height and --spp each >= 16, and both
    of --width and --height or neither."""
    for k, v in (("width", width), ("height", height), ("spp", spp)):
        if v is not None and v < 16:
            raise ParameterError(f"`{k}` must be >= 16 for the demo, got {v}")
    if (width is None) != (height is None):  # one alone would change the sensor's shape
        raise ParameterError(
            "`width` and `height` go together (a binned sensor's size, e.g. `width` 320 "
            "`height` 240); without either, the demo renders a window of the full sensor"
        )
