"""Tasks and their solution methods, built on a model: problem files (shipped ones as data), paths and
CAM programs, the cell, the posture NLP, compensation, timing, measurement files, identification,
placement studies and the virtual robot (``docs/architecture.md``).  Depends on :mod:`models` only."""
