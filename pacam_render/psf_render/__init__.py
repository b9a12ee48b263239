"""Ray-traced PSFs: a point source rendered through a camera design, particle-traced onto the
film, and registered with the analytic kernels of :mod:`pacam_render.psf` (:func:`render_psf`,
:class:`PSFRenderer`).

:mod:`.spec` is what to render and its checks (:class:`PSFSpec`), :mod:`.mode_setup` each
mode's pattern windows and model, :mod:`.film` the film, :mod:`.render` the render itself,
:mod:`.result` its result and fits, and :mod:`.diffraction` the openings' diffraction for it.
Importing this package imports neither Mitsuba nor Dr.Jit.
"""

from .render import PSFRenderer, render_psf
from .spec import PSFSpec

__all__ = ["PSFRenderer", "PSFSpec", "render_psf"]
