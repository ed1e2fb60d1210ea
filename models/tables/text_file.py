"""Reading a user's text file (robot, problem, measurement, simulation files, URDFs, programs):
UTF-8 text or one clear line saying why not."""

from __future__ import annotations

from pathlib import Path

from models.errors import InputError

__all__ = ["read_text_file"]


def _not_utf8(where: str, raw: bytes, exc: UnicodeDecodeError) -> str:
    """One line for text that is not UTF-8: line and column of the first bad byte, a hint."""
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        return (
            f"{where}: the file is UTF-16 encoded; save the file as UTF-8 (a plain text file, "
            "e.g. 'Save as... UTF-8' in the editor or spreadsheet)"
        )
    start = exc.start
    line = raw.count(b"\n", 0, start) + 1
    if b"\x00" in raw[:4096]:
        return f"{where}: not a text file (binary content, byte 0x{raw[start]:02x} at line {line}); expected UTF-8 text"
    col = start - (raw.rfind(b"\n", 0, start) + 1) + 1
    return (
        f"{where}: line {line}, column {col}: byte 0x{raw[start]:02x} is not UTF-8 text (the file is "
        "probably Latin-1 / Windows-1252); save the file as UTF-8"
    )


def read_text_file(path: str | Path, what: str = "file", error: type[InputError] = InputError) -> str:
    """The text of a user's input file, decoded as UTF-8 (a UTF-8 byte-order mark is dropped).

    Parameters
    ----------
    path : path
        The file.
    what : str
        What the file is, for messages (``"robot file"``, ``"measurement file"``, ...).
    error : type
        The :class:`~models.errors.InputError` subclass raised.

    Raises
    ------
    InputError
        One line naming the path: no such file, a folder where a file is expected, not
        readable, binary, or not UTF-8 (line and column of the first bad byte and the hint to
        save the file as UTF-8).
    """
    p = Path(path)
    if p.is_dir():
        raise error(f"{p}: is a folder; expected a {what}")
    if not p.exists():
        raise error(f"{p}: no such {what}")
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise error(f"{p}: cannot read the {what}: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(_not_utf8(str(p), raw, exc)) from None
    if "\x00" in text:
        raise error(f"{p}: not a text file (binary content); expected a {what} (UTF-8 text)")
    return text.removeprefix("\ufeff")
