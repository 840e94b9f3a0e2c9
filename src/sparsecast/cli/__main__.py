"""``python -m sparsecast.cli``: the same as the ``sparsecast`` command."""

from . import main

main()
