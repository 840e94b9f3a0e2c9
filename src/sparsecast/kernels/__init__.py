"""Small ``@njit`` building blocks shared by every renderer and index.

Kernels take arrays and scalars only (no Python objects) so that a CUDA backend can
mirror them later. Modules:

``bricks``     per-brick min/max with a one-voxel apron
``ray``        ray/box clipping and the global sampling lattice
``sample``     trilinear interpolation and central-difference gradients
``shade``      transfer-function lookup, Blinn-Phong shading, front-to-back compositing
``march``      marching one lattice segment (used by the naive and every ESS renderer)
``camera``     pixel -> ray generation
"""
