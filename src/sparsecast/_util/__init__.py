"""Internal utilities at the bottom of the import graph (they import only sparsecast.errors).

``atomic``  outputs written under a temporary name and renamed when complete
``checks``  parameter validation with one error family and one message form
"""
