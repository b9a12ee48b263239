"""Input files read as text: strictly UTF-8 (a byte-order mark is allowed), TOML parsed, and
every failure a :class:`~pacam_render.errors.ParameterError` naming the file and what is
wrong (the line and column, or the byte that is not UTF-8), never a traceback."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import ParameterError, did_you_mean

BOM = "\ufeff"


def read_text(path: str | os.PathLike, what: str = "file") -> str:
    """The file's text, strictly UTF-8; a leading byte-order mark is dropped.

    Raises
    ------
    ParameterError
        The file is missing, unreadable, or not UTF-8 (the message gives the byte offset).
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise ParameterError(f"{what} {str(p)!r} does not exist") from None
    except OSError as exc:
        raise ParameterError(f"cannot read {what} {str(p)!r}: {exc.strerror or exc}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ParameterError(
            f"{what} {str(p)!r} is not UTF-8 text: byte 0x{data[exc.start]:02x} at offset "
            f"{exc.start} ({exc.reason}); save it as UTF-8"
        ) from None
    return text[1:] if text.startswith(BOM) else text


def parse_toml(text: str, where: str) -> dict:
    """``text`` parsed as TOML (a byte-order mark is dropped), or ParameterError naming
    ``where`` and the parser's line and column."""
    try:
        import tomllib
    except ModuleNotFoundError:  # pragma: no cover - Python 3.10
        import tomli as tomllib
    if text.startswith(BOM):
        text = text[1:]
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{where} is not valid TOML: {exc}") from None


def read_toml(path: str | os.PathLike, what: str = "file") -> dict:
    """:func:`read_text` then :func:`parse_toml`."""
    return parse_toml(read_text(path, what), f"{what} {str(path)!r}")


def sub_table(doc: dict, key: str, where: str | None = None) -> dict:
    """``doc[key]`` (empty when absent), refused unless it is a table; ``where`` names it in
    the message (default ``[key]``)."""
    value = doc.get(key, {})
    if not isinstance(value, dict):
        raise ParameterError(f"{where or f'[{key}]'} must be a table, got {type(value).__name__}")
    return value


def check_keys(table: dict, where: str, valid: set) -> None:
    """Refuse a key of ``table`` not in ``valid``, naming it, the closest valid key and all
    of them."""
    unknown = sorted(set(table) - valid)
    if unknown:
        raise ParameterError(
            f"{where}: unknown key {unknown[0]!r}{did_you_mean(unknown[0], valid)}; valid keys: "
            f"{', '.join(sorted(valid))}"
        )
