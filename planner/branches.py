"""What the IK branch labels mean, in words (summaries and reports).

The labels are those of the IK families of :mod:`models.ik` (``docs/conventions.md``,
"IK branches"): ``s±w±e±`` for UR-type arms, ``front|back-up|down-noflip|flip`` for OPW arms,
``b1, b2, ...`` for other 6R arms (the solver's own branches).  For UR-type arms
(:mod:`models.ik.ur`):

* shoulder: ``θ1 = ψ + asin(D/r)`` (``s+``) or ``ψ + π − asin(D/r)`` (``s−``), with
  ``ψ, r`` the polar angle and radius of the wrist centre and ``D = d2 + d3 + d4``
  the lateral offset: the two turns of the base that reach the wrist centre, about
  half a turn apart, with the arm plane (upper arm and forearm) on one side of the
  wrist centre or the other ("shoulder left/right");
* wrist: ``θ5 = +acos(c5)`` (``w+``) or ``−acos(c5)`` (``w−``): the two wrist flips;
* elbow: ``θ3 = +acos(c3)`` (``e+``) or ``−acos(c3)`` (``e−``): the two bends of the
  elbow for the same wrist centre.

Which side is left and which elbow bend is "up" depend on the signs of the DH
parameters (``a2, a3, D``) and on the shoulder branch, so :func:`posture_words`
says them from a posture itself: the side of the arm plane seen from above, the
elbow above or below the shoulder-wrist line, and ``q5``.

Pure functions; nothing prints.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

#: Meaning of each part of a label, from the closed form of :mod:`models.ik`.
BRANCH_PARTS: dict[str, dict[str, str]] = {
    "s": {
        "+": "shoulder + (θ1 = ψ + asin(D/r))",
        "-": "shoulder − (θ1 = ψ + π − asin(D/r): the base turned about half a turn from s+, the arm "
        "plane on the other side of the wrist centre)",
    },
    "w": {"+": "wrist + (θ5 = +acos(c5) > 0)", "-": "wrist − (θ5 = −acos(c5) < 0: the other wrist flip)"},
    "e": {"+": "elbow + (θ3 = +acos(c3) > 0)", "-": "elbow − (θ3 = −acos(c3) < 0: the other elbow bend)"},
}
#: One line that decodes the label format (report legends).
BRANCH_LEGEND = (
    "IK branch labels s±w±e± (models/ik/ur.py): s = shoulder, θ1 = ψ + asin(D/r) (+) or ψ + π − "
    "asin(D/r) (−): the two base turns, about half a turn apart, that put the arm plane on either "
    "side of the wrist centre (shoulder left/right); w = wrist, θ5 = ±acos(c5): the two wrist flips; "
    "e = elbow, θ3 = ±acos(c3): the two elbow bends. Which side is left and which bend is up "
    "depend on the DH signs: the 'posture' column says it for each branch at waypoint 0."
)
#: Meaning of each part of an OPW label (:mod:`models.ik.opw`).
OPW_PARTS: dict[str, str] = {
    "front": "front: wrist centre in front of axis 1",
    "back": "back: wrist centre behind axis 1 (over the top)",
    "up": "elbow up: above the shoulder-wrist line",
    "down": "elbow down: below the shoulder-wrist line",
    "noflip": "no flip: θ5 > 0",
    "flip": "flip: θ5 < 0 (the wrist turned over)",
}
#: One line that decodes the OPW label format.
OPW_LEGEND = (
    "IK branch labels front|back-up|down-noflip|flip (models/ik/opw.py), as industrial controllers "
    "name configurations: front/back = wrist centre in front of or behind axis 1; up/down = elbow "
    "above or below the shoulder-wrist line; noflip/flip = θ5 positive or negative."
)
#: One line for the branches of a general 6R arm.
GENERAL_LEGEND = (
    "IK branch labels b1, b2, ... (models/ik/general.py): the general solver's branches in its own "
    "order (EAIK subproblem decomposition); the 'posture' column says how each one looks."
)
#: Elbow within this distance (m) of the shoulder-wrist line: stretched, neither up nor down.
ELBOW_STRAIGHT_M = 1e-3
#: What the status ``no_freedom`` is: not a failure, there is nothing to optimise.
NO_FREEDOM_TEXT = "fixed orientation: the IK solution, nothing to optimise"
#: Display text of each branch status of the posture stage.
STATUS_TEXT = {
    "no_freedom": NO_FREEDOM_TEXT,
    "optimised": "optimised (NLP)",
    "degenerate": "degenerate freedom (rotation about the joint-6 axis): branch choice only",
    "analytic": "analytic posture (no NLP)",
    "collision": "set aside: its posture comes closer than the cell's clearance (the reason names the pair)",
}


def _is_ur(label: str) -> bool:
    return len(label) == 6 and label[0::2] == "swe" and all(c in "+-" for c in label[1::2])


def _is_opw(label: str) -> bool:
    return len(label.split("-")) == 3 and all(p in OPW_PARTS for p in label.split("-"))


def decode(label: str) -> str:
    """The meaning of a label such as ``"s-w-e+"`` or ``"front-up-flip"``, part by part (empty
    for an unknown label)."""
    if _is_ur(label):
        return "; ".join(BRANCH_PARTS[p][sign] for p, sign in zip(label[0::2], label[1::2]))
    if _is_opw(label):
        return "; ".join(OPW_PARTS[p] for p in label.split("-"))
    if label[:1] == "b" and label[1:].isdigit():
        return f"branch {label[1:]} of the general 6R solver"
    return ""


def legend(labels: Sequence[str]) -> str:
    """The legend line of the label format(s) in ``labels`` (UR's when none is recognised)."""
    if any(_is_opw(lab) for lab in labels):
        return OPW_LEGEND
    if labels and all(lab[:1] == "b" and lab[1:].isdigit() for lab in labels):
        return GENERAL_LEGEND
    return BRANCH_LEGEND


def short(label: str) -> str:
    """A short reading of a label: ``"s-w-e+"`` -> ``"shoulder −, wrist −, elbow +"``,
    ``"front-up-flip"`` -> ``"front, up, flip"``."""
    if _is_opw(label):
        return ", ".join(label.split("-"))
    if not _is_ur(label):
        return label
    names = {"s": "shoulder", "w": "wrist", "e": "elbow"}
    return ", ".join(f"{names[p]} {'+' if s == '+' else '−'}" for p, s in zip(label[0::2], label[1::2]))


def status_text(status: str) -> str:
    """What a branch status means (``no_freedom`` is not a failure)."""
    return STATUS_TEXT.get(status, status)


def _joint_frames(frames: Sequence[np.ndarray], convention: str, frame0: np.ndarray | None = None) -> list[np.ndarray]:
    """The frames whose origins lie on the axes of joints 1..6 and whose z is that axis.

    In standard DH frame i (i = 0: ``frame0``, default the base) carries the axis of joint
    i + 1; in modified DH frame i carries joint i.  ``frames`` holds frames 1..6 (frame i -> base).
    """
    f = [np.asarray(x, float) for x in frames]
    if convention == "modified_dh":
        return f[:6]
    return [np.eye(4) if frame0 is None else np.asarray(frame0, float)] + f[:5]


def elbow_words(frames: Sequence[np.ndarray], convention: str = "standard_dh", frame0: np.ndarray | None = None) -> str:
    """ "elbow up", "elbow down" or "elbow stretched": the elbow against the shoulder-wrist line.

    Shoulder, elbow and wrist are the points of the axes of joints 2, 3, 4 (frame origins);
    up means above the line from the shoulder to the wrist (base z).
    """
    j = _joint_frames(frames, convention, frame0)
    sh, el, wr = j[1][:3, 3], j[2][:3, 3], j[3][:3, 3]
    line = wr - sh
    n = np.linalg.norm(line)
    if n == 0.0:
        return "elbow folded onto the shoulder"
    e = line / n
    off = (el - sh) - e * float((el - sh) @ e)  # elbow offset from the line
    up = np.array([0.0, 0.0, 1.0]) - e * e[2]  # base z, across the line
    if np.linalg.norm(off) < ELBOW_STRAIGHT_M:
        return "elbow stretched"
    if np.linalg.norm(up) < 1e-6:
        return "elbow to the side (vertical shoulder-wrist line)"
    return "elbow up" if float(off @ up) > 0 else "elbow down"


def shoulder_words(
    frames: Sequence[np.ndarray], convention: str = "standard_dh", frame0: np.ndarray | None = None
) -> str:
    """ "arm plane left/right of the wrist centre": seen from above, looking from the base axis
    towards the wrist centre, the side on which the plane of the upper arm and forearm (normal:
    the joint-2 axis, through the shoulder) passes the wrist centre (joint 5 point)."""
    j = _joint_frames(frames, convention, frame0)
    n = j[1][:3, 2].copy()
    n[2] = 0.0
    w = j[4][:3, 3].copy()
    w[2] = 0.0
    if np.linalg.norm(n) < 1e-9 or np.linalg.norm(w) < 1e-9:
        return "shoulder side undefined (wrist centre on the base axis)"
    n /= np.linalg.norm(n)
    dist = float((w - j[1][:3, 3] * np.array([1.0, 1.0, 0.0])) @ n)  # wrist centre from the arm plane
    if abs(dist) < ELBOW_STRAIGHT_M:
        return "arm plane through the wrist centre"
    to_plane = -dist * n  # from the wrist centre to the arm plane
    right = np.array([w[1], -w[0], 0.0]) / np.linalg.norm(w)
    return f"arm plane {'right' if float(to_plane @ right) > 0 else 'left'} of the wrist centre"


def posture_words(
    frames: Sequence[np.ndarray],
    q: np.ndarray,
    label: str = "",
    convention: str = "standard_dh",
    frame0: np.ndarray | None = None,
) -> str:
    """How a posture looks: the side of the arm plane, elbow up/down, q5.

    Parameters
    ----------
    frames : sequence of 6 ndarray (4, 4)
        DH frames 1..6 of the posture (frame i -> base), e.g. ``KinematicModel.fk_frames``.
    q : ndarray, shape (6,)
        The posture, rad.
    label : str
        Its branch label (unused; kept for the reader of a call).
    convention : {"standard_dh", "modified_dh"}
    frame0 : ndarray (4, 4), optional
        DH frame 0 in the base frame (the robot's ``frame02base``; default the base).
    """
    return (
        f"{shoulder_words(frames, convention, frame0)}, {elbow_words(frames, convention, frame0)}, "
        f"q5 = {math.degrees(float(q[4])):.1f}°"
    )


__all__ = [
    "legend",
    "decode",
    "posture_words",
    "short",
    "status_text",
]
