"""A capture's render error, typed: the record's ``render_error`` block.

Every producer of captures states the Monte Carlo error it rendered to and its cost in the same
fields: a direct render (:mod:`pacam_render.exposure.direct`) and a synthesis from a light-field
store (:mod:`pacam_render.lightfield.synthesis`) both build it in
:func:`pacam_render.exposure.assemble.render_error`. The JSON keys are the ones the record has
always written; an optional field that is unset is left out.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

from ..errors import ParameterError

ALWAYS = (
    "mc_sigma", "passes", "spp", "pass_spp", "sampler", "seconds", "time_steps_per_pass",
    "time_step_bias", "time_sampling", "mc_sigma_white_units",
)  # fmt: skip
"""The keys every ``render_error`` holds; the others are written where they are set."""


@dataclass
class RenderError:
    """The Monte Carlo error of a capture and its cost (:mod:`pacam_render.exposure.estimate`).

    Attributes
    ----------
    mc_sigma : float
        RMS over the window of the per-pixel Monte Carlo sigma, the capture's units.
    passes, spp : int
        The independent passes and the samples per pixel they took in all.
    pass_spp : list of int
        Each pass's samples per pixel.
    sampler : str
        Mitsuba's sampler of the passes, or ``light-field store`` for a synthesis.
    seconds : float
        The passes' seconds (a synthesis: its reweighting's), s.
    time_steps_per_pass : int
        Time steps of a moving scene's pass (0: one render covers the exposure).
    time_step_bias : float
        The time steps' bias: 0, their random times make them noise, counted in ``mc_sigma``.
    time_sampling : str
        How the exposure's time is sampled, in words.
    mc_sigma_white_units : float or None
        ``mc_sigma`` / ``light_factor`` (white = 1); None for a capture of no light.
    mc_sigma_by_object : dict, optional
        Each object's (``object_id`` legend) sigma.
    sharp_mc_sigma : float, optional
        The ``sharp`` truth layer's Monte Carlo sigma, white = 1.
    target_sigma, target_met, planned_spp : optional
        A capture rendered to a noise target: the sigma asked, whether it was met, and the
        samples the pilot planned.
    predicted_seconds : float, optional
        A pilot's prediction of the rest of its render, s.
    ratio_to_sensor : float, optional
        ``mc_sigma`` over the sensor's noise (set by the image sensor).
    extra : dict
        Keys of an older or newer record that this version does not know (kept, written back).
    """

    mc_sigma: float
    passes: int = 1
    spp: int = 0
    pass_spp: list = field(default_factory=list)
    sampler: str = "unknown"
    seconds: float = 0.0
    time_steps_per_pass: int = 0
    time_step_bias: float = 0.0
    time_sampling: str = ""
    mc_sigma_white_units: float | None = None
    mc_sigma_by_object: dict | None = None
    sharp_mc_sigma: float | None = None
    target_sigma: float | None = None
    target_met: bool | None = None
    planned_spp: int | None = None
    predicted_seconds: float | None = None
    ratio_to_sensor: float | None = None
    extra: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """The record's ``render_error`` block: :data:`ALWAYS`, then what is set."""
        out = {k: v for k, v in asdict(self).items() if k != "extra"}
        out = {k: v for k, v in out.items() if k in ALWAYS or v is not None}
        return {**self.extra, **out}

    @classmethod
    def from_json(cls, d: dict, where: str = "render_error") -> RenderError:
        """Read the block of a record written by this or an earlier version."""
        if not isinstance(d, dict) or "mc_sigma" not in d:
            raise ParameterError(f"{where}: expected an object with 'mc_sigma'")
        known = {f.name for f in fields(cls)} - {"extra"}
        return cls(
            **{k: v for k, v in d.items() if k in known},
            extra={k: v for k, v in d.items() if k not in known},
        )
