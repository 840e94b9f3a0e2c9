"""Names for the compiled kernels in a ``perf`` profile: a ``/tmp/perf-PID.map``.

Linux ``perf`` shows Numba's machine code as bare addresses ("[JIT]"): nothing on
disk names it. A perf map is the JIT convention for that (one ``START SIZE NAME``
line per function, in hex); this module writes one from the functions this
process compiled. The symbols come from each code library's object file (its ELF
symbol table, read with pyelftools), so functions that LLVM kept apart but that
no dispatcher exports (a plain ``@njit`` callee linked into its caller's library,
an overload's ``impl``) are named too. A library loaded from Numba's disk cache
keeps no object file, so profile with an empty kernel cache (compiling takes
seconds to minutes)::

    SPARSECAST_CACHE_DIR=$(mktemp -d) perf record -o perf.data \\
        python -c "import sparsecast.bench.perfmap as p; p.write_at_exit(); ..."
    perf report -i perf.data --no-children --sort sym

How the driver's reference counting was found (kernels.borrow, NO_REFCOUNT): 6 %
of a k-d tree isosurface frame in ``NRT_incref`` / ``NRT_decref``, a symbol this
map names (the runtime's own library is in it as well).
"""

from __future__ import annotations

import atexit
import gc
import io
import os
from pathlib import Path

__all__ = ["jit_symbols", "write_perf_map", "write_at_exit"]


def _library_symbols(library) -> list[tuple[int, int, str]]:
    """``(address, size, name)`` of the functions in one Numba code library."""
    from elftools.elf.elffile import ELFFile

    try:
        blob = library._get_compiled_object()  # only a library compiled in this process has one
    except Exception:  # noqa: BLE001 - loaded from the disk cache, or not finalized
        return []
    elf = ELFFile(io.BytesIO(blob))
    syms = []
    for section in elf.iter_sections():
        if section.header.sh_type != "SHT_SYMTAB":
            continue
        for s in section.iter_symbols():
            if s["st_info"]["type"] == "STT_FUNC" and s["st_shndx"] != "SHN_UNDEF" and s["st_size"]:
                syms.append((s.name, s["st_value"], s["st_size"], s["st_shndx"], s["st_info"]["bind"]))
    # A section's load address from one of its exported functions: the others of
    # that section sit at the same offsets from it as in the object file.
    base: dict = {}
    for name, offset, _, section, bind in syms:
        if section in base or bind != "STB_GLOBAL":
            continue
        try:
            address = library.get_pointer_to_function(name)
        except Exception:  # noqa: BLE001 - a symbol the engine does not export
            address = 0
        if address:
            base[section] = address - offset
    return [(base[sec] + off, size, name) for name, off, size, sec, _ in syms if sec in base]


def _runtime_symbols(library) -> list[tuple[int, int, str]]:
    """The Numba runtime's functions (``NRT_incref`` ...): its library keeps no object
    file, so each is named from its address up to the next one's (at most 4 KiB)."""
    try:
        names = [f.name for f in library._final_module.functions if not f.is_declaration]
    except Exception:  # noqa: BLE001 - Numba's internals moved
        return []
    found = []
    for name in names:
        try:
            address = library.get_pointer_to_function(name)
        except Exception:  # noqa: BLE001
            address = 0
        if address:
            found.append((address, name))
    found.sort()
    ends = [a for a, _ in found[1:]] + [found[-1][0] + 64] if found else []
    return [(a, min(end - a, 4096), name) for (a, name), end in zip(found, ends) if end > a]


def jit_symbols() -> list[tuple[int, int, str]]:
    """``(address, size, name)`` of every function compiled in this process, sorted by
    address: each dispatcher's code libraries, and the Numba runtime's."""
    from numba.core.registry import CPUDispatcher
    from numba.core.runtime import rtsys

    libraries = {}
    for obj in gc.get_objects():
        # by the object's own type: isinstance would follow a dead weakref.proxy and raise
        if issubclass(type(obj), CPUDispatcher):
            for cres in list(obj.overloads.values()):
                libraries[id(cres.library)] = cres.library
    rows = set()
    for library in libraries.values():
        rows.update(_library_symbols(library))
    runtime = getattr(rtsys, "_library", None)
    if runtime is not None:
        rows.update(_runtime_symbols(runtime))
    return sorted(rows)


def write_perf_map(path: str | os.PathLike | None = None) -> Path:
    """Write the perf map of :func:`jit_symbols` (default ``/tmp/perf-<pid>.map``, where
    ``perf report`` looks) and return its path."""
    target = Path(path) if path is not None else Path(f"/tmp/perf-{os.getpid()}.map")
    text = "".join(f"{address:x} {size:x} {name}\n" for address, size, name in jit_symbols())
    tmp = target.with_name(target.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, target)
    return target


def write_at_exit() -> None:
    """Write the perf map when the process exits (after everything profiled compiled)."""
    atexit.register(write_perf_map)
