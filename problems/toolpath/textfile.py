"""Reading a program file as text, with the checks every program format makes first."""

from __future__ import annotations

from pathlib import Path

from models.errors import InputError

__all__ = ["PROGRAM_MAX_BYTES", "read_program_text"]

#: Largest program file read (bytes): 10^6 moves or CL rows fit well under it.
PROGRAM_MAX_BYTES = 512 * 2**20


def read_program_text(
    path: str | Path, kind: str, what: str, error: type[InputError], *, latin1_fallback: bool = False
) -> str:
    """The text of a program file.

    Parameters
    ----------
    path : str or Path
        The file.
    kind : str
        The format's name ("G-code", "CL"), for the messages.
    what : str
        What the file should be, for the messages ("a G-code program", "CL data as CSV text").
    error : type
        The format's error class (an :class:`~models.errors.InputError`).
    latin1_fallback : bool
        Read a file that is not UTF-8 as Latin-1 (old controls' comments) instead of refusing it:
        every byte is a character, ASCII reads the same, so only non-ASCII text differs (G-code:
        a comment's text; outside a comment the lexer refuses it, naming the line).

    Raises
    ------
    InputError
        Of class ``error``: missing, unreadable, too large (``PROGRAM_MAX_BYTES``) or binary
        (NUL bytes) file, or not UTF-8 without ``latin1_fallback`` (the line, the byte and its
        offset named).
    """
    p = Path(path)
    try:
        size = p.stat().st_size
        if size > PROGRAM_MAX_BYTES:
            raise error(f"{p}: {size} bytes, more than the {PROGRAM_MAX_BYTES} bytes a {kind} file may have")
        data = p.read_bytes()
    except OSError as exc:
        raise error(f"{p}: cannot read the {kind} file ({exc.strerror or exc})") from None
    if b"\0" in data:
        raise error(f"{p}: a binary file (it holds NUL bytes); expected {what}")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        if latin1_fallback:
            return data.decode("latin-1")  # decodes every byte
        line = data.count(b"\n", 0, exc.start) + 1
        raise error(
            f"{p}: line {line}: byte 0x{data[exc.start]:02x} at offset {exc.start} is not UTF-8 text; "
            f"expected {what}: save the file as UTF-8"
        ) from None
