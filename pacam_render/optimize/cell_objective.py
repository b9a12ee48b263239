"""A differentiable rendered objective over cell codes: expected moving-object PSNR after a
Wiener restoration with the code's own s = 0 kernel, and its gradient by hand (adjoint).

For a code A[k, c] on a :class:`~pacam_render.lightfield.cell_basis.CellBasis` (weights
w = (1 - 1/C) A + 1/C with an LCoS of contrast C, else A), everything is closed form:

    y = sum_kc w_kc B_kc                       capture, linear in A (the basis)
    L = sum_kc w_kc lambda_kc                  light factor: open area x time / (pi R_max^2 x T)
    K = sum_c u_c Q_c / sum_c u_c mu_c         kernel at s = 0, u_c = sum_k w_kc dt_k: cell c's
                                               square imaged at beta (X_c, Y_c) (Eq. 8), Q_c
                                               its pixel-integrated PSF of mass mu_c
    sigma^2(L) = (a + b l kappa L) / (kappa L)^2   the sensor's noise in white = 1 units
                                               (EMVA linear model: var = a + b e-, kappa the
                                               electrons of white through the full lens)
    X = conj(K) Z / (|K|^2 + s^2 / S)          Wiener on z = y / L (reflect-padded), S = c g(f)
                                               the 1/f^2 prior with c fitted once per store
                                               from the prototype's capture (held fixed),
                                               s^2 = sigma^2 + the store's render variance
                                               (told, as the scorer tells its deconvolver)
    E = ||M (x - sharp)||^2 + |M| sigma^2 mean_f |W|^2   expected squared error on the moving
                                               objects M (at the best integer shift along x)
    E_s = ||N (x - sharp)||^2 + |N| sigma^2 mean_f |W|^2  the same on the still pixels N (every
                                               pixel of no moving object, inside the scorer's
                                               columns, unshifted: as score_capture's still)

and the score is P = -10 log10(E / |M|) (dB, white = 1), or with a still weight w > 0 the
weighted mean (P + w P_s) / (1 + w), P_s = -10 log10(E_s / |N|); pooled over the stores by
their mean, or by the soft minimum of their gains over their own design
(:func:`pooled_objectives`).
The weighted mean is taken in dB, not in squared error: -10 log10 (E E_s^w) / (1 + w) counts a
relative change of either error alike (a design cannot ignore the still pixels because their
error is smaller, nor the moving objects because they are fewer pixels), and w = 1 weighs one
dB on the moving objects as one on the still regions. No oracle: the
restoration is told the sensor's noise and the class prior, never the truth; the truth only
scores. It is a model of :class:`~.rendered.CaptureScorer` (expected noise instead of drawn
noise, one fixed prior level, one shift for all moving objects, periodic padding of a reflect-
padded window); designs are finally scored by the scorer itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError
from ..lightfield.cell_basis import lens_pixels
from ..psf.bitmap import bitmap_kernel
from ..restore.capture_score import flat_sigma
from ..restore.deconvolve import prior_spectrum
from ..restore.flat_field import RI_LAYER
from ..restore.metrics import shift_search_px
from ..restore.object_score import moving_shapes
from ..sensor.apply import clean_level
from ..sensor.model import SensorModel

AGGREGATES = ("mean", "worst")
"""How a score is pooled over the training stores (:func:`pooled_objectives`): the mean, or
the soft minimum of each store's gain over its own design."""
WORST_SOFTNESS_DB = 0.5
"""tau of the "worst" aggregate's soft minimum (dB): gains that differ by several tau count
as the smallest alone; within tau they share the gradient (a hard minimum would hop between
stores from step to step)."""
SHIFT_PX = 3
"""The restored image is compared with ``sharp`` at the best integer shift along x within
+-SHIFT_PX (the kernel's origin is the pinhole's; a moving object's restoration is offset)."""


