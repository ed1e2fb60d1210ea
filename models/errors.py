"""Exception types.  Every error a user can cause derives from :class:`CompplanError`;
the CLI prints its message on one line and exits non-zero, without a traceback."""

from __future__ import annotations


class CompplanError(Exception):
    """Base class of user-facing errors (bad input, infeasible task)."""


class InputError(CompplanError, ValueError):
    """Malformed or implausible input; the message names file, row/key, value, expectation."""


class UnreachableError(CompplanError):
    """A target pose has no inverse-kinematics solution; the message names the waypoint."""


class SingularityError(CompplanError):
    """A pose is (near-)singular where a regular pose is required."""


class InfeasibleError(CompplanError):
    """A planning problem has no solution under its constraints (status and reason attached)."""


class PluginError(CompplanError, TypeError):
    """A plug-in (effect, IK family, timing method, export format) is declared wrongly: no name,
    registered twice, a clash with another plug-in's names, a missing hook; the message names the
    plug-in and what it lacks.  A ``TypeError`` too, as before it had its own class."""
