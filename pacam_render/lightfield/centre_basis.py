"""Every centres schedule on a grid at once: one image per (pattern window, opening centre).

A centres design with n patterns shows, in window k of the exposure, a disc of radius R about
its centre X_k (mm along the lens's x). Its capture is linear in that transmission, so with
B[k, j] the store's samples of window k that fall in a disc about candidate centre x_j, a
design whose centres are on the grid is, exactly (the same samples, weights and estimator as
:func:`~.synthesis.synthesize`),

    capture = sum_k B[k, j_k]                       (an ideal LCoS)
    capture = sum_k (1 - 1/c) B[k, j_k] + F[k] / c  (contrast c: F[k] is window k's whole lens)

so a search over centres costs a sum of n images per design instead of a pass over the
store's samples. The focus, the radius, the exposure and the window's split into patterns are
the base design's: they decide the film points and the windows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ..exposure.plan import plan_capture
from .codes import design_aperture
from .store import Store
from .synthesis import _resolve, _scene, weighted_samples


@dataclass(frozen=True)
class CentreBasis:
    """B[k, j] and F[k] of one store (module docstring), the mean over its passes.

    ``images`` is (n, J, H, W, C) and ``full`` (n, H, W, C), capture units; ``positions_mm``
    the J candidate centres on the design's own x (``pattern_centres_mm``'s frame);
    ``contrast`` the LCoS's, or None for an ideal one; ``spec`` the base capture.
    """

    images: np.ndarray
    full: np.ndarray
    positions_mm: np.ndarray
    contrast: float | None
    spec: object
    samples: int

    @property
    def n_patterns(self) -> int:
        return self.images.shape[0]

    def compose(self, index) -> np.ndarray:
        """The capture (H, W, C) of the design with centre ``positions_mm[index[k]]`` in
        window k."""
        index = np.asarray(index)
        if index.shape != (self.n_patterns,):
            raise ParameterError(
                f"index: one candidate per pattern ({self.n_patterns}), got shape {index.shape}"
            )
        out = self.images[np.arange(self.n_patterns), index].sum(axis=0, dtype=np.float64)
        if self.contrast is not None:
            out = out * (1.0 - 1.0 / self.contrast) + self.full.sum(axis=0) / self.contrast
        return out


def plugin_sign(spec) -> float:
    """+1 or -1: the plugin's local x of a design's centre over the design's own x (the
    plugin's frame mirrors the lens's x), from the base design's own centres."""

    plan = plan_capture(spec)
    params = plan.sensor_params()
    ours = plan.cam.pattern_centres_xy_mm()[:, 0]
    theirs = design_aperture(plan, params).centres_mm[:, 0]
    if ours.shape != theirs.shape or not np.any(ours):
        raise ParameterError("the base design needs n centres off the axis to fix the frame")
    s = float(np.sign(np.dot(ours, theirs)))
    if not np.allclose(theirs, s * ours, atol=1e-9):
        raise ParameterError("the plugin's centres are not the design's, mirrored or not")
    return s


def centre_basis(store: Store, spec, positions_mm, progress: bool = False) -> CentreBasis:
    """:class:`CentreBasis` of ``store`` for the centres designs of ``spec``'s camera.

    Parameters
    ----------
    store : Store
    spec : CaptureSpec
        The base capture: a coded centres or parabolic design (its n, R, focus and exposure
        are kept), served by the store (:func:`~.synthesis.synthesize`'s checks).
    positions_mm : array_like
        Candidate centres on the design's x, mm; each disc must lie inside the lens.

    Returns
    -------
    CentreBasis
    """

    _scene(store, spec, None)
    plan, params, design_plan = _resolve(store, spec)
    if design_plan.schedule not in ("centres", "parabolic") or design_plan.kind == "bitmap":
        raise ParameterError(
            f"a centres search needs a disc schedule, got {design_plan.schedule!r}"
        )  # fmt: skip
    X = np.asarray(positions_mm, float)
    R, reach = design_plan.radius_mm, plan.cam.R_max_mm - design_plan.radius_mm
    if X.ndim != 1 or not len(X) or np.any(np.abs(X) > reach * (1 + 1e-9)):
        raise ParameterError(
            f"positions_mm: centres within +-{reach:.4g} mm (R_max - R), got {X.tolist()}"
        )
    x_plugin = plugin_sign(spec) * X
    n, J = len(design_plan.is_open), len(X)
    _, _, w, h = store.manifest.camera.window
    c, passes = store.manifest.channels, store.manifest.passes
    hw = h * w
    sums = np.zeros((c, (n * (J + 1)) * hw + 1))
    samples = 0
    for _, rec, t, pix, weight in weighted_samples(store, plan, params, design_plan, progress):
        t = np.broadcast_to(np.asarray(t, float), pix.shape)
        inside = (t >= design_plan.t_open) & (t < design_plan.t_close)
        k = design_plan.pattern_at(np.clip(t, design_plan.t_open, design_plan.t_close))
        keep = inside & design_plan.is_open[k] & (pix < hw)
        rows = np.nonzero(keep)[0]
        d2 = (rec["u"][rows, None] - x_plugin[None]) ** 2 + rec["v"][rows, None] ** 2
        hit_s, hit_j = np.nonzero(d2 < R * R)
        hit_s = np.concatenate([rows[hit_s], rows])  # and every kept sample in F[k]
        hit_j = np.concatenate([hit_j, np.full(len(rows), J)])
        bins = (k[hit_s] * (J + 1) + hit_j) * hw + pix[hit_s]
        for ch in range(c):
            sums[ch] += np.bincount(bins, rec["L"][ch][hit_s] * weight[hit_s],
                                    minlength=sums.shape[1])  # fmt: skip
        samples += len(rows)
    grid = np.moveaxis(sums[:, :-1].reshape(c, n, J + 1, h, w), 0, -1) / passes
    return CentreBasis(grid[:, :J].astype(np.float32), grid[:, J].astype(np.float32), X,
                       params.get("lcos_contrast"), plan.spec, samples)  # fmt: skip
