"""The schedule's objective on rendered captures: each light-field store's capture of a design,
through the sensor and the deconvolver, scored on the moving objects against ``sharp``.

For a centres design (n openings of the base design's radius, at its focus) the capture is a
sum of n images of the store's :class:`~pacam_render.lightfield.centre_basis.CentreBasis`, so
one evaluation is a sum, the sensor's noise, a Wiener deconvolution with the design's analytic
PSF and a score: milliseconds to a fraction of a second, not a render. Occlusion, parallax and
the 16 held patterns are in the captures, because they are in the store's rays.

No oracle: the deconvolver is told what a user of the camera can know, the sensor's noise
(from its calibration) and the render's Monte Carlo noise, never an error measured against
``sharp``. The sensor's noise is drawn from fixed seeds, the same for every design (common
random numbers: designs are compared on the same noise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..capture.result import Capture
from ..errors import ParameterError
from ..exposure.render_time import say
from ..limits import duration
from ..model.camera import CameraDesign
from ..restore.capture_score import deconvolve_capture, flat_sigma, radiance
from ..restore.metrics import shift_search_px
from ..restore.object_score import moving_object_se, moving_shapes, shift_bounds
from ..sensor.apply import apply_sensor, clean_level, sensor_sigma
from ..sensor.model import SensorModel

DEFAULT_METHOD = "wiener"
"""The deconvolver the search scores with: the Fourier objective's own (Wiener, 1/f^2
prior), and the fastest of the methods."""


class CaptureScorer:
    """A capture through the sensor and the deconvolver, scored on its moving objects.

    Parameters
    ----------
    template : Capture
        A capture of the scene and window with its truth layers: the moving objects, the
        shift search and the render's Monte Carlo sigma (told to the deconvolver) are its.
    sensor : str
        The sensor preset; ``light_level`` its photons/px/ms of white through the full lens.
    seeds : tuple of int
        The sensor's noise draws; :meth:`psnr_db` averages their squared errors.
    method : str
        The deconvolver.
    """

    def __init__(self, template, sensor: str, light_level, seeds, method=DEFAULT_METHOD):

        rec = template.record
        if "sharp" not in template.extra_layers:
            raise ParameterError("the capture has no truth layers (sharp): it cannot be scored")
        self.model = SensorModel.from_preset(sensor)
        self.light_level, self.seeds, self.method = light_level, tuple(seeds), method
        self.moving = moving_shapes(template.extra_layers, rec.objects or {})
        if not self.moving:
            raise ParameterError(
                "the window shows no moving object: the rendered objective scores the moving "
                "objects (take a window with one)"
            )
        self.shift = shift_search_px(rec.spec["width"])
        self.render_sigma = flat_sigma(template, rec.render_error.mc_sigma_white_units)

    def psnr_db(self, cap) -> float:
        """PSNR of ``cap``'s moving objects (dB, white = 1) after the sensor and the
        deconvolver, squared errors averaged over the seeds."""
        per = self.object_se(cap).values()
        return float(-10.0 * np.log10(sum(v[0] for v in per) / sum(v[1] for v in per)))

    def psnr_by_object(self, cap) -> dict[str, float]:
        """As :meth:`psnr_db`, each moving object's own (dB)."""
        return {k: float(-10.0 * np.log10(se / n)) for k, (se, n) in self.object_se(cap).items()}

    def object_se(self, cap) -> dict:
        """Each moving object's squared error and count over the seeds' restorations."""
        rec = cap.record
        out: dict[str, list] = {}
        for seed in self.seeds:
            _, noisy, _ = apply_sensor(cap, self.model, self.light_level, seed)
            level = clean_level(cap)  # not the noisy layer's: negative at low light
            sigma = flat_sigma(cap, sensor_sigma(rec, self.model, self.light_level, level))
            total = math.hypot(sigma, self.render_sigma)
            est = deconvolve_capture(cap, radiance(cap, noisy), total, self.method)
            bounds = shift_bounds(cap.extra_layers, rec.objects, self.moving, rec, self.shift)
            per = moving_object_se(
                est, cap.extra_layers, rec.objects, self.moving, self.shift, bounds
            )
            for name, (se, n) in per.items():
                acc = out.setdefault(name, [0.0, 0])
                acc[0], acc[1] = acc[0] + se, acc[1] + n
        if not out:
            raise ParameterError("no moving object has enough visible pixels to be scored")
        return {k: tuple(v) for k, v in out.items()}


