"""The ``programmable_aperture`` plugin's Dr.Jit kernels, one module per concern, each bound to
one Mitsuba variant: :mod:`.types` (the variant's types and helpers), :mod:`.schedule_lookup`,
:mod:`.aperture_sampling`, :mod:`.relative_illumination`, :mod:`.aperture_optics` (the LCoS's
flaws and the Airy draw) and :mod:`.defocus_draw` (the exact defocused PSF). They are imported
by :mod:`pacam_render.render.aperture_camera` only, and re-imported in that order by
:mod:`pacam_render.render.registry` after a variant switch; this package imports none of them.
"""
