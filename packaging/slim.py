"""Slimming steps for the PyInstaller bundle, used by stereo-gui.spec.

- `drop_with_private_libraries`: leave a binary (a Qt plugin) out of the bundle together with the
  shared libraries that only it needs, found from the ELF `DT_NEEDED` entries of every collected
  binary (a library another bundled binary needs stays).
- `strip_debug_sections`: `strip --strip-debug` on the bundled ELF files that carry `.debug_*`
  sections (symbol tables stay, so backtraces still name functions).

Both read ELF files with the small reader below (no pyelftools, no readelf); on Windows and macOS
there are no ELF files and both do nothing. tests/test_bundle.py uses the reader to check the
result.
"""

from __future__ import annotations

import logging
import os
import shutil
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path

# under PyInstaller's logger, so that its --log-level applies in a build
logger = logging.getLogger("PyInstaller.slim")

_SHT_DYNAMIC = 6
_DT_NULL = 0
_DT_NEEDED = 1
_SHN_XINDEX = 0xFFFF


@dataclass(frozen=True)
class ElfInfo:
    """What the bundle steps need to know of one ELF file."""

    needed: tuple[str, ...]  # DT_NEEDED sonames, in file order
    debug_bytes: int  # total size of the .debug_* / .zdebug_* sections


def read_elf(path: str | os.PathLike) -> ElfInfo | None:
    """Section facts of an ELF file, or None when the file is not ELF (or is cut short)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError:
        return None
    if len(data) < 64 or data[:4] != b"\x7fELF" or data[4] not in (1, 2) or data[5] not in (1, 2):
        return None
    is64 = data[4] == 2
    end = "<" if data[5] == 1 else ">"
    try:
        if is64:
            (_, _, _, _, _, shoff, _, _, _, _, shentsize, shnum, shstrndx) = struct.unpack_from(
                end + "HHIQQQIHHHHHH", data, 16)
            sh_fmt = end + "IIQQQQIIQQ"
            dyn_fmt = end + "qQ"
        else:
            (_, _, _, _, _, shoff, _, _, _, _, shentsize, shnum, shstrndx) = struct.unpack_from(
                end + "HHIIIIIHHHHHH", data, 16)
            sh_fmt = end + "IIIIIIIIII"
            dyn_fmt = end + "iI"
        if shoff == 0:
            return ElfInfo(needed=(), debug_bytes=0)

        def section(index: int) -> tuple[int, int, int, int, int]:
            name, kind, _, _, offset, size, link, _, _, _ = struct.unpack_from(
                sh_fmt, data, shoff + index * shentsize)
            return name, kind, offset, size, link

        if shnum == 0 or shstrndx == _SHN_XINDEX:  # large counts live in section 0
            _, _, _, size0, link0 = section(0)
            shnum = shnum or size0
            shstrndx = link0 if shstrndx == _SHN_XINDEX else shstrndx
        sections = [section(i) for i in range(shnum)]
        names_off = sections[shstrndx][2]

        def cstr(offset: int) -> str:
            stop = data.index(b"\0", offset)
            return data[offset:stop].decode("utf-8", "replace")

        debug = 0
        needed: list[str] = []
        dyn_size = struct.calcsize(dyn_fmt)
        for name, kind, offset, size, link in sections:
            if cstr(names_off + name).startswith((".debug", ".zdebug")):
                debug += size
            if kind == _SHT_DYNAMIC:
                strtab = sections[link][2]
                for pos in range(offset, offset + size - dyn_size + 1, dyn_size):
                    tag, value = struct.unpack_from(dyn_fmt, data, pos)
                    if tag == _DT_NULL:
                        break
                    if tag == _DT_NEEDED:
                        needed.append(cstr(strtab + value))
    except (struct.error, IndexError, ValueError):
        return None
    return ElfInfo(needed=tuple(needed), debug_bytes=debug)


def drop_with_private_libraries(binaries: list,
                                drop_suffixes: tuple[str, ...]) -> tuple[list, list]:
    """Leave out the binaries whose destination ends with one of `drop_suffixes` (forward
    slashes), and the collected libraries that only they need, directly or through each other.

    `binaries` is PyInstaller's Analysis.binaries: (dest_name, src_name, typecode) entries.
    Returns (the kept entries, the sorted destination names left out).
    """
    entries = {dest: (src, typecode) for dest, src, typecode in binaries}
    by_soname: dict[str, set[str]] = {}
    for dest in entries:
        by_soname.setdefault(os.path.basename(dest), set()).add(dest)

    def deps(dest: str) -> set[str]:
        src, typecode = entries[dest]
        if typecode == "SYMLINK":  # src is the link, relative to the link's own folder
            target = os.path.normpath(os.path.join(os.path.dirname(dest), src))
            return {target} if target in entries else set()
        info = read_elf(src)
        if info is None:
            return set()
        return {d for name in info.needed for d in by_soname.get(name, ())}

    graph = {dest: deps(dest) for dest in entries}

    def closure(starts) -> set[str]:
        seen: set[str] = set()
        todo = list(starts)
        while todo:
            dest = todo.pop()
            if dest not in seen:
                seen.add(dest)
                todo.extend(graph[dest])
        return seen

    roots = [d for d in entries if d.replace(os.sep, "/").endswith(drop_suffixes)]
    candidates = closure(roots)
    still_needed = closure(d for d in entries if d not in candidates)
    dropped = candidates - still_needed
    # a symbolic link to a dropped library goes with it
    dropped |= {d for d in entries if entries[d][1] == "SYMLINK" and graph[d] <= dropped
                and graph[d]}
    kept = [entry for entry in binaries if entry[0] not in dropped]
    return kept, sorted(dropped)


@dataclass(frozen=True)
class StripResult:
    files: int  # ELF files stripped
    bytes_saved: int  # the folder's size before minus after


def strip_debug_sections(folder: str | os.PathLike) -> StripResult:
    """Run `strip --strip-debug` on every regular ELF file under `folder` that has debug sections.

    Files with an `.hmac` or `.chk` companion (FIPS self-checks over the file's bytes) are left
    alone, as PyInstaller's own strip option does. Does nothing when `strip` is not installed.
    """
    strip = shutil.which("strip")
    if strip is None:
        logger.warning("strip (binutils) is not installed: the bundle keeps its debug sections")
        return StripResult(files=0, bytes_saved=0)
    files = 0
    saved = 0
    for path in sorted(Path(folder).rglob("*")):
        if path.is_symlink() or not path.is_file():
            continue
        info = read_elf(path)
        if info is None or info.debug_bytes == 0:
            continue
        if path.with_name(path.name + ".hmac").exists() or path.with_suffix(".chk").exists():
            continue
        before = path.stat().st_size
        proc = subprocess.run([strip, "--strip-debug", str(path)], capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"strip --strip-debug failed on {path}: {proc.stderr.strip()}")
        files += 1
        saved += before - path.stat().st_size
    return StripResult(files=files, bytes_saved=saved)