@dataclass
class CellProblem:
    """One store's fixed terms of the objective (module docstring), from :func:`cell_problem`."""

    B: np.ndarray  # (n, M, H, W, C)
    lam: np.ndarray  # (n, M) light factor per unit weight
    dt: np.ndarray  # (n,) window durations / exposure
    Qhat: np.ndarray  # (M, Hp, Wp) complex OTFs of the cells' PSFs (unit mass)
    mu: np.ndarray  # (M,) each cell's open area, relative
    S: np.ndarray  # (Hp, Wp) prior spectrum
    sharp: np.ndarray  # (H, W, C)
    mask: np.ndarray  # (H, W) moving objects away from the shift's edge columns
    still: np.ndarray  # (H, W) still pixels inside the scorer's columns (may be empty)
    pad: int
    noise: tuple  # (a, b, level, kappa)
    render_var: float  # the store's Monte Carlo variance, white = 1 (told, as the scorer's)
    contrast: float | None
    cells_ij: np.ndarray
    cells: int
    base_code: np.ndarray | None = None  # (n, G, G) the store's design (the "worst" gains')
    base_db: dict = field(default_factory=dict)  # still weight -> its objective (dB)


def _areas(basis) -> np.ndarray:
    """Each cell's open area in the clear aperture, a fraction of pi R_max^2 (its LCoS pixels
    that a mask may open, :func:`~pacam_render.lightfield.cell_basis.lens_pixels`)."""
    D, G = basis.display_px, basis.cells
    per = D // G
    ok = lens_pixels(D, basis.pitch_mm).reshape(G, per, G, per).sum(axis=(1, 3))
    return ok[basis.cells_ij[:, 0], basis.cells_ij[:, 1]] / (math.pi * (D / 2.0) ** 2)