@dataclass
class StoreObjective:
    """One store's rendered objective (module docstring): ``basis`` gives a candidate's image,
    ``template`` (the base design synthesised from the store) its record and truth, and
    ``scorer`` its score."""

    basis: object
    template: object
    scorer: CaptureScorer

    def __post_init__(self):
        self.cam = _camera(self.template.record)

    def capture(self, index):
        """The candidate's capture: the template with its image and camera."""

        image = self.basis.compose(index)
        image = image[..., 0] if self.template.image.ndim == 2 else image
        centres = tuple((float(x), 0.0) for x in self.basis.positions_mm[np.asarray(index)])
        cam = self.cam.with_(pattern_centres_mm=centres)
        # the camera and its optics whole, as the capture assembly records a design's
        record = replace(self.template.record, camera=cam.inputs(), optics=cam.summary())
        return Capture(image, {}, record, dict(self.template.extra_layers))

    def psnr_db(self, index) -> float:
        """The candidate's :meth:`CaptureScorer.psnr_db`."""
        return self.scorer.psnr_db(self.capture(index))


def _camera(record):
    """The record's mode camera, whose centres a candidate replaces."""

    cam = CameraDesign.from_inputs(record.camera)
    if record.mode != "coded":
        raise ParameterError(f"a centres search scores the coded mode, got {record.mode!r}")
    return cam


@dataclass
class SearchTrace:
    """A coordinate search's path: per accepted move and sweep end, (evaluations, seconds,
    worst case dB), and its final index and per-store scores."""

    rows: list
    index: np.ndarray
    worst_db: float
    per_store_db: list
    evaluations: int


def worst_case(objectives, index) -> tuple[float, list[float]]:
    """The lowest of the stores' PSNRs (dB) and each store's."""
    per = [o.psnr_db(index) for o in objectives]
    return min(per), per


def coordinate_search(objectives, start, sweeps: int, seed: int, progress: bool = True):
    """Maximise the worst case over the stores, one pattern's centre at a time.

    Each step tries every candidate centre for one pattern (patterns in an order drawn from
    ``seed`` per sweep) with the others held, and keeps the best if it raises the worst case.
    Gradient-free: the score passes through a deconvolution, a best-shift alignment and the
    worst case, and on the grid it is exact, so there is no finite-difference step to choose.
    Stops after ``sweeps`` sweeps, or after a sweep that moves nothing.

    Returns
    -------
    SearchTrace
    """
    import time

    from tqdm import tqdm

    if int(sweeps) != sweeps or sweeps < 1:
        raise ParameterError(f"`sweeps` must be an integer >= 1, got {sweeps!r}")
    basis = objectives[0].basis
    n, J = basis.n_patterns, len(basis.positions_mm)
    index = np.array(start, int)
    t0 = time.perf_counter()
    best, per = worst_case(objectives, index)
    evals = len(objectives)
    rows = [(evals, 0.0, best, 0)]
    rng = np.random.default_rng(seed)
    total = sweeps * n * (J - 1) * len(objectives)
    if progress:  # the first evaluation, timed, sizes the rest
        each = (time.perf_counter() - t0) / len(objectives)
        say(f"estimate: rendered search at most {duration(total * each)} ({evals + total} "
            f"evaluations of {duration(each)}, the first done and timed; it stops after a "
            "sweep that moves nothing)")  # fmt: skip
    with tqdm(total=total, desc="rendered search", unit="eval", disable=not progress) as bar:
        for sweep in range(1, sweeps + 1):
            moved = False
            for k in rng.permutation(n):
                held = index[k]  # scored already: the others are tried against it
                for j in range(J):
                    if j == held:
                        continue
                    trial = index.copy()
                    trial[k] = j
                    worst, trial_per = worst_case(objectives, trial)
                    evals += len(objectives)
                    bar.update(len(objectives))
                    if worst > best + 1e-9:
                        index, best, per, moved = trial, worst, trial_per, True
                        rows.append((evals, time.perf_counter() - t0, best, sweep))
            rows.append((evals, time.perf_counter() - t0, best, sweep))
            if not moved:
                break
    return SearchTrace(rows, index, best, per, evals)
