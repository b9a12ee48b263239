"""Image-plane trajectories of a point during the exposure, and their exact pixel statistics.

A trajectory is a list of :class:`Segment` pieces x(t) = x0 + v t + a t^2/2 on [t0, t1], each
weighted by a shutter transmittance w. The time a point spends in a pixel column is found in
closed form from the roots of that quadratic, so the inverse-square-root singularity of Levin's
PSF (Eq. 1) at the parabola's vertex never has to be sampled: every mass is exact and the masses
sum to the total exposure exactly.

Units: x in px, t in ms, v in px/ms, a in px/ms^2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError


@dataclass(frozen=True)
class Segment:
    """x(t) = x0 + v t + a t^2 / 2 for t in [t0, t1] ms, with shutter transmittance w, on the
    row y px (a designed schedule's vertical offset; 0 for every motion along x)."""

    t0: float
    t1: float
    x0: float = 0.0
    v: float = 0.0
    a: float = 0.0
    w: float = 1.0
    y: float = 0.0

    def __post_init__(self) -> None:
        vals = (self.t0, self.t1, self.x0, self.v, self.a, self.w, self.y)
        if not np.all(np.isfinite(vals)):
            raise ParameterError(f"trajectory segment must be finite, got {self}")
        if self.t1 < self.t0:
            raise ParameterError(f"segment needs t1 >= t0, got t0={self.t0}, t1={self.t1}")
        if self.w < 0:
            raise ParameterError(f"segment transmittance w must be >= 0, got {self.w}")

    def x(self, t):
        """Position at time t, px."""
        t = np.asarray(t, dtype=float)
        return self.x0 + self.v * t + 0.5 * self.a * t * t

    def antiderivative(self, t):
        """Integral of x(t) dt from 0 to t, px ms."""
        t = np.asarray(t, dtype=float)
        return self.x0 * t + 0.5 * self.v * t * t + self.a * t**3 / 6.0

    def extent(self) -> tuple[float, float]:
        """Smallest and largest x reached on [t0, t1], px."""
        ts = [self.t0, self.t1]
        if self.a != 0.0:
            tv = -self.v / self.a
            if self.t0 < tv < self.t1:
                ts.append(tv)
        xs = self.x(np.array(ts))
        return float(xs.min()), float(xs.max())


def _linear(seg: Segment) -> bool:
    """No usable quadratic term: a = 0, or so subnormal that a/2 underflows to 0."""
    return 0.5 * seg.a == 0.0


def _roots(seg: Segment, c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ordered roots r1 <= r2 of x(t) = c (a != 0), and whether they are real.

    Uses the cancellation-free form q = -(B + sign(B) sqrt(D)) / 2, roots q/A and C/q, so a
    tiny acceleration gives the linear root c/v to full precision instead of 0/0.
    """
    A, B, C = 0.5 * seg.a, seg.v, seg.x0 - c
    disc = B * B - 4.0 * A * C
    real = disc >= 0.0
    sq = np.sqrt(np.where(real, disc, 0.0))
    q = -0.5 * (B + np.copysign(sq, B if B != 0.0 else 1.0))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ra = np.where(q != 0.0, q / A, 0.0)
        rb = np.where(q != 0.0, C / q, 0.0)
    return np.minimum(ra, rb), np.maximum(ra, rb), real


def _sublevel_intervals(seg: Segment, c: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Up to two time intervals, clipped to [t0, t1], on which x(t) <= c."""
    t0, t1 = seg.t0, seg.t1
    lo_all, hi_all = np.full_like(c, t0), np.full_like(c, t1)
    if _linear(seg):
        if seg.v == 0.0:  # an atom at x0
            inside = seg.x0 <= c
            return [(lo_all, np.where(inside, t1, t0))]
        with np.errstate(over="ignore"):  # a subnormal v sends tc to +-inf: clipped below
            tc = (c - seg.x0) / seg.v
        if seg.v > 0:
            return [(lo_all, np.clip(tc, t0, t1))]
        return [(np.clip(tc, t0, t1), hi_all)]
    r1, r2, real = _roots(seg, c)
    if seg.a > 0:  # x <= c between the roots
        lo = np.where(real, np.clip(r1, t0, t1), t0)
        hi = np.where(real, np.clip(r2, t0, t1), t0)
        return [(lo, hi)]
    # a < 0: x <= c outside the roots; everywhere when there are none
    first_hi = np.where(real, np.clip(r1, t0, t1), t1)
    second_lo = np.where(real, np.clip(r2, t0, t1), t1)
    return [(lo_all, first_hi), (second_lo, hi_all)]


def cumulative(seg: Segment, c) -> tuple[np.ndarray, np.ndarray]:
    """Time (ms) and first moment (px ms) spent at x <= c, for each c."""
    c = np.asarray(c, dtype=float)
    mass = np.zeros_like(c)
    moment = np.zeros_like(c)
    for lo, hi in _sublevel_intervals(seg, c):
        hi = np.maximum(hi, lo)
        mass += hi - lo
        moment += seg.antiderivative(hi) - seg.antiderivative(lo)
    return mass, moment


def bin_statistics(segments: list[Segment], edges) -> tuple[np.ndarray, np.ndarray]:
    """Weighted time in each bin [e_k, e_k+1) and its first moment, summed over segments.

    The mass of an atom sitting exactly on an edge goes to the bin below it.
    """
    edges = np.asarray(edges, dtype=float)
    mass = np.zeros(edges.size - 1)
    moment = np.zeros(edges.size - 1)
    for seg in segments:
        if seg.w == 0.0 or seg.t1 == seg.t0:
            continue
        m, mom = cumulative(seg, edges)
        mass += seg.w * np.diff(m)
        moment += seg.w * np.diff(mom)
    return np.maximum(mass, 0.0), moment


def total_weight(segments: list[Segment]) -> float:
    """Total shutter-weighted time, ms."""
    return float(sum(s.w * (s.t1 - s.t0) for s in segments))


def extent(segments: list[Segment]) -> tuple[float, float]:
    """Range of x covered by the open segments, px."""
    lit = [s for s in segments if s.w > 0]
    if not lit:
        raise ParameterError("the shutter never opens: every segment has zero transmittance")
    ext = np.array([s.extent() for s in lit])
    return float(ext[:, 0].min()), float(ext[:, 1].max())


def density(segments: list[Segment], x) -> np.ndarray:
    """Pointwise PSF density at x (per px), normalised to unit total weight.

    For one parabola this is Eq. 1, lambda(x) / (2T sqrt(s^2 + 2 a x)), with lambda the number
    of times the point passes x. Atoms (static segments) have no density and are left out.
    """
    x = np.asarray(x, dtype=float)
    out = np.zeros_like(x)
    for seg in segments:
        if seg.w == 0.0 or (_linear(seg) and seg.v == 0.0):
            continue
        if _linear(seg):
            ts = [(x - seg.x0) / seg.v]
            real = np.ones_like(x, dtype=bool)
        else:
            r1, r2, real = _roots(seg, x)
            ts = [r1, r2]
        for t in ts:
            ok = real & (t >= seg.t0) & (t <= seg.t1)
            speed = np.abs(seg.v + seg.a * t)
            with np.errstate(divide="ignore"):
                out += np.where(ok, seg.w / speed, 0.0)
    return out / total_weight(segments)
