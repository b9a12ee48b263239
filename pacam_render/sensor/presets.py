"""Sensor presets: the built-in ones by name, and the JSON or TOML files of one's own.

Each preset is the :class:`~.model.SensorModel` constructor's keyword arguments, kept apart
from the chain so that the numbers and their sources are read in one place;
:meth:`~.model.SensorModel.from_preset` validates them into a model.

- ``paper``: the paper's simulation noise, additive Gaussian sigma on a [0, 1] image (Sec. 3,
  sigma = 0.01 by default). Decision: it is the same chain with no shot noise, no dark current and
  no fixed pattern, with 1.0 of the image = the full well = 65536 e- (qe = 1, K = 1 DN/e-), and
  ``read_noise_e = sigma * full_well_e``. A 20-bit ADC with a black offset of 2**19 DN leaves
  room for noise of +-8 full scales, so the noise is not clipped; the signal itself saturates at
  1.0 before the noise is added. So ``model.unit_from_dn(model.capture(
  model.photons_from_unit(x), seed=s))`` is ``x + N(0, sigma**2)`` quantised to 2**-16, and the
  output stays integer DN like every other preset. Set sigma with
  ``SensorModel.from_preset("paper", sigma=0.02)``.
- ``grasshopper-icx285``: the prototype's camera, Point Grey Grasshopper GRAS-14S5C (paper
  Sec. 4 and Table 1: Sony ICX285 CCD, 6.45 um pixels; the "C" model is the colour one, with a
  Bayer filter). Each value's source, or "estimate", is given beside it in :data:`PRESETS`.
- ``grasshopper-icx285-mono``: its monochrome twin (GRAS-14S5M, Sony ICX285AL): the same
  noise, full well and ADC, no Bayer filter, and the higher QE of a filterless pixel (0.62, an
  estimate). Grey captures (``--grey``) use it; a Bayer preset on a grey capture is refused
  (:func:`~pacam_render.sensor.apply.add_sensor_layers`), since a grey image is not a mosaic.
- User presets: JSON or TOML files with the constructor's parameter names as top-level keys,
  optionally ``base`` (a built-in preset to start from), ``sigma`` (read noise as a fraction of
  the full well) and ``description``. (TOML on Python 3.10 reads through ``tomli``.)
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ..errors import ParameterError
from ..io.toml_file import parse_toml, read_text

PRESETS: dict[str, dict[str, Any]] = {
    "paper": {
        "name": "paper",
        "qe": 1.0,
        "shot_noise": False,  # the paper adds Gaussian noise only (Sec. 3)
        "dark_current_e_per_s": 0.0,
        "full_well_e": 65536.0,  # 1.0 of the [0, 1] image
        "read_noise_e": 0.01 * 65536.0,  # sigma = 0.01 of full scale, the paper's standard
        "K": 1.0,
        "black_offset_dn": float(1 << 19),  # headroom for negative noise
        "bit_depth": 20,
        "prnu": 0.0,
        "dsnu_e": 0.0,
        "bayer": None,
    },
    "grasshopper-icx285": {
        "name": "grasshopper-icx285",
        # Estimate: peak QE of the mono ICX285AL is usually quoted near 0.6-0.65 (500-550 nm);
        # the colour ICX285AQ loses some of it in its filters.
        "qe": 0.5,
        "shot_noise": True,
        # Estimate for an uncooled interline CCD near 40 C; 0.45 e- over a 45 ms exposure.
        "dark_current_e_per_s": 10.0,
        # Estimate: ICX285 cameras quote full wells of 16000-18000 e-.
        "full_well_e": 18000.0,
        # Estimate: ICX285 cameras quote 6-10 e- depending on the pixel clock.
        "read_noise_e": 8.0,
        # Estimate: at 0 dB the gain is set so that the 14-bit ADC clips just below the full
        # well, (16383 - 64) / 0.92 = 17738 e-, as cameras usually do: saturated pixels then
        # read a constant 16383 DN.
        "K": 0.92,
        # Estimate: a small positive black level, so read noise below zero is kept.
        "black_offset_dn": 64.0,
        # Source: Point Grey Grasshopper Technical Reference v1.5 (2010), sec. 4.5.9,
        # "a 14-bit A/D converter" (Raw16 output carries 14 useful bits).
        "bit_depth": 14,
        "prnu": 0.01,  # Estimate: typical of CCDs (0.5-1 %).
        "dsnu_e": 1.0,  # Estimate.
        # GRAS-14S5C is the colour model (Bayer filter); the tile order is assumed RGGB.
        "bayer": "RGGB",
    },
}
"""Built-in presets: constructor keyword arguments of :class:`~.model.SensorModel` by name."""
PRESETS["grasshopper-icx285-mono"] = {
    **PRESETS["grasshopper-icx285"],
    "name": "grasshopper-icx285-mono",
    # The monochrome part, Sony ICX285AL (GRAS-14S5M): the same CCD without the colour filter
    # array, so the same read noise, full well, dark current, gain and ADC.
    # Estimate: no datasheet figure of its absolute QE could be found here (Sony's datasheets
    # give the relative spectral response only); cameras built on the ICX285AL quote a peak QE
    # of about 0.60-0.65 near 500 nm, and 0.62 is the middle of that range.
    "qe": 0.62,
    "bayer": None,  # no colour filter: every pixel sees the grey image, no mosaic, no demosaic
}

MONO_PRESETS: dict[str, str] = {"grasshopper-icx285": "grasshopper-icx285-mono"}
"""Each built-in colour (Bayer) preset's monochrome counterpart, for grey captures."""


def mono_preset(name: str) -> str:
    """The monochrome preset a grey capture uses in place of ``name``.

    Parameters
    ----------
    name : str
        A preset name (or file path).

    Returns
    -------
    str
        The built-in monochrome counterpart of a colour preset (:data:`MONO_PRESETS`), else
        ``name`` itself.

    Examples
    --------
    >>> mono_preset("grasshopper-icx285"), mono_preset("paper")
    ('grasshopper-icx285-mono', 'paper')
    """
    return MONO_PRESETS.get(name, name) if isinstance(name, str) else name


FILE_EXTRA_KEYS = ("base", "sigma", "description")
"""The keys a preset file may hold besides the constructor's parameters."""


def available_presets() -> list[str]:
    """Names of the built-in presets.

    Returns
    -------
    list of str
        The keys of :data:`PRESETS`, sorted (``grasshopper-icx285``,
        ``grasshopper-icx285-mono`` and ``paper``).

    Examples
    --------
    >>> available_presets()
    ['grasshopper-icx285', 'grasshopper-icx285-mono', 'paper']
    """
    return sorted(PRESETS)


def read_preset_file(path: Path) -> dict[str, Any]:
    """The table of a ``.json`` or ``.toml`` preset file (strict UTF-8), as a dict."""
    suffix = path.suffix.lower()
    if suffix not in (".json", ".toml"):
        raise ParameterError(f"preset file must end in .json or .toml, got {str(path)!r}")
    text = read_text(path, "preset file")  # strictly UTF-8, a byte-order mark allowed
    data = _parse_json(path, text) if suffix == ".json" else parse_toml(text, f"preset file {path}")
    if not isinstance(data, dict):
        raise ParameterError(f"preset file {path} must hold one table/object of parameters")
    return data


def _parse_json(path: Path, text: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ParameterError(f"preset file {path} is not valid JSON: {exc}") from None
    except RecursionError:
        raise ParameterError(f"preset file {path} is nested too deep") from None
