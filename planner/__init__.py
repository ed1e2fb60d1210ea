"""The pipeline and the ``compplan`` command line.  Depends on :mod:`problems` and :mod:`models`."""
