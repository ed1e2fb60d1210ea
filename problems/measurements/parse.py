"""Reading measurement files: dialects, formats, header and joint-name mapping, the table.

:func:`read_measurements` / :func:`parse_measurements` turn CSV text into a
validated :class:`~problems.measurements.table.Measurements`; the header's names are
mapped by :mod:`.header`, the cells themselves are read by :mod:`.cells`, a tracker-dif
file by :mod:`.tracker`, and the finished table is checked by :mod:`.validation`.
"""

from __future__ import annotations

import csv
import datetime as _dt
import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from models.errors import InputError

from .cells import Cells, time_column
from .columns import (
    UNITS,
    COLUMNS,
    DIALECT_CHOICES,
    DIALECTS,
    FORMAT_CHOICES,
    IGNORED_PREFIXES,
    JOINT_NAME_PRESETS,
    POSITION_COLUMNS,
    Q_COLUMNS,
    ROTATION_COLUMNS,
    SIGMA_ROT_COLUMNS,
    SIGMA_XYZ_COLUMNS,
    WRENCH_COLUMNS,
)
from .header import ros_joint_map, split_unit, resolve_joint_names
from .table import Measurements, sigma_rms
from .tracker import is_tracker_header, read_tracker
from .validation import validate


def read_measurements(
    path: str | Path,
    require_position: bool = True,
    require_wrench: bool = True,
    *,
    dialect: str = "auto",
    joint_names: str | Sequence[str] | None = None,
    file_format: str = "auto",
) -> Measurements:
    """Read and validate a measurement file.

    Parameters
    ----------
    path : path
        CSV file (see ``docs/measurement-file.md``).
    require_position : bool
        Whether ``x, y, z`` are required (False for command files of ``predict``
        and ``compensate``).
    require_wrench : bool
        Whether ``fx..mz`` are required (a missing wrench is *not* assumed zero).
    dialect : {"auto", "comma", "semicolon"}
        ``comma``: ``,`` separates cells, ``.`` is the decimal point.  ``semicolon``:
        ``;`` separates cells, numbers have a decimal comma (``1,5``; ``1.5`` is read
        too, a cell with both ``,`` and ``.`` is an error).  ``auto`` (default): the
        ``semicolon`` dialect when the header line has ``;`` and no ``,``, an error
        when it has both, else ``comma``; choosing ``semicolon`` adds a note.
    joint_names : str, sequence of str or None
        Columns read as ``q1..q6``: None for ``q1..q6`` themselves, ``"ros-ur"`` for
        ``shoulder_pan_joint, shoulder_lift_joint, elbow_joint, wrist_1_joint,
        wrist_2_joint, wrist_3_joint`` (rad; ``_deg`` suffix allowed), or six names
        (a sequence or one comma-separated string).  See :func:`resolve_joint_names`.
        Only for the ``compplan`` format.
    file_format : {"auto", "compplan", "tracker-dif", "tracker-dif-reversed"}
        ``compplan``: the columns of ``docs/measurement-file.md``.  ``tracker-dif``: a
        tracker export ``step_order, x_t, y_t, z_t, x_dif, y_dif, z_dif, joint_1..joint_6``
        (mm, deg; measured point = target + dif, no load; :mod:`.tracker`);
        ``tracker-dif-reversed``: the same with measured point = target - dif.  ``auto``
        (default): ``tracker-dif`` when the header has every tracker-dif column (with a
        note), else ``compplan``.

    Returns
    -------
    Measurements
        SI units; :attr:`Measurements.notes` lists what was detected or mapped.

    Raises
    ------
    InputError
        Missing or duplicated columns, non-numeric, empty, NaN or infinite cells,
        implausible magnitudes (the message suggests the unit), duplicated rows,
        time running backwards, a separator other than the dialect's, an ambiguous
        header under ``auto``, a bad ``dialect``, ``joint_names`` or ``file_format``; for the
        tracker formats, a column other than theirs, ``step_order`` decreasing, or a
        deviation beyond :data:`~.validation.PLAUSIBLE_NOMINAL_DEVIATION_M`.
    """
    from models.robot import read_text_file

    p = Path(path)
    _check_dialect(dialect)
    _check_format(file_format)
    names = resolve_joint_names(joint_names)
    text = read_text_file(p, "measurement file (CSV)")
    return parse_measurements(
        text, str(p), require_position, require_wrench, dialect=dialect, joint_names=names, file_format=file_format
    )


