"""Modules imported on first use (the standard library's :class:`importlib.util.LazyLoader`):
a heavy library that most commands never touch costs nothing until one does."""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType


def lazy_module(name: str) -> ModuleType:
    """``name`` as a module that loads on its first attribute access (or the module itself,
    once imported).

    Parameters
    ----------
    name : str
        An installed top-level module, e.g. ``"trimesh"`` (1.2 s to import: only building the
        asset cache uses it).

    Returns
    -------
    module
    """
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.find_spec(name)
    if spec is None or spec.loader is None:
        raise ModuleNotFoundError(f"No module named {name!r}", name=name)
    loader = importlib.util.LazyLoader(spec.loader)
    spec.loader = loader
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    loader.exec_module(module)
    return module
