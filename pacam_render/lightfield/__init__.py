"""Light-field stores: render a scene once through the whole lens, then synthesise any design's
capture from it by reweighting the samples (issue 44).

:mod:`.trace` keeps each camera sample (film point, lens point, time, radiance), :mod:`.render`
renders a store (:func:`render_lightfield`, :class:`StoreSpec`) and :mod:`.store` is its format
on disk; :mod:`.geometry` moves a sample to where another focus sees its ray, :mod:`.codes` is
a design's transmission A(u, v, t), and :mod:`.synthesis` bins a design's capture
(:func:`synthesize`), written as any capture is. It sits above the producers of captures
(``exposure/``), whose plan and record it reuses, and below the CLI and the studies.
"""

from .render import StoreInterrupted, render_lightfield
from .store import Store, StoreSpec
from .synthesis import synthesize

__all__ = ["Store", "StoreInterrupted", "StoreSpec", "render_lightfield", "synthesize"]