#: Separators a spreadsheet may have written instead of the dialect's (name for the message).
_OTHER_SEPARATORS = {",": "','", ";": "';'", "\t": "tab", "|": "'|'"}


def _check_dialect(dialect: str) -> None:
    if dialect not in DIALECT_CHOICES:
        raise InputError(f"CSV dialect {dialect!r}: expected one of {', '.join(DIALECT_CHOICES)}")


def _check_format(file_format: str) -> None:
    if file_format not in FORMAT_CHOICES:
        raise InputError(f"file format {file_format!r}: expected one of {', '.join(FORMAT_CHOICES)}")


def _resolve_format(where: str, header: list[str], file_format: str, names: tuple[str, ...] | None) -> str:
    """The format of a header: ``auto`` is ``tracker-dif`` when every tracker-dif column is there;
    raises for joint names given with a tracker format."""
    if file_format == "auto":
        file_format = "tracker-dif" if is_tracker_header(header) else "compplan"
    if file_format != "compplan" and names is not None:
        raise InputError(
            f"{where}: joint_names / --joint-names apply to the compplan format; the {file_format} "
            "format's joint columns are joint_1..joint_6"
        )
    return file_format


def _format_note(where: str, file_format: str) -> str:
    """The note of a format detected from the header."""
    return (
        f"{where}: read as the {file_format} format (detected from the header): measured point = "
        "x_t + x_dif ... in mm (target + deviation, robot base frame), joints joint_1..joint_6 in degrees, "
        "no external load; declare --format tracker-dif to fix it, or --format tracker-dif-reversed when "
        "the deviation is target - measured"
    )


def _check_separator(where: str, header_line: int, header: list[str], dialect: str = "comma") -> None:
    """Refuse a header that is one cell holding another separator (``;`` from a spreadsheet
    with a decimal comma, tabs): the message names the separator and the way out."""
    if len(header) > 2:
        return
    sep_ok = DIALECTS[dialect][0]
    joined = sep_ok.join(header)
    for sep, name in _OTHER_SEPARATORS.items():
        if sep == sep_ok:
            continue
        if joined.count(sep) >= 2:
            shown = joined[:60].replace("\t", "\\t")
            if sep == ";":
                way = (
                    "use ',' as the separator (and '.' as the decimal point), e.g. export as "
                    "'CSV (comma delimited)', or read the file as it is with --csv-dialect semicolon "
                    "(or auto)"
                )
            elif sep == ",":
                way = "read it with --csv-dialect comma (or auto), or export it with ';' as the separator"
            else:
                way = (
                    f"use '{sep_ok}' as the separator, e.g. export as 'CSV (comma delimited)'"
                    if sep_ok == ","
                    else f"use '{sep_ok}' as the separator"
                )
            raise InputError(
                f"{where}: line {header_line}: the header '{shown}' looks {name}-separated, but the "
                f"file is read as the {dialect} dialect ('{sep_ok}'-separated); {way}"
            )


def _header_text(lines: list[str]) -> tuple[int, str] | None:
    """(line number, text) of the first line that is neither empty nor a comment."""
    for i, ln in enumerate(lines, start=1):
        s = ln.strip()
        if not s or s.startswith("#") or s.startswith('"#'):
            continue
        return i, ln
    return None


def _detect_dialect(where: str, lines: list[str]) -> str:
    """``semicolon`` when the header line has ';' and no ',', an error when it has both, else ``comma``."""
    head = _header_text(lines)
    if head is None:
        return "comma"
    ln, text = head
    if ";" in text and "," in text:
        raise InputError(
            f"{where}: line {ln}: the header has both ',' and ';', so the separator cannot be told "
            "apart; declare the dialect (--csv-dialect comma or --csv-dialect semicolon)"
        )
    return "semicolon" if ";" in text else "comma"


def _resolve_dialect(where: str, lines: list[str], dialect: str) -> tuple[str, bool]:
    """(dialect, detected): ``auto`` resolved by the header line, else the declared one."""
    detected = dialect == "auto"
    if detected:
        dialect = _detect_dialect(where, lines)
    return dialect, detected


