"""The collision geometry: the arm's capsules along its chain, the shapes of the cell and the tool
(one class per kind, :mod:`models.collision.shapes`), distances and clearances.

Names load on first use (PEP 562): importing :mod:`models.collision.shapes` does not import coal.
"""

from typing import TYPE_CHECKING

from models.lazy import lazy_exports

if TYPE_CHECKING:
    from .capsules import (
        TOOL_BODY,
        TOOL_MIN_LENGTH_M,
        TOOL_SELF_MAX_BODY,
        with_tool,
        BUILTIN_ALLOWED_PAIRS,
        BUILTIN_RADII_M,
        BUILTIN_RADII_SOURCE,
        CapsuleModel,
        body_name,
        capsule_model,
        default_radii,
        self_collision_body_pairs,
        self_collision_pairs,
    )
    from .chain import capsule_points_sx, capsule_segments, chain_frames, chain_frames_sx
    from .clearance import (
        DEFAULT_CLEARANCE_M,
        Clearance,
        ClearanceStatus,
        clearance_from_distances,
        object_distances,
        self_distances,
    )
    from .distance import (
        CellShape,
        PairDistance,
        box_shape,
        capsule_shape_distance,
        cylinder_shape,
        mesh_shape,
        shape_pair_distance,
        sphere_shape,
    )
    from .scene import Scene, SceneObject
    from .segments import (
        capsule_distance,
        segment_distance,
    )

#: The submodule defining each name re-exported here (imported on first use).
_LAZY = {
    "TOOL_BODY": "capsules",
    "TOOL_MIN_LENGTH_M": "capsules",
    "TOOL_SELF_MAX_BODY": "capsules",
    "with_tool": "capsules",
    "BUILTIN_ALLOWED_PAIRS": "capsules",
    "BUILTIN_RADII_M": "capsules",
    "BUILTIN_RADII_SOURCE": "capsules",
    "CapsuleModel": "capsules",
    "body_name": "capsules",
    "capsule_model": "capsules",
    "capsule_segments": "chain",
    "capsule_points_sx": "chain",
    "chain_frames_sx": "chain",
    "Scene": "scene",
    "SceneObject": "scene",
    "chain_frames": "chain",
    "default_radii": "capsules",
    "self_collision_body_pairs": "capsules",
    "self_collision_pairs": "capsules",
    "DEFAULT_CLEARANCE_M": "clearance",
    "Clearance": "clearance",
    "ClearanceStatus": "clearance",
    "clearance_from_distances": "clearance",
    "object_distances": "clearance",
    "self_distances": "clearance",
    "CellShape": "distance",
    "PairDistance": "distance",
    "box_shape": "distance",
    "capsule_shape_distance": "distance",
    "cylinder_shape": "distance",
    "mesh_shape": "distance",
    "shape_pair_distance": "distance",
    "sphere_shape": "distance",
    "capsule_distance": "segments",
    "segment_distance": "segments",
}

__getattr__, __dir__ = lazy_exports(__name__, globals(), _LAZY)

__all__ = [
    "Scene",
    "SceneObject",
    "capsule_points_sx",
    "chain_frames_sx",
    "BUILTIN_ALLOWED_PAIRS",
    "BUILTIN_RADII_M",
    "BUILTIN_RADII_SOURCE",
    "CapsuleModel",
    "CellShape",
    "Clearance",
    "ClearanceStatus",
    "DEFAULT_CLEARANCE_M",
    "PairDistance",
    "TOOL_BODY",
    "TOOL_MIN_LENGTH_M",
    "TOOL_SELF_MAX_BODY",
    "body_name",
    "box_shape",
    "capsule_distance",
    "capsule_model",
    "capsule_segments",
    "capsule_shape_distance",
    "chain_frames",
    "clearance_from_distances",
    "cylinder_shape",
    "default_radii",
    "mesh_shape",
    "object_distances",
    "segment_distance",
    "self_collision_body_pairs",
    "self_collision_pairs",
    "self_distances",
    "shape_pair_distance",
    "sphere_shape",
    "with_tool",
]
