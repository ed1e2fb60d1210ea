"""The arm's collision geometry (capsules along the links), distances and clearances.

Foundation of issue 25 (``docs/cell.md``): not yet wired into problem files or planning.
"""

from .capsules import (
    BUILTIN_ALLOWED_PAIRS,
    BUILTIN_RADII_M,
    BUILTIN_RADII_SOURCE,
    CapsuleModel,
    body_name,
    capsule_model,
    capsule_segments,
    chain_frames,
    default_radii,
    self_collision_body_pairs,
    self_collision_pairs,
)
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
    capsule_distance,
    capsule_shape_distance,
    cylinder_shape,
    mesh_shape,
    segment_distance,
    shape_pair_distance,
    sphere_shape,
)

__all__ = [
    "BUILTIN_ALLOWED_PAIRS",
    "BUILTIN_RADII_M",
    "BUILTIN_RADII_SOURCE",
    "DEFAULT_CLEARANCE_M",
    "CapsuleModel",
    "CellShape",
    "Clearance",
    "ClearanceStatus",
    "PairDistance",
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
]
