"""Analytic PSF benchmark: time per 129x129 kernel, closed form vs brute force, and
discretisation error against run time (issue 2).

- Levin's phi (Eq. 1): closed-form pixel integration vs brute-force time sampling.
- Phi = phi * psi (Eq. 14, r = 2 px): the quadrature bin du_px swept against a du = 0.002 px
  reference, vs brute-force Monte Carlo (time x disc samples).
Errors are relative L1 (sum |k - ref|). Writes benchmarks/figures/psf_error_vs_time.png.

    python benchmarks/bench_psf.py [--full]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from common import median_spread, record, timeit

from pacam_render.psf import analytic as psf

T, S, A, R = 22.5, 0.3, 0.04, 2.0
SIZE = 129
EDGES = np.arange(SIZE + 1) - SIZE // 2 - 0.5


def brute_levin(n: int, rng) -> np.ndarray:
    t = rng.uniform(-T, T, n)
    row = np.histogram(S * t + 0.5 * A * t * t, bins=EDGES)[0] / n
    k = np.zeros((SIZE, SIZE))
    k[SIZE // 2] = row
    return k


def brute_coded(n: int, rng) -> np.ndarray:
    t = rng.uniform(-T, T, n)
    rho, th = R * np.sqrt(rng.uniform(0, 1, n)), rng.uniform(0, 2 * np.pi, n)
    x = S * t + 0.5 * A * t * t + rho * np.cos(th)
    return np.histogram2d(rho * np.sin(th), x, bins=[EDGES, EDGES])[0] / n


def best_time(fn, repeat: int) -> tuple[float, float]:
    return median_spread(timeit(fn, repeat=repeat))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="more samples and repeats")
    args = ap.parse_args()
    rep = 7 if args.full else 3
    rng = np.random.default_rng(0)
    rows, curves = [], {"closed form (du sweep)": [], "brute force MC": [], "phi brute force": []}

    ref_phi = psf.levin_psf(S, A, T, size=SIZE)
    t_phi, sp = best_time(lambda: psf.levin_psf(S, A, T, size=SIZE), rep)
    rows.append(
        {
            "method": "phi closed form",
            "setting": "exact",
            "time_ms": 1e3 * t_phi,
            "spread_ms": 1e3 * sp,
            "rel_L1": 0.0,
        }
    )
    for n in [10**4, 10**5, 10**6] + ([10**7] if args.full else []):
        t_b, sp = best_time(lambda n=n: brute_levin(n, rng), rep)
        err = np.abs(brute_levin(n, rng) - ref_phi).sum()
        rows.append(
            {
                "method": "phi brute force",
                "setting": f"{n:.0e} samples",
                "time_ms": 1e3 * t_b,
                "spread_ms": 1e3 * sp,
                "rel_L1": err,
            }
        )
        curves["phi brute force"].append((t_b, err))

    ref = psf.coded_psf(S, A, R, T, size=SIZE, du_px=0.002)
    for du in [1.0, 0.5, 0.25, 0.1, 0.05, 0.02, 0.01]:
        t_c, sp = best_time(lambda du=du: psf.coded_psf(S, A, R, T, size=SIZE, du_px=du), rep)
        err = np.abs(psf.coded_psf(S, A, R, T, size=SIZE, du_px=du) - ref).sum()
        tag = " (default)" if du == psf.default_du_px(R) else ""
        rows.append(
            {
                "method": "Phi closed form",
                "setting": f"du={du} px{tag}",
                "time_ms": 1e3 * t_c,
                "spread_ms": 1e3 * sp,
                "rel_L1": err,
            }
        )
        curves["closed form (du sweep)"].append((t_c, err))
    for n in [10**4, 10**5, 10**6] + ([10**7] if args.full else []):
        t_b, sp = best_time(lambda n=n: brute_coded(n, rng), rep)
        err = np.abs(brute_coded(n, rng) - ref).sum()
        rows.append(
            {
                "method": "Phi brute-force MC",
                "setting": f"{n:.0e} samples",
                "time_ms": 1e3 * t_b,
                "spread_ms": 1e3 * sp,
                "rel_L1": err,
            }
        )
        curves["brute force MC"].append((t_b, err))

    t0 = time.perf_counter()
    psf.discrete_coded_psf(S, A, R, T, 16, size=SIZE)
    rows.append(
        {
            "method": "discrete 16-pattern Phi",
            "setting": "default du",
            "time_ms": 1e3 * (time.perf_counter() - t0),
            "spread_ms": 0.0,
            "rel_L1": float("nan"),
        }
    )

    record(
        "Analytic PSF: 129x129 kernels, closed form vs brute force (issue 2)",
        rows,
        notes=f"s={S} px/ms, a_i={A} px/ms^2, r={R} px, T={T} ms; rel_L1 vs exact phi or vs "
        "Phi at du=0.002 px; time = median of repeats, spread = half range",
    )
    fig, ax = plt.subplots(figsize=(6, 4))
    for label, pts in curves.items():
        if pts:
            t, e = np.array(pts).T
            ax.loglog(1e3 * t, np.maximum(e, 1e-12), "o-", label=label)
    ax.set_xlabel("time per 129x129 kernel (ms)")
    ax.set_ylabel("relative L1 error")
    ax.set_title("PSF discretisation error vs run time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    out = Path(__file__).with_name("figures") / "psf_error_vs_time.png"
    out.parent.mkdir(exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
