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


def is_mono(variant: str | None) -> bool:
    """Whether a Mitsuba variant renders one (grey) channel.

    Parameters
    ----------
    variant : str or None
        A variant name such as ``llvm_ad_mono``; None (no variant active) is not mono.

    Returns
    -------
    bool
        True for the ``*_mono`` and ``*_mono_polarized`` variants.

    Examples
    --------
    >>> is_mono("llvm_ad_mono"), is_mono("llvm_ad_rgb"), is_mono(None)
    (True, False, False)
    """
    return variant is not None and "_mono" in variant


def grey_request(grey: bool = False) -> bool:
    """Whether this process renders grey, checked before any work and without importing Mitsuba.

    Parameters
    ----------
    grey : bool, optional
        A grey capture was asked for (``--grey``, or ``grey = true`` in a study's ``[render]``).

    Returns
    -------
    bool
        True if ``grey`` is asked for or ``PACAM_VARIANT`` names a mono variant: the captures
        will then be one channel.

    Raises
    ------
    ParameterError
        If ``grey`` is asked for while ``PACAM_VARIANT`` names a colour variant.
    """
    name = os.environ.get("PACAM_VARIANT", "").strip()
    if grey and name and not is_mono(name):
        raise ParameterError(
            f"`grey` asks for a single-channel (mono) variant, but PACAM_VARIANT={name!r} "
            "renders colour; unset PACAM_VARIANT or set it to a mono variant (llvm_ad_mono)"
        )
    return bool(grey) or is_mono(name)


def _variant_name(kind: str, mono: bool) -> str:
    if kind == "scalar":
        # the Mitsuba wheel ships no scalar_mono: a grey capture then renders with scalar_rgb
        # and a luminance film, so that it is still one channel
        import mitsuba as mi

        return "scalar_mono" if mono and "scalar_mono" in mi.variants() else "scalar_rgb"
    return f"{kind}_ad_{'mono' if mono else 'rgb'}"


def _override(mono: bool = False) -> str | None:
    import mitsuba as mi

    name = os.environ.get("PACAM_VARIANT", "").strip()
    if not name:
        return None
    if name not in mi.variants():
        raise ParameterError(
            f"PACAM_VARIANT={name!r} is not a Mitsuba variant; valid: {', '.join(mi.variants())}"
        )
    if mono and not is_mono(name):
        valid = ", ".join(v for v in mi.variants() if is_mono(v))
        raise ParameterError(
            f"`grey` asks for a single-channel (mono) variant, but PACAM_VARIANT={name!r} "
            f"renders colour; unset PACAM_VARIANT or set it to a mono variant ({valid})"
        )
    if name.startswith("llvm"):
        ok, why = llvm_status()
        if not ok:
            raise ParameterError(f"PACAM_VARIANT={name!r} cannot render: {why}. Fix: {LLVM_FIX}")
    elif name.startswith("cuda") and not cuda_available():
        fallback = name.replace("cuda", "llvm", 1)
        raise ParameterError(
            f"PACAM_VARIANT={name!r} cannot render here: the CUDA variant does not load (no "
            f"NVIDIA GPU or driver); set PACAM_VARIANT={fallback} to render on the CPU, or "
            "unset PACAM_VARIANT to let pacam choose (llvm_ad_rgb where it works)"
        )
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
        Pick the single-channel variant (``*_mono``), for grey experiments. The Mitsuba wheel
        has no ``scalar_mono``, so there the scalar fallback is ``scalar_rgb`` either way (a grey
        capture then asks its film for luminance, :func:`~.registry.sensor_entry`).

    Returns
    -------
    str
        ``PACAM_VARIANT`` if set; else ``cuda_ad_*`` when ``gpu`` and CUDA loads; else
        ``llvm_ad_*`` when drjit's LLVM backend works (:func:`llvm_status`); else
        ``scalar_mono`` (if this Mitsuba has it and ``mono``) or ``scalar_rgb``, with one
        :class:`BackendWarning` per process.

    Raises
    ------
    ParameterError
        If ``PACAM_VARIANT`` is not a Mitsuba variant, names an LLVM variant that cannot
        render here, or names a CUDA variant where none loads (no GPU); the message names the
        CPU variant to use instead; or names a colour variant while ``mono`` asks for grey.
    """
    override = _override(mono)
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
