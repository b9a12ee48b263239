"""Patch a function of the package wherever it is bound.

The package imports its own modules at the top (issue 55), so ``from .x import f`` binds ``f``
in each importing module when that module loads: patching ``x.f`` alone no longer reaches its
callers. :func:`patch_everywhere` replaces every loaded module's binding of the same object.
"""

from __future__ import annotations

import sys


def patch_everywhere(monkeypatch, module, name: str, new) -> None:
    """``module.name`` replaced by ``new`` in ``module`` and in every loaded ``pacam_render``
    module that bound the same object (undone with ``monkeypatch``)."""
    old = getattr(module, name)
    for mod in list(sys.modules.values()):
        if getattr(mod, "__name__", "").startswith("pacam_render") and (
            getattr(mod, name, None) is old
        ):
            monkeypatch.setattr(mod, name, new)
    monkeypatch.setattr(module, name, new)
