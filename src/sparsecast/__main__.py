"""``python -m sparsecast``: the same as the ``sparsecast`` command."""

from .cli import main

if __name__ == "__main__":  # not when a spawned worker (sparsecast compile --jobs) imports it
    main()
