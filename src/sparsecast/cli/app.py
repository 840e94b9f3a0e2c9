"""The typer application, its consoles, the option types several commands share, and
:func:`main`, the console entry point.

Commands live one group per module (:mod:`.render`, :mod:`.info`, :mod:`.bench`,
:mod:`.view`, :mod:`.mesh`, :mod:`.points`, :mod:`.compile`, :mod:`.convert`) and register themselves on :data:`app` when
:mod:`sparsecast.cli` imports them; this module imports none of them, so the
dependencies point one way only.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.text import Text

from ..errors import ParameterError, SparsecastError, TransferFunctionError

__all__ = [
    "app", "main", "out", "err", "warn", "error", "plain_console",
    "FileArg", "TfOpt", "TfRangeOpt", "ThresholdOpt", "DimsOpt", "DtypeOpt", "SpacingOpt", "CellOpt",
    "AllowOutsideOpt", "OrientationOpt", "ViewOpt", "NonFiniteOpt",
    "AzimuthOpt", "ElevationOpt", "ProjectionOpt", "ZoomOpt", "SizeOpt", "OutputOpt", "UpOpt",
]

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Fast ray casting of sparse volumes.",
)
#: Results go to stdout, warnings, progress and errors to stderr. Markup and
#: highlighting are off: messages carry file names, presets and option values as the
#: user wrote them, and rich would swallow ``[v2]`` in ``scan[v2].nrrd`` as a tag.
#: Styling goes through :class:`rich.text.Text` (see :func:`warn`, :func:`error`).
out = Console(soft_wrap=True, markup=False, highlight=False)
err = Console(stderr=True, soft_wrap=True, markup=False, highlight=False)


def plain_console(width: int) -> Console:
    """A stdout console of a fixed width that prints text as written (tables in logs)."""
    return Console(soft_wrap=True, width=width, markup=False, highlight=False)


def warn(message: str) -> None:
    """``warning: MESSAGE`` on stderr, the message verbatim."""
    err.print(Text.assemble(("warning:", "yellow"), " ", message))


def error(message: str) -> None:
    """``error: MESSAGE`` on stderr, the message verbatim."""
    err.print(Text.assemble(("error:", "red"), " ", message))

# Options shared by the commands that load and classify a volume (render, info, view).
FileArg = Annotated[
    Optional[Path],
    typer.Argument(help="Volume file (.nrrd .nhdr .nii .nii.gz .raw .npy .tif), Zarr / OME-Zarr store, or "
                        "file.h5:/dataset; omit for the built-in demo."),
]
TfOpt = Annotated[
    str, typer.Option("--tf", help="Preset name (see `sparsecast info --presets`), a TF .json file (a label "
                                   "file too), or for label volumes 'labels' (every id but 0) or 'labels:ID,ID,...'.")
]
TfRangeOpt = Annotated[Optional[str], typer.Option(help="Data range 'lo,hi' the TF spans (default: the volume's).")]
ThresholdOpt = Annotated[str, typer.Option(
    help="Colour-map presets: transparent below this fraction of the range, or 'auto': 0.1, raised above the "
         "histogram's background peak when that lies higher (a scan whose background noise is not at the bottom).")]
DimsOpt = Annotated[Optional[str], typer.Option(help="Raw files: NXxNYxNZ.")]
DtypeOpt = Annotated[Optional[str], typer.Option(help="Raw files: uint8, uint16, int16, float32, float64.")]
SpacingOpt = Annotated[Optional[str], typer.Option(help="Override voxel spacing 'sx,sy,sz'.")]
AllowOutsideOpt = Annotated[bool, typer.Option(
    "--allow-outside-data",
    help="NRRD: read a detached header's data file even when it lies outside the header's folder.")]
NonFiniteOpt = Annotated[Optional[str], typer.Option(
    "--nonfinite",
    help="NaN or Inf voxels (float data): 'raise' (the default: an error that names the file and counts them) or "
         "'replace' (NaN and -Inf by the finite minimum, +Inf by the finite maximum).")]
LazyOpt = Annotated[Optional[bool], typer.Option(
    "--lazy/--no-lazy",
    help="Keep the volume as bricks read from the file on demand (Zarr, HDF5, .npy, raw, raw NRRD). Default: "
         "lazy when it is larger than --memory-limit, or than half the memory.")]
MemoryLimitOpt = Annotated[Optional[str], typer.Option(
    help="Most memory a lazy volume's resident bricks may take, e.g. 2GB or 512MiB.")]
LevelOpt = Annotated[Optional[str], typer.Option(
    help="OME-Zarr: the resolution level, by index or path (default: the finest).")]
SchedulerOpt = Annotated[Optional[str], typer.Option(
    help="Render on the Dask cluster of this scheduler (tcp://host:8786): pieces stay on its workers across "
         "frames; files must be readable by the workers (else each piece's voxels are sent once).")]
PiecesOpt = Annotated[Optional[int], typer.Option(
    help="With --scheduler: pieces to cut the volume into (default: one per worker thread).")]
CellOpt = Annotated[Optional[int], typer.Option(help="Grid indices: voxels per macrocell edge (4, 8, 16, 32, 64).")]
OrientationOpt = Annotated[Optional[str], typer.Option(
    help="Anatomical axis codes of +i, +j, +k, e.g. RAS or LPS (default: the file's NRRD space / NIfTI "
         "sform or qform, if any).")]
ViewOpt = Annotated[Optional[str], typer.Option(
    help="Look at the patient from anterior, posterior, left, right, superior or inferior (superior up; "
         "anterior up from above or below); needs an orientation. Default anterior where the volume has one.")]

# Options shared by the commands that render an image (render, render-mesh).
AzimuthOpt = Annotated[float, typer.Option(help="Orbit azimuth in degrees.")]
ElevationOpt = Annotated[float, typer.Option(help="Orbit elevation in degrees.")]
ProjectionOpt = Annotated[str, typer.Option(help="perspective or orthographic.")]
ZoomOpt = Annotated[float, typer.Option(help="Magnification (>1 zooms in).")]
SizeOpt = Annotated[str, typer.Option(help="Image size WIDTHxHEIGHT.")]
OutputOpt = Annotated[Path, typer.Option("-o", "--output", help="Image file (.png, .jpg, .tif, or .npy).")]
UpOpt = Annotated[Optional[str], typer.Option(
    help="World axis that is up on screen: x, y, z, -x, -y or -z (default z; scanned meshes are often y-up).")]


#: Library parameters as the commands' options spell them: the library checks these values
#: and names its own parameter ("dt: expected ..."), which a command-line user did not type.
_OPTION_OF = {"dt": "--dt", "ert": "--ert", "zoom": "--zoom", "background": "--background",
              "azimuth": "--azimuth", "elevation": "--elevation", "projection": "--projection",
              "threshold": "--threshold", "value_range": "--tf-range", "width": "--size", "height": "--size",
              "brick_size": "--brick-size", "chunks": "--chunks", "clevel": "--clevel", "iso": "--iso",
              "radius": "--radius"}


def cli_message(exc: SparsecastError) -> str:
    """The error's message, with a library parameter it starts with named as its option
    (``--tf-range (value_range): expected ...``); the rest verbatim."""
    text = str(exc)
    name, sep, rest = text.partition(": ")
    # (a TF's own checks raise TransferFunctionError: value_range is --tf-range's)
    option = _OPTION_OF.get(name) if sep and isinstance(exc, (ParameterError, TransferFunctionError)) else None
    if option is None:
        return text
    return f"{option}: {rest}" if option == "--" + name.replace("_", "-") else f"{option} ({name}): {rest}"


#: said once on stderr, at a terminal, when a command starts compiling kernels
FIRST_COMPILE_NOTE = ("compiling kernels on first use (up to a minute; cached for later runs, and "
                      "`sparsecast compile` compiles them all ahead)")


#: click's UsageError as typer raises it (typer >= 0.20 vendors click as ``typer._click``,
#: older versions raise click's own): the base of the public ``typer.BadParameter``
_UsageError = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")


def _typed(args: list[str], opts: list[str]) -> list[str]:
    """The values given to an option spelt ``opts`` in ``args`` (``--x V`` or ``--x=V``)."""
    found = []
    for i, arg in enumerate(args):
        for opt in opts:
            if arg == opt and i + 1 < len(args):
                found.append(args[i + 1])
            elif arg.startswith(opt + "=") and opt.startswith("--"):
                found.append(arg[len(opt) + 1:])
    return found


def usage_message(exc: Exception, args: list[str]) -> str:
    """A command line typer could not parse (a value of the wrong type, an unknown option, a
    missing argument), as one line: the option, typer's reason, what was typed, where help is.

    typer's own report is a boxed usage block whose reason does not show the value typed
    ("Input should be a valid integer"); every other bad value gets one ``error:`` line.
    """
    text = exc.format_message()
    param = getattr(exc, "param", None)
    opts = [o for o in getattr(param, "opts", None) or [] if o.startswith("-")]
    prefix = f"Invalid value for '{opts[0]}': " if opts else None
    if prefix and text.startswith(prefix):  # a value that would not convert: name it as typed
        reason = text[len(prefix):].rstrip(".")
        typed = _typed(args, opts + [o for o in getattr(param, "secondary_opts", None) or [] if o.startswith("-")])
        shown = (repr(typed[0]) if len(typed) == 1 else repr(typed)) if typed else None
        text = f"{opts[0]}: {reason[:1].lower()}{reason[1:]}" + (f", got {shown}" if shown else "")
    command = getattr(getattr(exc, "ctx", None), "command_path", None)
    if command is None:  # (an option missing its value comes without a context)
        known = getattr(typer.main.get_command(app), "commands", {})
        command = f"sparsecast {args[0]}" if args and args[0] in known else "sparsecast"
    return f"{text} (see '{command} --help')"


def main() -> None:
    """Console entry point: bad input becomes one line on stderr and exit status 2."""
    from ..kernel_cache import announce_first_compile

    if err.is_terminal:  # a minute of silence looks like a hang; a log or a pipe gets no chatter
        announce_first_compile(lambda: err.print(Text(FIRST_COMPILE_NOTE, style="dim")))
    try:
        # not standalone: typer's usage errors come back here as exceptions, for one line
        status = app(standalone_mode=False)
    except _UsageError as exc:
        if type(exc).__name__ == "NoArgsIsHelpError":  # bare `sparsecast`: the help, as typer shows it
            if exc.format_message().strip():  # (click >= 8.2 unvendored carries the help as its message)
                out.print(exc.format_message())
        else:
            error(usage_message(exc, sys.argv[1:]))
        sys.exit(2)
    except typer.Abort:
        err.print("aborted")
        sys.exit(1)
    except SparsecastError as exc:
        error(cli_message(exc))
        sys.exit(2)
    except (FileNotFoundError, PermissionError, IsADirectoryError) as exc:
        error(str(exc))
        sys.exit(2)
    except KeyboardInterrupt:
        err.print("interrupted")
        sys.exit(130)
    # typer.Exit(code) comes back as its code; a command's own return value is no status
    if isinstance(status, int) and not isinstance(status, bool) and status:
        sys.exit(status)