def _read_rows(where: str, lines: list[str], dialect: str) -> tuple[int, list[str], list[tuple[int, list[str]]]]:
    """(header line, header cells, rows as (line, cells)) of the non-empty, non-comment
    lines; raises for an empty file, a header in another separator or no rows."""
    sep = DIALECTS[dialect][0]
    table: list[tuple[int, list[str]]] = []
    reader = csv.reader(io.StringIO("\n".join(lines)), delimiter=sep)
    for lineno, cells in enumerate(reader, start=1):
        if not cells or (len(cells) == 1 and cells[0].strip() == ""):
            continue
        if cells[0].lstrip().startswith("#"):
            continue
        table.append((lineno, [c.strip() for c in cells]))
    if not table:
        raise InputError(f"{where}: empty file; expected a header row and measurement rows")
    header_line, header = table[0]
    _check_separator(where, header_line, header, dialect)
    rows = table[1:]
    if not rows:
        raise InputError(f"{where}: no measurement rows after the header (line {header_line})")
    return header_line, header, rows


def _map_columns(
    where: str, header_line: int, header: list[str], jmap: dict[str, str]
) -> tuple[dict[str, tuple[int, str, float]], list[str]]:
    """(quantity -> (column index, column as written, SI factor); the q1..q6 columns left
    unmapped because joint_names names the joint columns)."""
    colmap: dict[str, tuple[int, str, float]] = {}
    unmapped_q: list[str] = []  # q1..q6 columns when joint_names names the joint columns
    for k, col in enumerate(header):
        if col == "":
            raise InputError(f"{where}: line {header_line}: column {k + 1} has an empty name")
        if any(col.startswith(pfx) for pfx in IGNORED_PREFIXES):
            continue
        base, factor = split_unit(where, col, jmap)
        if jmap and base in Q_COLUMNS and not any(col.startswith(n) and col[len(n) :] in UNITS["angle"] for n in jmap):
            unmapped_q.append(col)
            continue
        if base in colmap:
            other = colmap[base][1]
            raise InputError(
                f"{where}: column '{base}' is given twice ('{other}' and '{col}'); "
                "keep exactly one (with its unit suffix)"
            )
        colmap[base] = (k, col, factor)
    return colmap, unmapped_q


def _check_required(
    where: str,
    header_line: int,
    header: list[str],
    colmap: dict[str, tuple[int, str, float]],
    unmapped_q: list[str],
    jmap: dict[str, str],
    names: tuple[str, ...] | None,
    require_position: bool,
    require_wrench: bool,
) -> None:
    """Raise for a missing required column, or q1..q6 besides the named joint columns."""
    required = (
        list(Q_COLUMNS)
        + (list(WRENCH_COLUMNS) if require_wrench else [])
        + (list(POSITION_COLUMNS) if require_position else [])
    )
    missing = [c for c in required if c not in colmap]
    if missing:
        qname = {q: n for n, q in jmap.items()}
        shown = ", ".join(qname.get(c, c) for c in missing)
        via = (
            f" (joint columns named by joint_names / --joint-names: {', '.join(names or ())})"
            if any(c in qname for c in missing)
            else ""
        )
        also = (
            f"; the file has {', '.join(unmapped_q)}: to read those, leave the joint names at q1..q6"
            if unmapped_q
            else ""
        )
        raise InputError(
            f"{where}: missing required column(s) {shown}{via} "
            f"(header on line {header_line}: {', '.join(header)}){also}"
        )
    if unmapped_q:
        raise InputError(
            f"{where}: column(s) {', '.join(unmapped_q)} besides the joint columns named by "
            f"joint_names / --joint-names ({', '.join(colmap[q][1] for q in Q_COLUMNS)}); "
            "keep one set of joint columns"
        )


def _check_groups(where: str, colmap: dict[str, tuple[int, str, float]]) -> None:
    """Raise for an incomplete column group, a single and a per-axis standard deviation
    together, or an orientation standard deviation without rx, ry, rz."""
    for grp in (WRENCH_COLUMNS, POSITION_COLUMNS, ROTATION_COLUMNS, SIGMA_XYZ_COLUMNS, SIGMA_ROT_COLUMNS):
        have = [c for c in grp if c in colmap]
        if have and len(have) != len(grp):
            raise InputError(
                f"{where}: columns {', '.join(grp)} go together; found only {', '.join(colmap[c][1] for c in have)}"
            )
    for single, per_axis, what in (("sigma", "sigma_x", "position"), ("sigma_r", "sigma_rx", "orientation")):
        if single in colmap and per_axis in colmap:
            grp = SIGMA_XYZ_COLUMNS if single == "sigma" else SIGMA_ROT_COLUMNS
            raise InputError(
                f"{where}: columns '{colmap[single][1]}' and '{colmap[per_axis][1]}' are both given; "
                f"give either '{single}' (one {what} standard deviation for every axis) or "
                f"{', '.join(grp)} (per axis), not both"
            )
    rot_sigma = [colmap[c][1] for c in ("sigma_r", *SIGMA_ROT_COLUMNS) if c in colmap]
    if rot_sigma and "rx" not in colmap:
        raise InputError(
            f"{where}: column(s) {', '.join(rot_sigma)} (orientation standard deviation) need the "
            "measured orientation rx, ry, rz, which the file does not have"
        )


