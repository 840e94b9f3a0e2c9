"""``python -m sparsecast``: the same as the ``sparsecast`` command."""

from .cli import main

main()
