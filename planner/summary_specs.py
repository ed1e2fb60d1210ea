"""The kinds of value a run's ``summary.json`` may hold: the declarative kinds of
:mod:`models.tables.kinds`, where they live now (one reader of tables for every format); the names
are re-exported here for :mod:`planner.summary_schema` and its callers."""

from models.tables.kinds import (
    MAGNITUDE_MAX,
    SHOWN_CHARS,
    Ctx,
    Either,
    External,
    Flag,
    ListOf,
    MapOf,
    Number,
    Refused,
    Row,
    Spec,
    Table,
    Text,
    Vector,
    check,
    dotted,
    shown,
    template_text,
    templates,
)

__all__ = [
    "MAGNITUDE_MAX",
    "SHOWN_CHARS",
    "Ctx",
    "Either",
    "External",
    "Flag",
    "ListOf",
    "MapOf",
    "Number",
    "Refused",
    "Row",
    "Spec",
    "Table",
    "Text",
    "Vector",
    "check",
    "dotted",
    "shown",
    "template_text",
    "templates",
]
