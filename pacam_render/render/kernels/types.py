"""The Dr.Jit types and helpers of the ``programmable_aperture`` kernels, for one Mitsuba variant.

Imported for the active variant (it must be set first); :mod:`.registry` re-imports this module
first, then the modules of the camera's kernels (:mod:`.schedule_lookup`,
:mod:`.aperture_sampling`, :mod:`.relative_illumination`, :mod:`.aperture_optics`) and last
:mod:`.aperture_camera`, after a variant switch. In scalar variants the helpers work on plain
Python numbers and numpy tables.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..plan import pad_table

if mi.variant() is None:  # mi.Sensor and the array types below belong to one variant
    raise ImportError(
        "pacam_render.render.kernels.types needs an active Mitsuba variant: call "
        "pacam_render.render.register() (or backend.select_variant()) first"
    )

VARIANT = mi.variant()
"""The variant this module was imported for; :mod:`.registry` re-imports it after a switch."""
Float, Int, UInt = mi.Float, mi.Int32, mi.UInt32
Point2f, Point3f, Vector3f = mi.Point2f, mi.Point3f, mi.Vector3f
JIT = dr.is_jit_v(Float)  # scalar variants: plain Python numbers and numpy tables


def opaque_scalar(v, t=Float):
    return dr.opaque(t, v) if JIT else t(v)


def opaque_array(a, t=Float):
    if not JIT:
        return np.asarray(pad_table(a))
    x = t(pad_table(a))
    dr.make_opaque(x)
    return x


def gather(t, source, index, active=True):
    if JIT:
        return dr.gather(t, source, index, active)
    return t(source[min(max(int(index), 0), len(source) - 1)]) if active else t(0)


def first(v) -> float:
    return float(v[0]) if JIT else float(v)


def make_opaque(*args):
    if JIT:
        dr.make_opaque(*args)


def as_type(t, v):
    """``v`` as type ``t``, converted only if it is not one already.

    Mitsuba's C++ sensors convert their arguments in the bindings, so Mitsuba's tests call
    them with Python numbers, lists and tuples (``sample_ray(0, 0, [0.5, 0.5], [0.5, 0.5])``);
    a Python plugin receives those as they are. Arguments of the right type (as the
    integrators pass them) are returned untouched, so traced kernels do not change.
    """
    return v if isinstance(v, t) else t(v)


def traversable(v: float):
    """A holder of ``v`` that ``mi.traverse`` can update in place: a ``Float`` in JIT
    variants, a one-element ``Array1f`` in scalar ones (a Python float is immutable)."""
    return Float(v) if JIT else dr.scalar.Array1f(v)


def held(h) -> float:
    """The value in a :func:`traversable` holder, as a Python float."""
    return float(h[0])
