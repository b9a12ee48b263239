"""Mitsuba variant choice: which variant renders here, chosen once per process and request.

Order: ``PACAM_VARIANT`` if set; else ``cuda_ad_*`` when a GPU is asked for and present; else
``llvm_ad_*`` when drjit's LLVM backend works; else ``scalar_*`` with one warning (a Python
sensor runs about 13x slower there). ``mono=True`` picks the single-channel variant, for grey
experiments that need no RGB.

drjit 1.5 needs libLLVM >= 16: with Debian 12's default libLLVM-15 the variant loads but the
first render aborts the whole process. That is why the version is checked before it is used,
and why ``python -m pacam_render.render.backend --check`` does a real render (run it in a
subprocess).

This module knows nothing of our sensor plugins: :func:`~.backend.select_variant` activates
the variant chosen here and installs them (:mod:`.registry`).
"""

from __future__ import annotations

import os
import warnings

from ..errors import ParameterError

MIN_LLVM = (16, 0, 0)
LLVM_FIX = "apt-get install -y libllvm19"


class BackendWarning(UserWarning):
    """Rendering falls back to a slower backend."""


_chosen: dict[tuple[bool, bool], str] = {}
_warned = False


def llvm_status() -> tuple[bool, str]:
    """Whether drjit's LLVM backend can render here, and why not.

    Returns
    -------
    ok : bool
        True if the ``llvm_ad_rgb`` variant loads and drjit's libLLVM is at least
        :data:`MIN_LLVM` (16).
    reason : str
        The libLLVM version found, or why the backend cannot render.

    Notes
    -----
    Imports Mitsuba and drjit, and probes by activating ``llvm_ad_rgb``: that variant stays
    active if it loads.
    """
    import drjit as dr
    import mitsuba as mi

    try:
        mi.set_variant("llvm_ad_rgb")
    except (ImportError, AttributeError, RuntimeError) as exc:
        return False, f"drjit found no libLLVM ({exc})"
    version = tuple(dr.detail.llvm_version())
    if version < MIN_LLVM:
        found = ".".join(map(str, version))
        return False, f"libLLVM {found} is too old (drjit needs >= 16; renders abort)"
    return True, "libLLVM " + ".".join(map(str, version))


def cuda_available() -> bool:
    """Whether the CUDA variant loads (a GPU and driver are present).

    Returns
    -------
    bool
        True if ``cuda_ad_rgb`` could be activated.

    Notes
    -----
    Imports Mitsuba and probes by activating ``cuda_ad_rgb``: that variant stays active if it
    loads.
    """
    import mitsuba as mi

    try:
        mi.set_variant("cuda_ad_rgb")
    except (ImportError, AttributeError, RuntimeError):
        return False
    return True


def _variant_name(kind: str, mono: bool) -> str:
    if kind == "scalar":  # the Mitsuba wheel ships no scalar_mono: grey renders use rgb there
        return "scalar_rgb"
    return f"{kind}_ad_{'mono' if mono else 'rgb'}"


def _override() -> str | None:
    import mitsuba as mi

    name = os.environ.get("PACAM_VARIANT", "").strip()
    if not name:
        return None
    if name not in mi.variants():
        raise ParameterError(
            f"PACAM_VARIANT={name!r} is not a Mitsuba variant; valid: {', '.join(mi.variants())}"
        )
    if name.startswith("llvm"):
        ok, why = llvm_status()
        if not ok:
            raise ParameterError(f"PACAM_VARIANT={name!r} cannot render: {why}. Fix: {LLVM_FIX}")
    return name


def _warn_fallback(reason: str) -> None:
    global _warned
    if not _warned:
        warnings.warn(
            f"drjit's LLVM backend is unavailable ({reason}); rendering with the scalar variant, "
            f"about 10x slower. Fix: {LLVM_FIX}",
            BackendWarning,
            stacklevel=3,
        )
        _warned = True


def choose_variant(gpu: bool = False, mono: bool = False) -> str:
    """Name of the variant to use, without activating it (beyond probing).

    Parameters
    ----------
    gpu : bool, optional
        Prefer the CUDA variant when a GPU is present.
    mono : bool, optional
        Pick the single-channel variant (``*_mono``), for grey experiments; there is no
        ``scalar_mono``, so the scalar fallback is ``scalar_rgb`` either way.

    Returns
    -------
    str
        ``PACAM_VARIANT`` if set; else ``cuda_ad_*`` when ``gpu`` and CUDA loads; else
        ``llvm_ad_*`` when drjit's LLVM backend works (:func:`llvm_status`); else
        ``scalar_rgb``, with one :class:`BackendWarning` per process.

    Raises
    ------
    ParameterError
        If ``PACAM_VARIANT`` is not a Mitsuba variant, or names an LLVM variant that cannot
        render here.
    """
    override = _override()
    if override:
        return override
    if gpu and cuda_available():
        return _variant_name("cuda", mono)
    ok, why = llvm_status()
    if ok:
        return _variant_name("llvm", mono)
    _warn_fallback(why)
    return _variant_name("scalar", mono)


def activate_variant(gpu: bool = False, mono: bool = False) -> str:
    """Choose (once per process and request) and activate a Mitsuba variant; return its name.

    Parameters
    ----------
    gpu, mono : bool, optional
        As :func:`choose_variant`.

    Returns
    -------
    str
        The variant now active. The choice for each (``gpu``, ``mono``) is made once per
        process and reused.

    Raises
    ------
    ParameterError
        As :func:`choose_variant`.

    Notes
    -----
    Does not register the sensor plugins: :func:`~.backend.select_variant` does both.
    """
    import mitsuba as mi

    key = (gpu, mono)
    if key not in _chosen:
        _chosen[key] = choose_variant(gpu, mono)
    mi.set_variant(_chosen[key])
    return _chosen[key]
