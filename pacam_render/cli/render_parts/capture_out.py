"""Writing a capture from a command, and the lines that summarise it (``render``, ``sensor``)."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from ...capture.optics_error import summary_line
from ...exposure.direct import write_capture
from ..common import user_words


def write_or_rescue(cap, out: Path, force: bool, error_layer: bool = False) -> list[Path]:
    """Write the capture; only then drop its rendered passes (``DIR/.partial``). A failed
    write (a full disk) keeps them, tries the files in a temporary folder too, and says where
    both are: the same command resumes from the passes without rendering again."""

    try:
        paths = write_capture(cap, out, force=force, error_layer=error_layer)
    except OSError as exc:
        kept = out / ".partial"
        saved = kept.is_dir() and any(kept.iterdir())
        where = f"the rendered passes are kept in {kept}" if saved else "no passes could be kept"
        try:
            rescue = Path(tempfile.mkdtemp(prefix="pacam-rescue-"))
            write_capture(cap, rescue, force=True, error_layer=error_layer)
            where += f", and the capture was written to {rescue}"
        except OSError:
            pass
        again = "which resumes without rendering" if saved else "which renders it again"
        raise OSError(
            f"writing the capture to {out} failed ({exc}); {where}: free the space and run the "
            f"same command again, {again}"
        ) from None
    shutil.rmtree(out / ".partial", ignore_errors=True)
    return paths


def error_line(err: dict) -> str:
    """One line: the capture's Monte Carlo sigma, against the sensor's, its time steps' error,
    and its cost."""
    ratio = err.get("ratio_to_sensor")
    vs = f" ({ratio:.2g}x the sensor's)" if ratio is not None else ""
    target = ""
    if "target_sigma" in err:
        met = "met" if err["target_met"] else "NOT met"
        target = f", target {err['target_sigma']:.3g} {met}"
    steps = (
        "time-step error 0 (stratified random times: inside the MC sigma)"
        if err["time_steps_per_pass"]
        else "no time steps (static)"
    )
    return (
        f"MC sigma {err['mc_sigma']:.3g}{vs}{target}, {steps}, {err['seconds']:.1f} s "
        f"({err['passes']} passes, {err['spp']} spp, {err['sampler']})"
    )


def scale_line(optics: dict, coded: dict) -> str:
    """The camera's px quantities at the capture's resolution (they shrink with binning)."""
    if coded.get("schedule") == "designed":  # a_i and the range fitted to its own openings
        kind = coded.get("schedule_kind", "centres")
        head = (
            f"at {optics['width_px']}x{optics['height_px']} px: r = {optics['r_px']:.3g} px; "
            f"a designed schedule ({kind}) of {coded['n_patterns']} patterns"
        )
        if coded.get("a_i_px_per_ms2") is None:
            return head + f" ({coded.get('fit_undefined_reason', 'no parabola fits it')})"
        return head + (
            f", fitted a_i = {coded['a_i_px_per_ms2']:.3g} px/ms^2, invariant |s| <= "
            f"{coded['velocity_range_px_per_ms']:.3g} px/ms (fitted)"
        )
    return (
        f"at {optics['width_px']}x{optics['height_px']} px: r = {optics['r_px']:.3g} px, "
        f"a_i = {optics['a_i_px_per_ms2']:.3g} px/ms^2; the coded design keeps |s| <= "
        f"{coded['velocity_range_px_per_ms']:.3g} px/ms invariant (r = {coded['r_px']:.3g} px)"
    )


def optics_lines(block: dict | None) -> list[str]:
    """The diffraction decision and the largest left-out optical effect of a capture
    (:mod:`~pacam_render.capture.optics_error`); none for an older capture."""
    if not block:
        return []

    info = block["diffraction"]
    line = summary_line(block)
    line = user_words(line) if line else line
    if info.get("setting", "off") == "off":  # the budget's line says what it left out
        return [line] if line else []
    head = f"diffraction {info['decision']}"
    waves = "/".join(f"{w:g}" for w in info.get("wavelengths_nm", []))
    if "lambda_n_px" in info:
        ln = "/".join(f"{x:.3g}" for x in info["lambda_n_px"])
        psf = "exact defocused PSF" if info.get("ray_psf") == "exact" else "Airy draw"
        head += f"; in the rays ({psf}) at {waves} nm (lambda N = {ln} px)"
    elif "kernel_px" in info:
        head += f" ({info['kernel_px']} px kernels at {waves} nm)"
    return [head] + ([line] if line else [])