def _check_row_lengths(where: str, rows: list[tuple[int, list[str]]], ncol: int, decimal_comma: bool) -> None:
    """Raise for a row whose cell count differs from the header's (hinting at a decimal comma)."""
    for lineno, cells in rows:
        if len(cells) != ncol:
            hint = ""
            if not decimal_comma and len(cells) > ncol and any(c.isdigit() and c.lstrip("-").isdigit() for c in cells):
                hint = "; a decimal comma (0,40)? write numbers with '.' (0.40)"
            raise InputError(f"{where}: line {lineno}: {len(cells)} cells, expected {ncol} (as the header){hint}")


def _column(
    colmap: dict[str, tuple[int, str, float]], rows: list[tuple[int, list[str]]], cells_parser: Cells, base: str
) -> np.ndarray:
    """One numeric column in SI units, shape (N,)."""
    k, col, factor = colmap[base]
    return np.array([cells_parser.number(ln, col, cells[k]) for ln, cells in rows]) * factor


def _numeric_columns(
    where: str, colmap: dict[str, tuple[int, str, float]], rows: list[tuple[int, list[str]]], cells_parser: Cells
) -> dict:
    """The numeric fields of :class:`Measurements`, read in column order: joints, wrench
    (zero when absent), position, orientation, then the optional columns."""

    def stack(cols: tuple[str, ...]) -> np.ndarray:
        return np.column_stack([_column(colmap, rows, cells_parser, c) for c in cols])

    q = stack(Q_COLUMNS)
    wrench = stack(WRENCH_COLUMNS) if "fx" in colmap else np.zeros((len(rows), 6))
    pos = stack(POSITION_COLUMNS) if "x" in colmap else None
    rot = stack(ROTATION_COLUMNS) if "rx" in colmap else None
    return dict(q=q, wrench=wrench, p=pos, rotation=rot, **_optional_columns(where, colmap, rows, cells_parser))


def _optional_columns(
    where: str, colmap: dict[str, tuple[int, str, float]], rows: list[tuple[int, list[str]]], cells_parser: Cells
) -> dict:
    """t (numbers or date-times), temperature and the standard deviations (None when absent)."""

    def column(base: str) -> np.ndarray:
        return _column(colmap, rows, cells_parser, base)

    t = t_origin = None
    if "t" in colmap:
        k, col, factor = colmap["t"]
        t, t_origin = time_column(where, rows, k, col, factor, cells_parser)
    temp = column("temperature") if "temperature" in colmap else None
    sigma = column("sigma") if "sigma" in colmap else None
    sigma_xyz = np.column_stack([column(c) for c in SIGMA_XYZ_COLUMNS]) if "sigma_x" in colmap else None
    if sigma_xyz is not None:
        sigma = sigma_rms(sigma_xyz)
    sigma_rot = None
    if "sigma_rx" in colmap:
        sigma_rot = np.column_stack([column(c) for c in SIGMA_ROT_COLUMNS])
    elif "sigma_r" in colmap:
        sigma_rot = np.repeat(column("sigma_r")[:, None], 3, axis=1)
    return dict(t=t, t_origin=t_origin, temperature=temp, sigma=sigma, sigma_xyz=sigma_xyz, sigma_rot=sigma_rot)


def _point_column(
    where: str, colmap: dict[str, tuple[int, str, float]], rows: list[tuple[int, list[str]]]
) -> np.ndarray | None:
    """The pose ids of the ``point`` column (str), or None; raises for an empty cell."""
    if "point" not in colmap:
        return None
    k = colmap["point"][0]
    point = np.array([cells[k] for _ln, cells in rows], dtype=object)
    for ln, cells in rows:
        if cells[k] == "":
            raise InputError(f"{where}: line {ln}, column 'point': empty cell; expected a pose id")
    return point.astype(str)


