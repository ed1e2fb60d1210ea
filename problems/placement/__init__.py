"""Base-placement studies: where to put the robot for a task (``docs/placement.md``).

:mod:`~problems.placement.grid` (candidate placements and their transforms),
:mod:`~problems.placement.kernel` (the per-pose kernel: one chunk of placements -> scores),
:mod:`~problems.placement.scores` (statuses, scores, ranking),
:mod:`~problems.placement.sweep` (chunks, serial or on a Dask cluster),
:mod:`~problems.placement.sweep_status` (a sweep's outcome and progress stage),
:mod:`~problems.placement.cluster` (the Dask side), and
:mod:`~problems.placement.placed` (a problem moved to a placement, for a full plan).
"""
