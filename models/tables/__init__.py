"""One reader of tables for every input format and for the run's ``summary.json``.

:mod:`models.tables.values`: :class:`TableReader`, the value kinds of the input files (numbers,
positive numbers, integers in a range, flags, strings, vectors, rows, unknown keys), bound to each
format's error class, the key path in every message. :mod:`models.tables.keys`: a table declared key by
key (:class:`~models.tables.keys.KeyTable`: each key's name, reader, default, unit; the allowed keys
and the reader follow from it). :mod:`models.tables.kinds`: the declarative
kinds of a whole document (a tree of specs: tables, lists, vectors, numbers with range and unit,
strings from a set, file names), read by :mod:`planner.summary_schema`.
"""

from models.tables.values import TableReader, is_number

__all__ = ["TableReader", "is_number"]
