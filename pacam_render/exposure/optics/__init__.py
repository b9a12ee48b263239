"""A capture's optics after its rays: diffraction decided and applied (:mod:`.diffraction`),
what the rays' diffraction leaves out (:mod:`.wave_residual`), and the record's physics error
budget (:mod:`.budget`, :func:`~pacam_render.exposure.optics.budget.finish_optics`)."""
