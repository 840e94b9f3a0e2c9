"""``lbvh``: a linear BVH over the non-empty bricks, rebuilt in about a millisecond."""

from .build import LBVH, brick_grid_shape, vote_bricks, vote_voxels
from .traversal import LbvhRecord

__all__ = ["LBVH", "LbvhRecord", "brick_grid_shape", "vote_bricks", "vote_voxels"]
