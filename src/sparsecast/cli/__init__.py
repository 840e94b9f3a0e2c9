"""The ``sparsecast`` command line: ``render``, ``info``, ``bench``, ``view``, ``render-mesh``, ``render-points``,
``compile`` and ``convert``.

:mod:`.app` holds the typer application and the entry point :func:`main`; each
command group is a module of its own that registers its command on the app when
imported here (in the order ``sparsecast --help`` lists them). :mod:`.parse` holds
every command-line value parser.
"""

from . import render, info, bench, view, mesh, points, compile, convert  # noqa: F401  (register the commands, in --help order)
from .app import app, main

__all__ = ["app", "main"]
