"""Collision shapes, one module per kind, each a registered :class:`~.base.Shape`.

:mod:`.box`, :mod:`.cylinder`, :mod:`.sphere` and :mod:`.mesh` are imported here, and so is every
module in the folders named by ``$COMPPLAN_SHAPE_PATH`` (``os.pathsep``-separated), as
``models.collision.shapes.<name>`` (:func:`models.plugins.import_plugins`): a new kind of shape is
one module that subclasses :class:`~.base.Shape` and decorates it ``@register_shape``; problem
files (``[[cell.objects]]``, ``[[robot.tool.body]]``), the posture NLP, the plan's check, the
placement kernel, the summary and the report pick it up (``docs/cell.md``, "Adding a shape kind").
Neither coal nor trimesh is imported until a shape is built or measured.
"""

from models.plugins import import_plugins

from .base import (
    NORM_EPS_M,
    OUTLINE_CIRCLE_POINTS,
    SHAPE_KEYS,
    Shape,
    box_signed_distance,
    excess_distance_sx,
    outline_ring,
    register_shape,
    shape_class,
    shape_kinds,
    shape_to_dict,
)
from .segment_box import segment_box_distance

#: Extra folders searched for shape modules (``os.pathsep``-separated).
SHAPE_PATH_VARIABLE = "COMPPLAN_SHAPE_PATH"
import_plugins(
    __name__, __path__, SHAPE_PATH_VARIABLE, skip=("base", "segment_box"), first=("box", "cylinder", "sphere", "mesh")
)

__all__ = [
    "NORM_EPS_M",
    "OUTLINE_CIRCLE_POINTS",
    "SHAPE_KEYS",
    "Shape",
    "box_signed_distance",
    "excess_distance_sx",
    "outline_ring",
    "register_shape",
    "segment_box_distance",
    "shape_class",
    "shape_kinds",
    "shape_to_dict",
]
