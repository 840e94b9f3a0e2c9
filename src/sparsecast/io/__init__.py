"""File input and output: volumes, images (and later meshes)."""
