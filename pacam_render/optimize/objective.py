"""The schedule's figure of merit in closed form: the expected error of deblurring every speed
and depth in a range with one kernel (Wiener, 1/f^2 prior), in the Fourier domain.

A schedule shows n openings of radius R at centres X_k (mm, along the image's x) for 2T/n
each; the lens focuses so that an object at the design depth Z_0 sees beta_0 px of image
shift per mm of aperture (Eq. 9). An object at depth Z moving at s px/ms then has the OTF

    H(f) = sinc(f_x s 2T/n) (1/n) sum_k exp(-2 pi i f_x (beta_Z X_k + s t_k))
           x jinc(|beta_Z| R |f|) x sinc(f_x) sinc(f_y)                          (Eqs. 8, 12-14)

(the box each pattern's motion draws, the pillbox of Eq. 13, the pixel's integration), with
beta_Z = beta_0 + f_px (1/Z_0 - 1/Z). Deblurring with the Wiener filter W = K* / (|K|^2 +
sigma^2 / S) of the kernel K = H(s = 0, Z_0), under the image prior S(f) = c / (|f|^2 + f0^2),
leaves the per-pixel mean squared error

    e(s, Z) = mean_f [ S |1 - W H exp(2 pi i f_x delta)|^2 + sigma^2 |W|^2 ],

minimised over the shift delta that a motion-invariant PSF gives each speed (-s^2 / 2 a_i for
the parabola): the error of deblurring, not of registration. sigma^2 is the sensor's noise at
the light the opening collects, so a smaller opening pays for its light. The optimiser
minimises a soft maximum of 10 log10 e over the (s, Z) grid; the gradient is exact (Wirtinger
calculus through W, H and the pillbox; checked against central differences in the tests).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from ..errors import ParameterError
from ..model.camera import MIN_FOCUS_MM, MIN_OPENING_LCOS_PX, CameraDesign

PRIOR_C = 3.0e-4
"""c of the 1/f^2 prior, per-pixel DFT units (E|X(f)|^2 / N = c / (|f|^2 + f0^2)): the mean
power spectrum of the 13 photographs of :mod:`pacam_render.experiments.simulate` (256^2, mean
removed, Hann window) over c g(f), geometric mean over 0.02 < |f| < 0.5 cycles/px. With it the
parabola's predicted PSNR is within 1.6 dB of Fig. 6's image-domain Wiener, dips included
(tests/optimize/test_optimize.py)."""
MEAN_LEVEL = 0.42
"""The grey level the noise is taken at (white = 1): the mean of the same 13 photographs."""
SOFTMAX_DB = 0.25
"""Temperature of the soft maximum over the (speed, depth) grid, dB."""
BETA_RANGE = 3.0
"""The focus may give up to this many times the reference design's |beta_0|."""


@dataclass(frozen=True)
class Grid:
    """The speeds (px/ms) and depths (mm) the objective covers, and the frequency grid.

    ``depths_mm[z0]`` is the design depth Z_0 and ``speeds[s0] == 0``: the deblurring kernel's.
    """

    speeds: np.ndarray
    depths_mm: np.ndarray
    z0: int
    s0: int
    shape: tuple[int, int]  # (Ly, Lx) of the real-space grid the frequencies stand for