def _notes(
    where: str,
    dialect: str,
    detected: bool,
    cells_parser: Cells,
    t_origin: _dt.datetime | None,
    line: np.ndarray,
    names: tuple[str, ...] | None,
    colmap: dict[str, tuple[int, str, float]],
) -> list[str]:
    """What was decided without the user saying so: a detected dialect, mixed decimal
    separators, date-times read as times, a joint-name mapping."""
    notes: list[str] = []
    if detected and dialect == "semicolon":
        extra = ""
        if cells_parser.n_point:
            extra = (
                f"; {cells_parser.n_point} cell(s) written with a decimal point (e.g. 1.5) were read with "
                "'.' as the decimal point too"
            )
        notes.append(
            f"{where}: read as ';'-separated with decimal commas (detected from the header line; "
            f"declare --csv-dialect to fix it){extra}"
        )
    elif DIALECTS[dialect][1] and cells_parser.n_point and cells_parser.n_comma:
        notes.append(
            f"{where}: {cells_parser.n_comma} cell(s) have a decimal comma and {cells_parser.n_point} a "
            "decimal point; both were read as the decimal separator"
        )
    if t_origin is not None:
        zone = (
            ""
            if t_origin.tzinfo is not None
            else "; no time zone given: local clock times are taken as they are (a daylight-saving change "
            "inside the file would shift them by 1 h)"
        )
        notes.append(
            f"{where}: column 't' read as date-times: t = seconds since this file's first row "
            f"(line {int(line[0])}, {t_origin.isoformat()}){zone}"
        )
    if names is not None:
        preset = next((p for p, v in JOINT_NAME_PRESETS.items() if v == names), None)
        how = f"preset '{preset}'" if preset else "joint names given"
        mapping = ", ".join(f"{colmap[q][1]} = {q}" for q in Q_COLUMNS)
        notes.append(f"{where}: joint columns read as q1..q6 ({how}): {mapping}")
    return notes


def parse_measurements(
    text: str,
    where: str = "<text>",
    require_position: bool = True,
    require_wrench: bool = True,
    *,
    dialect: str = "auto",
    joint_names: str | Sequence[str] | None = None,
    file_format: str = "auto",
) -> Measurements:
    """Parse measurement-file text; see :func:`read_measurements` (same parameters;
    ``where`` names the text in messages and notes)."""
    _check_dialect(dialect)
    _check_format(file_format)
    names = resolve_joint_names(joint_names)
    lines = text.splitlines()
    dialect, detected = _resolve_dialect(where, lines, dialect)
    decimal_comma = DIALECTS[dialect][1]
    cells_parser = Cells(where, decimal_comma)
    header_line, header, rows = _read_rows(where, lines, dialect)
    fmt = _resolve_format(where, header, file_format, names)
    if fmt != "compplan":
        return _parse_tracker(where, header_line, header, rows, cells_parser, fmt, (dialect, detected, file_format))
    jmap = ros_joint_map(names)
    colmap, unmapped_q = _map_columns(where, header_line, header, jmap)
    _check_required(where, header_line, header, colmap, unmapped_q, jmap, names, require_position, require_wrench)
    _check_groups(where, colmap)
    _check_row_lengths(where, rows, len(header), decimal_comma)
    line = np.array([ln for ln, _c in rows], dtype=int)
    units = {col: factor for (_k, col, factor) in colmap.values()}
    fields = _numeric_columns(where, colmap, rows, cells_parser)
    point = _point_column(where, colmap, rows)
    notes = _notes(where, dialect, detected, cells_parser, fields["t_origin"], line, names, colmap)
    m = Measurements(
        **fields,
        point=point,
        line=line,
        source=where,
        units=units,
        notes=notes,
        columns={base: col for base, (_k, col, _f) in colmap.items()},
    )
    validate(m, colmap, _plain=frozenset(c for c in header if c in COLUMNS or c in jmap))
    return m


def _parse_tracker(
    where: str,
    header_line: int,
    header: list[str],
    rows: list[tuple[int, list[str]]],
    cells_parser: Cells,
    fmt: str,
    how: tuple[str, bool, str],
) -> Measurements:
    """A file of a tracker format (:mod:`.tracker`), validated, with its notes; ``how`` is
    (dialect, dialect detected, format as asked)."""
    dialect, detected, asked = how
    _check_row_lengths(where, rows, len(header), DIALECTS[dialect][1])
    m, colmap = read_tracker(where, header_line, header, rows, cells_parser, fmt)
    m.notes = _notes(where, dialect, detected, cells_parser, None, m.line, None, colmap)
    if asked == "auto":
        m.notes.append(_format_note(where, fmt))
    validate(m, colmap, _plain=frozenset())
    return m
