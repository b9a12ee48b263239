"""Experiments: the paper's figures and our checks of the simulator. :mod:`.simulate` is the
batched image-domain simulation of Section 3 (blur, noise, Wiener deconvolution, PSNR);
:mod:`.reproduce` turns it into the simulation figures (Figs. 6-9, ``pacam reproduce``: one
module each, :mod:`.fig6` to :mod:`.fig9` and :mod:`.fig_train`, on the set-up of :mod:`.figures`);
:mod:`.demo` renders and deblurs the train scene of Figs. 12-15 (``pacam demo``);
:mod:`.validate_psf` compares ray-traced PSFs with the analytic model (r of Eq. 12, a_i of
Eq. 18; ``pacam validate-psf``); :mod:`.regression` compares fresh renders with stored ones.
"""
