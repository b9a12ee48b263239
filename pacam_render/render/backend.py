"""Mitsuba variant selection: the one place that decides which backend renders.

:func:`select_variant` activates the variant :mod:`.variant` chooses (``PACAM_VARIANT``, else
CUDA when asked for and present, else LLVM when drjit's libLLVM works, else scalar with one
warning) and installs our sensor plugins for it (:mod:`.registry`).

drjit 1.5 needs libLLVM >= 16: with Debian 12's default libLLVM-15 the variant loads but the
first render aborts the whole process. That is why ``python -m pacam_render.render.backend
--check`` does a real render (run it in a subprocess).
"""

from __future__ import annotations

import sys

from .registry import install
from .variant import activate_variant, choose_variant, llvm_status


def select_variant(gpu: bool = False, mono: bool = False) -> str:
    """Choose (once per process and request) and activate a Mitsuba variant; return its name.

    Parameters
    ----------
    gpu : bool, optional
        Prefer the CUDA variant when a GPU is present (see :func:`~.variant.choose_variant`).
    mono : bool, optional
        Pick the single-channel variant.

    Returns
    -------
    str
        The variant now active. The choice for each (``gpu``, ``mono``) is made once per
        process and reused.

    Raises
    ------
    ParameterError
        As :func:`~.variant.choose_variant`.

    Notes
    -----
    Also installs the sensor plugins (:func:`~pacam_render.render.registry.install`): they are
    registered for this variant and again after every later variant switch.
    """
    variant = activate_variant(gpu, mono)
    install()  # our sensors follow the variant from now on
    return variant


def _render_check() -> int:
    """Render a tiny scene with the LLVM variant; a broken libLLVM aborts the process."""
    ok, why = llvm_status()
    if not ok:
        print(f"LLVM backend unavailable: {why}", file=sys.stderr)
        return 1
    import mitsuba as mi

    scene = mi.load_dict(mi.cornell_box())
    img = mi.render(scene, spp=1)
    print(f"LLVM backend renders ({why}), image {tuple(img.shape)}")
    return 0


if __name__ == "__main__":
    if sys.argv[1:] == ["--check"]:
        sys.exit(_render_check())
    print(choose_variant())
