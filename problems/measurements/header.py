"""Column names of a measurement file's header: quantities and units, joint-name mapping.

:func:`resolve_joint_names` checks a ``joint_names`` option; :func:`split_unit` maps one
header cell of the ``compplan`` format to its quantity and SI factor, and its unknown-column
error lists what every declared format expects (:data:`~.columns.FORMATS`).
"""

from __future__ import annotations

from collections.abc import Sequence

from models.errors import InputError

from .columns import (
    UNITS,
    COLUMNS,
    IGNORED_PREFIXES,
    JOINT_NAME_PRESETS,
    LABEL_COLUMNS,
    Q_COLUMNS,
    TRACKER_COLUMNS,
    TRACKER_FORMATS,
    tracker_columns_text,
)


def resolve_joint_names(joint_names: str | Sequence[str] | None, where: str = "joint_names") -> tuple[str, ...] | None:
    """The six joint column names of a ``joint_names`` option, or None for ``q1..q6``.

    Parameters
    ----------
    joint_names : str, sequence of str or None
        ``None`` (or ``"none"``): the plain ``q1..q6``.  A preset name of
        :data:`JOINT_NAME_PRESETS` (``"ros-ur"``), six comma-separated names
        (``"a,b,c,d,e,f"``) or a sequence of six names: the columns read as
        ``q1..q6`` in this order.
    where : str
        What the option is called, for messages.

    Raises
    ------
    InputError
        Unknown preset, not six names, an empty or repeated name, a name that is
        another column of the format (``fx``, ``x``, ``t``, ``q3`` for joint 1 ...).
    """
    if joint_names is None:
        return None
    if isinstance(joint_names, str):
        spec = joint_names.strip()
        if spec in ("", "none"):
            return None
        if spec in JOINT_NAME_PRESETS:
            return JOINT_NAME_PRESETS[spec]
        if "," not in spec:
            raise InputError(
                f"{where} {joint_names!r}: expected a preset ({', '.join(JOINT_NAME_PRESETS)}), "
                "'none' (q1..q6) or six comma-separated column names (joint 1 to joint 6)"
            )
        names = [n.strip() for n in spec.split(",")]
    else:
        names = [str(n).strip() for n in joint_names]
    shown = ",".join(names)
    if len(names) != 6:
        raise InputError(
            f"{where} '{shown}': {len(names)} name(s); expected six column names, joint 1 to joint 6 "
            f"(or a preset: {', '.join(JOINT_NAME_PRESETS)})"
        )
    for i, name in enumerate(names):
        if name == "":
            raise InputError(f"{where} '{shown}': name {i + 1} is empty; expected six column names")
        if names.index(name) != i:
            raise InputError(
                f"{where} '{shown}': '{name}' is given for joints {names.index(name) + 1} and {i + 1}; "
                "expected six different column names"
            )
        for other in names:
            if other != name and name.startswith(other) and name[len(other) :] in UNITS["angle"]:
                raise InputError(
                    f"{where} '{shown}': '{name}' reads as '{other}' with a unit suffix; "
                    "expected six column names without unit suffixes (a column may add one)"
                )
        try:
            as_column = split_unit(where, name)[0]
        except InputError:
            as_column = None
        taken = (as_column is not None and not (as_column == Q_COLUMNS[i] and name == Q_COLUMNS[i])) or any(
            name.startswith(pfx) for pfx in IGNORED_PREFIXES
        )
        if taken:
            raise InputError(
                f"{where} '{shown}': '{name}' (joint {i + 1}) is the name of another column of the "
                "measurement file format; expected the file's own names of the six joint columns"
            )
    return tuple(names)


def ros_joint_map(joint_names: tuple[str, ...] | None) -> dict[str, str]:
    """Joint column name -> ``q<i>`` (empty for the plain names)."""
    if joint_names is None:
        return {}
    return {name: Q_COLUMNS[i] for i, name in enumerate(joint_names)}


def _ros_hint(col: str) -> str:
    """The hint for an unknown column that is a ROS UR joint name."""
    for preset, names in JOINT_NAME_PRESETS.items():
        for name in names:
            if col.startswith(name) and col[len(name) :] in UNITS["angle"]:
                return (
                    f"; '{name}' is a ROS joint name: read the joint columns with --joint-names {preset} "
                    f"(joint_names='{preset}': {', '.join(names)} -> q1..q6)"
                )
    return ""


def split_unit(where: str, col: str, joint_map: dict[str, str] | None = None) -> tuple[str, float]:
    """Map a column header to (base name, SI factor); raise for unknown names."""
    if col in LABEL_COLUMNS:
        return col, 1.0
    for name, base in (joint_map or {}).items():
        if col.startswith(name) and col[len(name) :] in UNITS["angle"]:
            return base, UNITS["angle"][col[len(name) :]]
    for base, qty in COLUMNS.items():
        if col.startswith(base):
            suffix = col[len(base) :]
            if suffix in UNITS[qty]:
                return base, UNITS[qty][suffix]
    known = ", ".join(list(COLUMNS) + list(LABEL_COLUMNS))
    hint = _ros_hint(col) if not joint_map else ""
    if col in TRACKER_COLUMNS:
        hint = f"; '{col}' is a column of the tracker-dif format: read the file with --format tracker-dif"
    others = " or ".join(TRACKER_FORMATS)
    raise InputError(
        f"{where}: unknown column '{col}'{hint}; the compplan format expects {known} "
        "(with an optional unit suffix such as _mm, _deg, _N), or a column starting with "
        f"{' / '.join(IGNORED_PREFIXES)}; the {others} format (--format) expects {tracker_columns_text()}"
    )