def _cell_otfs(basis, cam, shape) -> tuple[np.ndarray, int]:
    """(M, Hp, Wp) OTFs of each cell's unit-mass s = 0 PSF (its square, imaged at beta times
    its place: :func:`~pacam_render.psf.bitmap.bitmap_kernel`, pinhole origin), on the padded
    grid of a (H, W) window, and the padding (px)."""
    G, pitch = basis.cells, basis.display_px * basis.pitch_mm / basis.cells
    size = bitmap_kernel(np.ones((1, G, G)), pitch, cam.beta_px_per_mm, cam.T_ms,
                         origin="pinhole").shape[0]  # fmt: skip
    pad = size // 2 + SHIFT_PX + 1
    if pad >= min(shape):
        raise ParameterError(f"the window {shape} is narrower than the kernel's reach {pad} px")
    Hp, Wp = shape[0] + 2 * pad, shape[1] + 2 * pad
    out = np.empty((len(basis.cells_ij), Hp, Wp), complex)
    for m, (i, j) in enumerate(basis.cells_ij):
        one = np.zeros((1, G, G))
        one[0, i, j] = 1.0
        k = bitmap_kernel(one, pitch, cam.beta_px_per_mm, cam.T_ms, size=size, origin="pinhole")
        big = np.zeros((Hp, Wp))
        big[:size, :size] = k
        out[m] = np.fft.fft2(np.roll(big, (-(size // 2), -(size // 2)), axis=(0, 1)))
    return out, pad


def _noise_terms(template, sensor: str, light_level: float) -> tuple:
    """(a, b, level, kappa): the sensor's variance a + b e- (EMVA linear model), the scene's
    mean level (white = 1) and the electrons of white through the full lens (kappa L is a
    design's, light factor L)."""
    rec = template.record
    model = SensorModel.from_preset(sensor)
    a = float(model.temporal_noise_e(0.0, rec.exposure_ms)) ** 2
    b = float(model.temporal_noise_e(1.0, rec.exposure_ms)) ** 2 - a
    kappa = model.qe * light_level * rec.reference_exposure_ms
    return a, b, clean_level(template), kappa


def sigma2(noise, L: float) -> tuple[float, float]:
    """The sensor's noise variance in white = 1 units at light factor L, and d/dL."""
    a, b, level, kappa = noise
    e = kappa * L
    return (a + b * level * e) / e**2, (-2 * a / e**3 - b * level / e**2) * kappa


def cell_problem(basis, template, plan, base_code, sensor: str, light_level: float,
                 dtype=np.float32, still_edge_px: int | None = None):  # fmt: skip
    """The fixed terms (:class:`CellProblem`) of one store's objective: ``template`` the base
    design's synthesised capture (truth, objects, exposure), ``plan`` its capture plan (camera,
    windows), ``base_code`` (n, G, G) that design on the cells (the prior's kernel).
    ``dtype`` of the capture's matrix products: float32 (the basis's own, 3x faster) or
    float64 (for finite differences finer than float32's rounding). ``still_edge_px``: the
    columns left out of the still term at each side (default the scorer's, its shift search
    at the capture's sensor width)."""
    layers, rec = template.extra_layers, template.record
    if RI_LAYER in layers:
        raise ParameterError("the cell objective assumes no relative illumination (cos4 off)")
    moving = moving_shapes(layers, rec.objects or {})
    ids = layers["object_id"]
    mask = np.isin(ids, [int(k) for k, v in (rec.objects or {}).items() if v in moving])
    edge = _scorer_edge_px(rec) if still_edge_px is None else int(still_edge_px)
    if edge < 0:
        raise ParameterError(f"still_edge_px: an integer >= 0, got {still_edge_px!r}")
    still = ~mask
    still[:, :edge] = still[:, ids.shape[1] - edge :] = False
    mask[:, :SHIFT_PX] = mask[:, ids.shape[1] - SHIFT_PX :] = False
    if not mask.any():
        raise ParameterError("the window shows no moving object: the objective scores them")
    params = plan.sensor_params()
    dp = plan.aperture(params)
    dt = open_times(np.diff(dp.pattern_edges), params.get("lcos_switching"))
    area = _areas(basis)
    sharp = layers["sharp"]
    sharp = sharp[..., None] if sharp.ndim == 2 else sharp
    Qhat, pad = _cell_otfs(basis, plan.cam, sharp.shape[:2])
    noise = _noise_terms(template, sensor, light_level)
    render = flat_sigma(template, rec.render_error.mc_sigma_white_units) ** 2
    B = np.asarray(basis.images, dtype)
    p = CellProblem(B, dt[:, None] * area[None], dt, Qhat, area, None, sharp, mask, still,
                    pad, noise, render, basis.contrast, basis.cells_ij, basis.cells,
                    np.asarray(base_code, float))  # fmt: skip
    u = np.asarray(base_code, float)[:, basis.cells_ij[:, 0], basis.cells_ij[:, 1]].T @ dt
    p.S = _prior(p, template, rec.light_factor, u)
    return p


def open_times(widths_ms, switch_ms: float | None = None) -> np.ndarray:
    """Each pattern window's share of the exposure that its code is shown for: its width,
    with a switching LCoS (t_s) less the t_s / 2 that the next window's first t_s still shows
    it on average (the pixels turn linearly), and plus the t_s / 2 it is shown into the next
    window: window 0 gains t_s / 2, the last window loses it (a cell's open time, the
    kernel's weight, is linear in the code either way)."""
    w = np.asarray(widths_ms, float).copy()
    if switch_ms:
        w[:-1] += 0.5 * switch_ms
        w[1:] -= 0.5 * switch_ms
    return w / float(np.sum(widths_ms))


def _scorer_edge_px(record) -> int:
    """The columns score_capture leaves out at each side: its shift search at the capture's
    sensor width (:func:`~pacam_render.restore.metrics.shift_search_px`)."""
    return int(shift_search_px(record.spec.get("width") or record.camera.get("width_px")))


def _prior(p: CellProblem, template, light_factor: float, u: np.ndarray) -> np.ndarray:
    """The 1/f^2 prior S = c g(f) on the padded grid, c fitted (:func:`~pacam_render.restore.
    deconvolve.prior_spectrum`) to the base design's capture with one draw of its noise and
    its kernel (cells open for times ``u``)."""
    img = np.asarray(template.image, float)
    img = img[..., None] if img.ndim == 2 else img
    s2 = sigma2(p.noise, light_factor)[0]
    z = img.mean(axis=-1) / light_factor
    z = z + np.random.default_rng(0).normal(0, math.sqrt(s2), z.shape)
    s2 += p.render_var
    zp = np.pad(z, p.pad, mode="reflect")
    Y = np.fft.rfft2(zp)
    K = np.tensordot(u * p.mu, p.Qhat, axes=1) / float(u @ p.mu)
    H2 = np.abs(K[:, : Y.shape[1]]) ** 2
    S_r = prior_spectrum(Y, H2, zp.shape, math.sqrt(s2))
    fy, fx = np.fft.fftfreq(zp.shape[0]), np.fft.fftfreq(zp.shape[1])
    f0 = 1.0 / max(zp.shape)
    g = 1.0 / (fy[:, None] ** 2 + fx[None, :] ** 2 + f0**2)
    c = float(S_r[0, 1] * (fy[0] ** 2 + np.fft.rfftfreq(zp.shape[1])[1] ** 2 + f0**2))
    return c * g  # per-pixel units: E|X|^2 = S under the unitary FFT


def _flat(B: np.ndarray) -> np.ndarray:
    """The basis as a (n M, H W C) matrix: a view of a contiguous basis (a matrix product,
    not an einsum's copy)."""
    return B.reshape(B.shape[0] * B.shape[1], -1)


def _pad_index(shape, pad: int) -> np.ndarray:
    """The flat window index of each padded pixel (reflect padding): forward ``z[idx]``,
    adjoint a bincount over ``idx``."""
    return np.pad(np.arange(shape[0] * shape[1]).reshape(shape), pad, mode="reflect")


def check_still_weight(problems, still_weight: float) -> float:
    """``still_weight`` checked: finite and >= 0, and with a weight some store has still
    pixels to score (a store with none scores its moving objects only)."""
    w = float(still_weight)
    if not (math.isfinite(w) and w >= 0):
        raise ParameterError(f"still_weight: a finite number >= 0, got {still_weight!r}")
    if w > 0 and not any(p.still.any() for p in problems):
        raise ParameterError("still_weight: no store's window shows a still pixel inside the "
                             "scorer's columns; score moving objects only")  # fmt: skip
    return w


def objective(p: CellProblem, code, grad: bool = True, still_weight: float = 0.0):
    """Expected PSNR (dB) of ``code`` (n, G, G) in [0, 1] on one store: the moving objects',
    or with ``still_weight`` w > 0 the weighted mean (P + w P_s) / (1 + w) with the still
    pixels' (module docstring; P alone where the store's scored columns hold no still pixel);
    and its gradient d PSNR / d code (n, G, G) when ``grad`` (adjoint by hand)."""
    vals, grads = objectives(p, np.asarray(code, float)[None], grad, still_weight)
    return float(vals[0]), None if grads is None else grads[0]


def objectives(p: CellProblem, codes, grad: bool = True, still_weight: float = 0.0):
    """:func:`objective` of S codes (S, n, G, G) at once: values (S,) and gradients (S, n, G,
    G) or None. The basis is read once for all of them (its matrix products take the S codes
    together: an evaluation is bound by reading the basis, not by arithmetic)."""
    still_weight = still_weight if p.still.any() else 0.0
    A = np.asarray(codes, float)
    scale = 1.0 if p.contrast is None else 1.0 - 1.0 / p.contrast
    w = np.stack([_weights(p, a) for a in A])
    H, W, Ch = p.sharp.shape
    Y = (w.reshape(len(A), -1).astype(p.B.dtype) @ _flat(p.B)).astype(float)
    fwd = [_forward(p, w[i], float(still_weight), Y[i].reshape(H, W, Ch)) for i in range(len(A))]
    vals = np.array([f["value"] for f in fwd])
    if not grad:
        return vals, None
    parts_ = [_backward(p, w[i], fwd[i]) for i in range(len(A))]
    g_y = np.stack([g.ravel() for g, _ in parts_]).astype(p.B.dtype)
    g_w = (g_y @ _flat(p.B).T).astype(float).reshape(w.shape) + np.stack([r for _, r in parts_])
    out = np.zeros_like(A)
    out[:, :, p.cells_ij[:, 0], p.cells_ij[:, 1]] = scale * g_w
    return vals, out


def _best_shift(p: CellProblem, xp: np.ndarray) -> tuple:
    """(squared error, shift, masked residual) on the moving objects at the best shift."""
    H, W, _ = p.sharp.shape
    best = None
    for sh in range(-SHIFT_PX, SHIFT_PX + 1):
        r = (xp[p.pad : p.pad + H, p.pad + sh : p.pad + sh + W] - p.sharp) * p.mask[..., None]
        se = float(np.sum(r * r))
        if best is None or se < best[0]:
            best = (se, sh, r)
    return best


def _forward(p: CellProblem, w: np.ndarray, still_weight: float = 0.0, y=None) -> dict:
    """The objective's forward pass, keeping what the adjoint needs (``y``: the capture
    sum w B where the caller has it)."""
    H, W, Ch = p.sharp.shape
    if y is None:
        y = (w.ravel().astype(p.B.dtype) @ _flat(p.B)).reshape(H, W, Ch).astype(float)
    L = float(np.sum(w * p.lam))
    if L <= 0:
        raise ParameterError("code: an all-black code collects no light")
    s2, ds2 = sigma2(p.noise, L)
    idx = _pad_index((H, W), p.pad)
    zp = (y / L).reshape(H * W, Ch)[idx]  # (Hp, Wp, C)
    Z = np.fft.fft2(zp, axes=(0, 1), norm="ortho")
    u = w.T @ p.dt  # (M,) each cell's open time
    mass = float(u @ p.mu)
    Kh = np.tensordot(u * p.mu, p.Qhat, axes=1) / mass
    D = np.abs(Kh) ** 2 + (s2 + p.render_var) / p.S
    Wf = np.conj(Kh) / D
    xp = np.fft.ifft2(Wf[..., None] * Z, axes=(0, 1), norm="ortho").real
    se, shift, r = _best_shift(p, xp)
    n_px = int(p.mask.sum()) * Ch
    w2 = float(np.mean(np.abs(Wf) ** 2))
    E = se + n_px * s2 * w2
    f = dict(y=y, L=L, s2=s2, ds2=ds2, idx=idx, Z=Z, u=u, mass=mass, Kh=Kh, D=D, Wf=Wf,
             shift=shift, r=r, n_px=n_px, w2=w2, E=E, psnr=-10.0 * math.log10(E / n_px),
             weight=still_weight)  # fmt: skip
    f["value"] = f["psnr"]
    if still_weight > 0:
        rs = (xp[p.pad : p.pad + H, p.pad : p.pad + W] - p.sharp) * p.still[..., None]
        n_s = int(p.still.sum()) * Ch
        if n_s == 0:
            raise ParameterError("still_weight: the window shows no still pixel to score")
        E_s = float(np.sum(rs * rs)) + n_s * s2 * w2
        f.update(r_s=rs, n_s=n_s, E_s=E_s, psnr_still=-10.0 * math.log10(E_s / n_s))
        f["value"] = (f["psnr"] + still_weight * f["psnr_still"]) / (1.0 + still_weight)
    return f


def _backward(p: CellProblem, w: np.ndarray, f: dict) -> np.ndarray:
    """d value / d w (n, M) as (d value / d y (H, W, C), the rest): the adjoint of
    :func:`_forward` (dE = Re sum conj(G) dX for each complex intermediate X, unitary FFTs),
    d value / d w = B d value / d y + the rest (the caller's matrix product, :func:`objectives`);
    the squared errors' weights cE, cS are d value / d E and d value / d E_s."""
    H, W, Ch = p.sharp.shape
    ws = f["weight"]
    cE = -10.0 / (math.log(10.0) * f["E"]) / (1.0 + ws)
    g_xp = np.zeros(f["Z"].shape)
    sh = f["shift"]
    g_xp[p.pad : p.pad + H, p.pad + sh : p.pad + sh + W] = 2.0 * cE * f["r"]
    n_eff = cE * f["n_px"]  # d value / d (s2 w2)
    if ws > 0:
        cS = -10.0 * ws / (math.log(10.0) * f["E_s"]) / (1.0 + ws)
        g_xp[p.pad : p.pad + H, p.pad : p.pad + W] += 2.0 * cS * f["r_s"]
        n_eff += cS * f["n_s"]
    G_X = np.fft.fft2(g_xp, axes=(0, 1), norm="ortho")
    G_Z = np.conj(f["Wf"])[..., None] * G_X
    G_W = np.sum(G_X * np.conj(f["Z"]), axis=-1) + 2.0 * n_eff * f["s2"] / f["Wf"].size * f["Wf"]
    g_s2 = n_eff * f["w2"]
    Kh, D = f["Kh"], f["D"]
    G_K = np.conj(G_W) / D
    q = np.real(np.conj(G_W) * np.conj(Kh)) / D**2
    G_K = G_K - 2.0 * q * Kh
    g_s2 += float(np.sum(-q / p.S))  # the regulariser's sensor share
    # Kh = sum_m u_m mu_m Q_m / mass: dKh/du_m = mu_m (Q_m - Kh) / mass
    proj = np.real(np.tensordot(p.Qhat.reshape(len(p.mu), -1), np.conj(G_K).ravel(), axes=1))
    g_u = p.mu * (proj - float(np.real(np.sum(np.conj(G_K) * Kh)))) / f["mass"]
    g_zp = np.fft.ifft2(G_Z, axes=(0, 1), norm="ortho").real
    g_z = np.stack([np.bincount(f["idx"].ravel(), g_zp[..., c].ravel(), minlength=H * W)
                    for c in range(Ch)], axis=-1).reshape(H, W, Ch)  # fmt: skip
    L = f["L"]
    g_y = g_z / L
    g_L = -float(np.sum(g_z * f["y"])) / L**2 + g_s2 * f["ds2"]
    return g_y, g_L * p.lam + p.dt[:, None] * g_u[None, :]


def pooled_objective(problems, code, grad: bool = True, still_weight: float = 0.0,
                     aggregate: str = "mean"):  # fmt: skip
    """:func:`pooled_objectives` of one code: its value (dB) and gradient."""
    vals, grads = pooled_objectives(problems, np.asarray(code, float)[None], grad, still_weight,
                                    aggregate)  # fmt: skip
    return float(vals[0]), None if grads is None else grads[0]


def pooled_objectives(problems, codes, grad: bool = True, still_weight: float = 0.0,
                      aggregate: str = "mean"):  # fmt: skip
    """:func:`objectives` of S codes pooled over the stores: values (S,) and gradients
    (S, n, G, G) or None.

    ``aggregate`` "mean": the mean over the stores. "worst": the soft minimum over the stores
    of each one's gain over its base design (the code :func:`cell_problem` was given, the
    store's own), g_i = P_i - b_i, at softness tau = :data:`WORST_SOFTNESS_DB`:

        value = mean_i b_i - tau log mean_i exp(-g_i / tau)

    between mean_i b_i + min_i g_i and the mean objective, equal to it where every store
    gains alike; its gradient weighs store i's by softmax(-g / tau)_i. Gains, not PSNRs: a
    scene that is hard for every camera (fine texture, low light) does not take the search.
    """
    check_aggregate(aggregate)
    got = [objectives(p, codes, grad, still_weight) for p in problems]
    V = np.stack([v for v, _ in got])  # (stores, S)
    if aggregate == "mean":
        pi = np.full(V.shape, 1.0 / len(problems))
        vals = V.mean(axis=0)
    else:
        b = np.array([base_value(p, still_weight) for p in problems])
        soft, pi = soft_minimum(V - b[:, None])
        vals = b.mean() + soft
    if not grad:
        return vals, None
    return vals, sum(w[:, None, None, None] * g for w, (_, g) in zip(pi, got))


def soft_minimum(gains) -> tuple[np.ndarray, np.ndarray]:
    """-tau log mean_i exp(-g_i / tau) over axis 0 of ``gains`` (tau = :data:`WORST_SOFTNESS_DB`)
    and its weights d/dg_i = softmax(-g / tau)_i (they sum to 1), overflow-safe."""
    z = -np.asarray(gains, float) / WORST_SOFTNESS_DB
    m = z.max(axis=0)
    e = np.exp(z - m)
    return -WORST_SOFTNESS_DB * (m + np.log(e.mean(axis=0))), e / e.sum(axis=0)


def base_value(p: CellProblem, still_weight: float) -> float:
    """The store's base design's :func:`objective` (dB) at ``still_weight``, kept once."""
    key = float(still_weight)
    if key not in p.base_db:
        p.base_db[key] = float(objectives(p, p.base_code[None], False, key)[0][0])
    return p.base_db[key]


def check_aggregate(aggregate: str) -> str:
    """``aggregate`` one of :data:`AGGREGATES`."""
    if aggregate not in AGGREGATES:
        raise ParameterError(f"`aggregate`: one of {', '.join(AGGREGATES)}, got {aggregate!r}")
    return aggregate


def parts(problems, code) -> tuple[float, float]:
    """The model's moving PSNR (dB) of ``code``, the mean over the stores, and its still PSNR,
    the mean over the stores with still pixels (nan where none has)."""
    got = [_forward(p, _weights(p, code), float(p.still.any())) for p in problems]
    still = [f["psnr_still"] for f in got if "psnr_still" in f]
    return float(np.mean([f["psnr"] for f in got])), float(np.mean(still)) if still else math.nan


def _weights(p: CellProblem, code) -> np.ndarray:
    """The cells' weights w (n, M) of ``code``: its transmittance with the LCoS's floor."""
    C = p.contrast
    scale = 1.0 if C is None else 1.0 - 1.0 / C
    a = np.asarray(code, float)[:, p.cells_ij[:, 0], p.cells_ij[:, 1]]
    return scale * a + (0.0 if C is None else 1.0 / C)
