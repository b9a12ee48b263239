"""Where on the lens a store's rays start: a proposal fitted to the designs it is made for.

Uniform samples over the whole lens serve every design, but a design whose opening is a
twelfth of the lens uses a twelfth of them. The store therefore draws each ray's lens point,
given its time t, from a defensive mixture

    p(a | t) = alpha / (pi R_max^2) + (1 - alpha) / J(t) sum_j 1[a in D_j(t)] / (pi R_j^2),

where D_j(t) is the opening of design j at time t (its disc, about its centre then; J(t) counts
the designs open at t). Designs that share their path (the parabola of a family of covering
designs) overlap, so each keeps most of the samples. The ``alpha`` part covers the rest of the
lens, so that any other design, a bitmap, or an LCoS's leakage stays unbiased (each sample
weighs A / (p pi R_max^2), :mod:`.synthesis`). The density is stored with every sample.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError
from ..render.plan import AperturePlan

DEFENSIVE = 0.2
"""The uniform share alpha of the mixture: a design not in the proposal has at most 1 / alpha
times the variance that uniform samples give it. Measured (``bench_lightfield.py --only
alpha``, stores of equal cost): for the listed prototype, sigma 0.00052 at alpha 0.05, 0.00062
at 0.2 and 0.0025 at 1 (uniform); for a design not listed (normal), 0.0107, 0.0053 and 0.0027.
0.2 keeps 70 % of the best error per second for the listed designs and 4x the 0.05 one's for
the others."""


@dataclass(frozen=True)
class Proposal:
    """The mixture of the module docstring; ``discs`` are the designs' plans (disc schedules)
    and each one's offset from the store's clock to its own (ms)."""

    lens_radius_mm: float
    alpha: float = DEFENSIVE
    discs: list[tuple[AperturePlan, float]] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not 0.0 < self.alpha <= 1.0:
            raise ParameterError(
                f"`alpha`, the proposal's uniform share, must be in (0, 1], got {self.alpha!r}"
            )

    def to_json(self) -> dict:
        return {
            "alpha": self.alpha,
            "designs": [{"schedule": p.schedule, "radius_mm": p.radius_mm,
                         "centres_mm": p.centres_mm.tolist(), "aperture_quad": p.aperture_quad,
                         "t_open": p.t_open, "t_close": p.t_close, "offset_ms": o,
                         "is_open": p.is_open.tolist()} for p, o in self.discs],
        }  # fmt: skip

    def _components(self, t: np.ndarray):
        """Per design: whether it is open at each t, its centre (n, 2) and radius."""
        for plan, offset in self.discs:
            td = np.asarray(t, np.float64) + offset
            inside = (td >= plan.t_open) & (td < plan.t_close)
            tc = np.clip(td, plan.t_open, plan.t_close)
            k = plan.pattern_at(tc)
            yield inside & plan.is_open[k], plan.aperture_centre_at(tc), plan.radius_mm

    def density(self, u: np.ndarray, v: np.ndarray, t: np.ndarray) -> np.ndarray:
        """p(a | t), 1/mm^2, float64."""
        lens = np.pi * self.lens_radius_mm**2
        n = np.shape(u)
        count = np.zeros(n)
        focused = np.zeros(n)
        for on, c, r in self._components(np.broadcast_to(t, n)):
            count += on
            inside = (u - c[..., 0]) ** 2 + (v - c[..., 1]) ** 2 < r * r
            focused += np.where(on & inside, 1.0 / (np.pi * r * r), 0.0)
        share = np.where(count > 0, 1.0 - self.alpha, 0.0)
        return (1.0 - share) / lens + share * focused / np.maximum(count, 1)

    def sample(
        self, t: np.ndarray, rng: np.random.Generator, uv=None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Lens points (u, v) mm drawn from p(. | t), one per time; ``uv`` (2, n) are the
        uniforms that place each point in its disc (stratified ones, :class:`~.trace.Strata`),
        else drawn from ``rng``. Which part of the mixture a point comes from is drawn."""
        n = len(t)
        uv = rng.random((2, n)) if uv is None else uv
        u, v = _disc(uv, self.lens_radius_mm, np.zeros((n, 2)))
        comps = list(self._components(t))
        if not comps:
            return u, v
        on = np.stack([c[0] for c in comps])  # (J, n)
        pick = rng.random(n)
        focused = (rng.random(n) >= self.alpha) & on.any(axis=0)
        # the j-th open design, j uniform among those open at t
        rank = np.floor(pick * on.sum(axis=0)).astype(int)
        chosen = np.argmax(np.cumsum(on, axis=0) > rank, axis=0)
        for j, (_, centre, r) in enumerate(comps):
            sel = focused & (chosen == j)
            if sel.any():
                u[sel], v[sel] = _disc(uv[:, sel], r, centre[sel])
        return u, v


def _disc(uv: np.ndarray, radius: float, centre: np.ndarray):
    """Points uniform on discs of ``radius`` about ``centre`` (n, 2), from uniforms (2, n)
    (the polar map: strata of the unit square stay strata of the disc)."""
    rho = radius * np.sqrt(uv[0])
    phi = 2 * np.pi * uv[1]
    return centre[:, 0] + rho * np.cos(phi), centre[:, 1] + rho * np.sin(phi)


def disc_plans(plans: list[tuple[AperturePlan, float]]) -> list[tuple[AperturePlan, float]]:
    """The plans a proposal can focus on: disc schedules (a bitmap is served by alpha)."""
    return [(p, o) for p, o in plans if p.kind == "disc" and p.camera_quad == 0.0]