def make_grid(s_max, depth_range_mm, n_speeds: int, n_depths: int, extent_px, r_max_px) -> Grid:
    """Odd counts so that s = 0 and the middle depth (harmonic mean: uniform in 1/Z) are on it.

    ``extent_px`` bounds the PSF's width and ``r_max_px`` its disc: the grid holds twice that.
    """
    near, far = depth_range_mm
    n_s, n_z = n_speeds | 1, n_depths | 1 if near != far else 1
    speeds = np.linspace(-s_max, s_max, n_s)
    depths = 1.0 / np.linspace(1.0 / near, 1.0 / far, n_z)
    lx = 1 << max(7, math.ceil(math.log2(2.0 * extent_px + 32.0)))
    ly = 1 << max(5, math.ceil(math.log2(4.0 * r_max_px + 32.0)))
    if lx > 8192 or ly > 1024:
        raise ParameterError(
            f"the PSFs this range allows span {extent_px:.0f} x {2 * r_max_px:.0f} px: too wide "
            "to optimise (lower max_velocity_px_per_ms or narrow depth_range_mm)"
        )
    return Grid(speeds, depths, n_z // 2, n_s // 2, (ly, lx))


def _jinc(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unit-mass disc's FT at r|f| = u, 2 J1(2 pi u) / (2 pi u), and its derivative."""
    x = 2.0 * np.pi * u
    small = x < 1e-6
    xs = np.where(small, 1.0, x)
    j = np.where(small, 1.0 - x * x / 8.0, 2.0 * special.j1(xs) / xs)
    dj = np.where(small, -np.pi * x / 4.0, -4.0 * np.pi * special.jv(2, xs) / xs)
    return j, dj


class Objective:
    """The error e(s, Z) of a schedule (module doc) and the soft worst case's gradient.

    Parameters (the vector theta): u_k = X_k / (R_max - R) in [-1, 1] (k < n), b = beta_0 /
    beta_ref, and, with a free radius, q = R / R_ref. ``noise_var(R_mm)`` gives sigma^2 in
    white = 1 units for an opening of radius R.
    """

    def __init__(self, ref: CameraDesign, grid: Grid, noise_var, free_radius: bool = False):
        self.ref, self.grid, self.noise_var, self.free_radius = ref, grid, noise_var, free_radius
        self.n = ref.n_patterns
        self.R_max = ref.R_max_mm
        self.beta_ref = abs(ref.beta_px_per_mm)
        self.f_px = ref.focal_length_px
        self.dbeta = self.f_px * (1.0 / ref.object_depth_mm - 1.0 / grid.depths_mm)  # (Z,)
        dt = ref.exposure_ms / self.n
        self.t_k = -ref.T_ms + (np.arange(self.n) + 0.5) * dt
        ly, lx = grid.shape
        self.fx = np.arange(lx // 2 + 1) / lx
        fy = np.arange(ly // 2 + 1) / ly
        wx = np.where((self.fx > 0) & (self.fx < 0.5), 2.0, 1.0)
        wy = np.where((fy > 0) & (fy < 0.5), 2.0, 1.0)
        self.w = wx[:, None] * wy[None, :] / (lx * ly)  # (Fx, Fy): mean over the full grid
        self.w[0, 0] = 0.0  # the mean is measured, not restored
        self.rho = np.hypot(self.fx[:, None], fy[None, :])
        self.pix = np.sinc(self.fx)[:, None] * np.sinc(fy)[None, :]
        self.S = PRIOR_C / (self.rho**2 + (1.0 / max(lx, ly)) ** 2)
        self.box = np.sinc(np.outer(grid.speeds * dt, self.fx))  # (S, Fx)

    # --- parameters ------------------------------------------------------------------------
    def radius_mm(self, theta) -> float:
        return self.ref.R_mm * theta[self.n + 1] if self.free_radius else self.ref.R_mm

    def unpack(self, theta) -> tuple[np.ndarray, float, float]:
        """(X_k mm, beta_0 px/mm, R mm)."""
        R = self.radius_mm(theta)
        return np.asarray(theta[: self.n]) * (self.R_max - R), theta[self.n] * self.beta_ref, R

    def pack(self, X_mm, beta0_px_per_mm: float, R_mm: float | None = None) -> np.ndarray:
        R = self.ref.R_mm if R_mm is None else R_mm
        theta = [*(np.asarray(X_mm) / (self.R_max - R)), beta0_px_per_mm / self.beta_ref]
        return np.array(theta + ([R / self.ref.R_mm] if self.free_radius else []))

    def bounds(self) -> list[tuple[float, float]]:
        """u in [-1, 1]; the focus beyond MIN_FOCUS_MM and short of infinity; R from one LCoS
        pixel to 95 % of the lens."""
        z0 = self.ref.object_depth_mm
        lo = max(-BETA_RANGE, -0.999 * self.f_px / z0 / self.beta_ref)
        hi = min(BETA_RANGE, self.f_px * (1.0 / MIN_FOCUS_MM - 1.0 / z0) / self.beta_ref)
        out = [(-1.0, 1.0)] * self.n + [(lo, hi)]
        if self.free_radius:
            r_min = MIN_OPENING_LCOS_PX * self.ref.lcos_pitch_mm
            out.append((r_min / self.ref.R_mm, 0.95 * self.R_max / self.ref.R_mm))
        return out

    def focus_mm(self, beta0_px_per_mm: float) -> float:
        """The focus distance that gives beta_0 at the design depth (Eq. 9)."""
        return 1.0 / (1.0 / self.ref.object_depth_mm + beta0_px_per_mm / self.f_px)

    # --- the error ---------------------------------------------------------------------------
    def _forward(self, theta) -> dict:
        X, beta0, R = self.unpack(theta)
        beta = beta0 + self.dbeta  # (Z,)
        phase = beta[:, None, None] * X[None, None, :] + self.grid.speeds[None, :, None] * self.t_k
        E = np.exp(-2j * np.pi * phase[..., None] * self.fx) / self.n  # (Z, S, n, Fx)
        M = self.box[None] * E.sum(axis=2)  # (Z, S, Fx)
        r = np.abs(beta) * R
        J, dJ = _jinc(r[:, None, None] * self.rho[None])  # (Z, Fx, Fy)
        A = J * self.pix
        H = M[..., None] * A[:, None]  # (Z, S, Fx, Fy)
        K = H[self.grid.z0, self.grid.s0]
        var = float(self.noise_var(R))
        lam = var / self.S
        D = (K * K.conj()).real + lam
        W = K.conj() / D
        return dict(X=X, beta=beta, R=R, E=E, M=M, J=J, dJ=dJ, A=A, H=H, K=K, var=var, lam=lam,
                    D=D, W=W)  # fmt: skip

    def _shifts(self, f: dict) -> np.ndarray:
        """The shift delta (px) per (Z, S) that best registers W H with the truth."""
        lx = self.grid.shape[1]
        a = np.einsum("zsxy,xy->zsx", f["H"], self.w * self.S * f["W"])
        full = np.zeros(a.shape[:2] + (lx,), complex)
        full[..., : a.shape[2]] = a
        c = np.fft.ifft(full, axis=-1).real
        i = np.argmax(c, axis=-1)
        cm, c0, cp = (
            np.take_along_axis(c, ((i + d) % lx)[..., None], -1)[..., 0] for d in (-1, 0, 1)
        )
        den = cm - 2.0 * c0 + cp
        frac = np.where(den < 0, 0.5 * (cm - cp) / np.where(den < 0, den, -1.0), 0.0)
        d = i + np.clip(frac, -0.5, 0.5)
        d = np.where(d > lx / 2, d - lx, d)
        w = 2j * np.pi * self.fx
        for _ in range(2):  # Newton on the exact correlation: the gradient needs its stationarity
            e = a * np.exp(w * d[..., None])
            c1, c2 = (w * e).sum(-1).real, (w * w * e).sum(-1).real
            d = np.where(c2 < 0, d - c1 / np.where(c2 < 0, c2, -1.0), d)
        return d

    def errors(self, theta, f: dict | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
        """e (Z, S), the per-pixel MSE of each speed and depth at its best shift; the shifts."""
        f = self._forward(theta) if f is None else f
        delta = self._shifts(f)
        ramp = np.exp(2j * np.pi * delta[..., None] * self.fx)  # (Z, S, Fx)
        G = f["H"] * ramp[..., None]
        res = 1.0 - f["W"] * G
        e = np.einsum("zsxy,xy->zs", (res * res.conj()).real, self.w * self.S)
        e += f["var"] * float(np.sum(self.w * (f["W"] * f["W"].conj()).real))
        f.update(ramp=ramp, G=G, res=res)
        return e, delta, f

    def psnr_db(self, theta) -> np.ndarray:
        """Predicted PSNR (dB, white = 1) of each speed and depth, (Z, S)."""
        return -10.0 * np.log10(self.errors(theta)[0])

    def loss(self, theta) -> tuple[float, np.ndarray]:
        """Soft maximum over the grid of 10 log10 e (dB; lower is better), and its gradient."""
        e, _, f = self.errors(theta)
        p = 10.0 * np.log10(e) / SOFTMAX_DB
        m = p.max()
        soft = np.exp(p - m)
        L = SOFTMAX_DB * (m + math.log(soft.sum() / soft.size))
        c = soft / soft.sum() * (10.0 / math.log(10.0)) / e  # dL / de, (Z, S)
        return L, self._gradient(theta, f, c)

    def _gradient(self, theta, f: dict, c: np.ndarray) -> np.ndarray:
        """dL/dtheta for dL/de = c (Z, S): Wirtinger calculus, dL = 2 Re sum Gamma dH."""
        w, S, W, K, D, var = self.w, self.S, f["W"], f["K"], f["D"], f["var"]
        gam = -(c[..., None, None] * w * S) * W * f["res"].conj() * f["ramp"][..., None]
        B = np.einsum("zs,zsxy->xy", c, -S * f["G"] * f["res"].conj()) * w
        B += c.sum() * var * w * W.conj()
        gam[self.grid.z0, self.grid.s0] += (-B * K.conj() ** 2 + B.conj() * f["lam"]) / D**2
        dvar = c.sum() * float(np.sum(w * (W * W.conj()).real))
        dvar += 2.0 * float(np.sum((B * (-K.conj()) / D**2 / S).real))
        # through the motion part M: positions beta_Z X_k
        Y = np.einsum("zsxy,zxy->zsx", gam, f["A"]) * self.box[None] * (-2j * np.pi * self.fx)
        T = np.einsum("zsx,zskx->zsk", Y, f["E"])
        X, beta, R = f["X"], f["beta"], f["R"]
        dX = 2.0 * np.einsum("z,zsk->k", beta, T).real
        dbeta = 2.0 * np.einsum("k,zsk->z", X, T).real
        # through the pillbox: r_Z = |beta_Z| R
        gA = np.einsum("zsxy,zsx->zxy", gam, f["M"])
        dr = 2.0 * np.einsum("zxy,zxy->z", gA, f["dJ"] * (self.rho * self.pix)[None]).real
        dbeta += np.sign(beta) * R * dr
        grad = [(self.R_max - R) * dX, [self.beta_ref * dbeta.sum()]]
        if self.free_radius:
            h = 1e-6 * R
            dvar_dR = (self.noise_var(R + h) - self.noise_var(R - h)) / (2.0 * h)
            dR = float(np.abs(beta) @ dr) + dvar * dvar_dR
            u = np.asarray(theta[: self.n])
            grad.append([self.ref.R_mm * (dR - float(u @ dX))])
        return np.concatenate(grad)
