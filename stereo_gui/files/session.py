"""Capture sessions: a folder of calibration image pairs plus a `session.json` manifest.

Each pair is written the moment it is saved (both images, then the manifest, each atomically),
in the original capture script's naming `chessboard-L{n}.png` / `chessboard-R{n}.png`, so a
session folder is also a plain folder of pairs that `stereo-gui calibrate DIR` reads. The manifest holds the board,
the resolution, the camera identities, each pair's name, files and time, the excluded pairs, and
the cameras' controls (focus, exposure...) when the pairs were taken.

A folder without a manifest (the original script's captures, `left{n}`/`right{n}`, ...) opens too; the
manifest is written at its first change. Pairs whose images exist but which the manifest does not
list (a crash between the images and the manifest) are picked up again on opening, so nothing
saved is lost.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import os
import threading
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from stereo_gui.core.board import DEFAULT_DICTIONARY, BoardSpec
from stereo_gui.core.camera_settings import PairSettings
from stereo_gui.core.errors import InputError, StereoGuiError
from stereo_gui.files.atomic import write_bytes_atomic, write_json_atomic
from stereo_gui.files.pairs import discover_pairs

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
MANIFEST = "session.json"
LEFT_PATTERN = "chessboard-L{n}.png"
RIGHT_PATTERN = "chessboard-R{n}.png"


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="milliseconds")


def pair_name(number: int) -> str:
    """The name a session gives its pair number `number` (as discover_pairs names it too)."""
    return f"chessboard-{number}"


@dataclass(frozen=True)
class PairEntry:
    """One saved pair: its name, number, image files (absolute paths) and save time (ISO 8601)."""

    name: str
    number: int
    left: Path
    right: Path
    time: str = ""
    excluded: bool = False


@dataclass(frozen=True)
class CameraIds:
    """Which devices took the images, as the system names them (free text, may be empty)."""

    left: str = ""
    right: str = ""


def _discover(folder: Path, warnings: list[str] | None = None) -> list[PairEntry]:
    """Pairs found in the folder by their file names (stereo_gui.files.pairs)."""
    try:
        found = discover_pairs(folder)
    except StereoGuiError as exc:  # an empty folder is a fine start for a session
        log.info("no pairs discovered in %s: %s", folder, exc)
        return []
    if warnings is not None and found.warning():
        warnings.append(f"{folder}: {found.warning()}")
    return [PairEntry(p.name, p.number, Path(p.left), Path(p.right)) for p in found.pairs]


MAX_SIDE_PX = 100_000
MAX_TEXT = 4096


def _whole(v: object, field: str, lo: int = -(2**31), hi: int = 2**31) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise ValueError(f"{field} should be a whole number, not {v!r:.40}")
    if not lo <= v <= hi:
        raise ValueError(f"{field} is {v}; it must be from {lo} to {hi}")
    return v


def _number(v: object, field: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise ValueError(f"{field} should be a number, not {v!r:.40}")
    try:
        return float(v)
    except OverflowError:  # an integer such as 10**400 has no float
        raise ValueError(f"{field} should be a number of at most 1e308, not {v!r:.40}") from None


def _text(v: object, field: str, empty: bool = True) -> str:
    if not isinstance(v, str) or len(v) > MAX_TEXT or "\0" in v or (not empty and not v):
        raise ValueError(f"{field} should be {'a' if empty else 'a non-empty'} text of at most "
                         f"{MAX_TEXT} characters")
    return v


def _pair_entry(folder: Path, p: object, i: int, excluded: set[str], names: set[str],
                numbers: set[int], files: set[Path]) -> PairEntry:
    """The manifest's pairs entry `p` (number `i`), checked against those before it (their
    names, numbers and files, which this one joins); ValueError naming what is wrong."""
    if not isinstance(p, dict):
        raise ValueError(f"pairs entry {i} should be an object")
    name = _text(p.get("name"), f"pairs entry {i} name", empty=False)
    number = _whole(p.get("number"), f"pairs entry {i} number", 1, 10**9)
    if name in names:
        raise ValueError(f"pairs entry {i}: name {name!r} is listed twice")
    if number in numbers:
        raise ValueError(f"pairs entry {i}: number {number} is listed twice")
    left = _inside(folder, p.get("left"), f"pairs entry {i} ({name}) left")
    right = _inside(folder, p.get("right"), f"pairs entry {i} ({name}) right")
    if left == right or left in files or right in files:
        raise ValueError(f"pairs entry {i}: its image files are listed twice")
    time = _text(p.get("time", ""), f"pairs entry {i} time")
    names.add(name)
    numbers.add(number)
    files.update((left, right))
    return PairEntry(name, number, left, right, time, name in excluded)


def _is_inside(folder: Path, path: Path) -> bool:
    try:
        Path(path).resolve().relative_to(Path(folder).resolve())
    except (ValueError, OSError, RuntimeError):
        return False
    return True


def _inside(folder: Path, rel: object, field: str) -> Path:
    """The manifest's relative path `rel` as a path inside `folder`; ValueError for a path that
    leads out of it (an absolute path, "..", a link pointing elsewhere)."""
    rel = _text(rel, field, empty=False)
    path = folder / rel
    if Path(rel).is_absolute() or not _is_inside(folder, path) or \
            Path(path).resolve() == Path(folder).resolve():
        raise ValueError(f"{field} {rel!r} is not a file inside the session folder")
    return path


def _manifest_board(b: object) -> BoardSpec | None:
    """The manifest's `board`, or None; ValueError naming what is wrong."""
    if b is None:
        return None
    if not isinstance(b, dict):
        raise ValueError("board should be an object")
    target = b.get("target", "chessboard")
    dictionary = b.get("dictionary", DEFAULT_DICTIONARY)
    if not (isinstance(target, str) and isinstance(dictionary, str)):
        raise ValueError("board target and dictionary should be text")
    try:
        return BoardSpec(_whole(b.get("cols"), "board cols"),
                         _whole(b.get("rows"), "board rows"),
                         _number(b.get("square_mm"), "board square_mm"), target,
                         _number(b.get("marker_mm", 0.0), "board marker_mm"), dictionary)
    except InputError as exc:
        raise ValueError(f"board: {exc}") from None


def _manifest_resolution(res: object) -> tuple[int, int] | None:
    """The manifest's `resolution` [width, height], or None."""
    if res is None:
        return None
    if not isinstance(res, list) or len(res) != 2:
        raise ValueError("resolution should be [width, height]")
    return (_whole(res[0], "resolution width", 1, MAX_SIDE_PX),
            _whole(res[1], "resolution height", 1, MAX_SIDE_PX))


def _manifest_cameras(cams: object) -> CameraIds:
    if not isinstance(cams, dict):
        raise ValueError("cameras should be an object")
    return CameraIds(_text(cams.get("left", ""), "cameras left"),
                     _text(cams.get("right", ""), "cameras right"))


def _listed_pairs(folder: Path, raw_pairs: list[object], excluded: set[str],
                  warnings: list[str]) -> tuple[list[PairEntry], int]:
    """The pairs the manifest lists whose images are there, and how many entries were dropped
    as unusable; what is left out is said in `warnings`."""
    pairs: list[PairEntry] = []
    names: set[str] = set()
    numbers: set[int] = set()
    files: set[Path] = set()
    dropped = 0
    for i, p in enumerate(raw_pairs, start=1):
        # an entry that cannot be used (a file outside the folder, a number listed twice)
        # is left out alone: the other pairs and the exclusions still hold
        try:
            e = _pair_entry(folder, p, i, excluded, names, numbers, files)
        except ValueError as exc:
            dropped += 1
            warnings.append(f"{folder / MANIFEST}: {exc}; that entry is left out (the "
                            f"manifest is kept as {MANIFEST}.unreadable when the session "
                            "changes)")
            continue
        if not (e.left.is_file() and e.right.is_file()):
            warnings.append(f"{folder}: pair {e.name} is listed but its images are missing; "
                            "it is left out")
            continue
        pairs.append(e)
    return pairs, dropped


def _unlisted_pairs(folder: Path, pairs: list[PairEntry], excluded: set[str],
                    warnings: list[str]) -> list[PairEntry]:
    """Images saved but not listed (a crash before the manifest was rewritten): they are kept,
    and said in `warnings`."""
    listed = {e.left.resolve() for e in pairs} | {e.right.resolve() for e in pairs}
    found: list[PairEntry] = []
    for e in _discover(folder, warnings):
        if e.left.resolve() in listed or e.right.resolve() in listed:
            continue
        if any(p.name == e.name for p in pairs + found):
            e = replace(e, name=f"{e.name}-{e.number}")
        e = replace(e, excluded=e.name in excluded)  # exclusions are kept by name
        warnings.append(f"{folder}: pair {e.left.name}/{e.right.name} was not in the "
                        "manifest; it is added")
        found.append(e)
    return found


class CaptureSession:
    """A capture session folder. Methods that change it write through to disk at once.

    Safe to call from one worker thread while the UI reads `pairs` (a lock guards changes).
    """

    def __init__(self, folder: Path, board: BoardSpec | None, resolution: tuple[int, int] | None,
                 cameras: CameraIds, created: str, pairs: list[PairEntry],
                 has_manifest: bool, warnings: list[str] | None = None) -> None:
        self.folder = Path(folder)
        self.board = board
        self.resolution = resolution  # (width, height), px, or None when not known yet
        self.cameras = cameras
        self.created = created
        self._pairs = sorted(pairs, key=lambda e: e.number)
        self.has_manifest = has_manifest
        self.warnings = list(warnings or [])  # what opening had to tolerate
        self._unreadable_manifest = False  # an unreadable session.json is moved aside, not lost
        # the pairs' left and right images are to be exchanged when calibrating (the cameras
        # were found swapped); the saved images stay as they were taken
        self.swapped = False
        # the cameras' controls when the pairs were taken (as the source names the cameras),
        # None when not known (another program's pairs, a session before controls were kept)
        self.camera_controls: PairSettings | None = None
        self._lock = threading.RLock()

    # ---- creating and opening ---------------------------------------------------------------
    @classmethod
    def create(cls, folder: str | os.PathLike[str], board: BoardSpec | None = None,
               resolution: tuple[int, int] | None = None,
               cameras: CameraIds | tuple[str, str] | None = None) -> CaptureSession:
        """Start a session in `folder` (created if needed; pairs already there are kept)."""
        folder = Path(folder)
        if (folder / MANIFEST).exists():
            raise InputError(f"{folder} already holds a capture session; open it instead")
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(
                f"cannot create session folder {folder}: {exc.strerror or exc}") from exc
        if isinstance(cameras, tuple):
            cameras = CameraIds(*cameras)
        existing = _discover(folder)
        size = (resolution[0], resolution[1]) if resolution else None
        s = cls(folder, board, size, cameras or CameraIds(),
                _now(), existing, has_manifest=False)
        s._write_manifest()
        return s

    @classmethod
    def open(cls, folder: str | os.PathLike[str]) -> CaptureSession:
        """Open a session folder, or a plain folder of pairs (its manifest is written on change)."""
        folder = Path(folder)
        if not folder.is_dir():
            raise InputError(f"session folder {folder} does not exist")
        manifest = folder / MANIFEST
        warnings: list[str] = []
        if manifest.exists():
            problem = ""
            try:
                data = json.loads(manifest.read_text(encoding="utf-8"))
                return cls._from_manifest(folder, data)
            except RecursionError:
                problem = "nested too deeply to be a manifest"
            except (OSError, UnicodeDecodeError, ValueError, StereoGuiError) as exc:
                problem = str(exc)
            warnings.append(f"{manifest} is unreadable ({problem}); pairs found in the folder "
                            "are used, without its board and exclusions (the file is kept "
                            f"as {MANIFEST}.unreadable when the session changes)")
            log.warning("%s", warnings[-1])
        pairs = _discover(folder, warnings)
        s = cls(folder, None, None, CameraIds(), "", pairs, has_manifest=False, warnings=warnings)
        s.resolution = s._first_image_size()
        s._unreadable_manifest = manifest.exists()
        return s

    @classmethod
    def _from_manifest(cls, folder: Path, data: object) -> CaptureSession:
        """The session a parsed manifest describes; ValueError naming the field that is wrong
        (the caller then falls back to the pairs found in the folder)."""
        if not isinstance(data, dict):
            raise ValueError(f"it holds a JSON {type(data).__name__}, not an object")
        version = data.get("format_version")
        if isinstance(version, bool) or not isinstance(version, int) or not \
                1 <= version <= FORMAT_VERSION:
            raise ValueError(f"format version {version!r} is not one this version reads")
        board = _manifest_board(data.get("board"))
        resolution = _manifest_resolution(data.get("resolution"))
        cameras = _manifest_cameras(data.get("cameras") or {})
        excluded_raw = data.get("excluded", [])
        if not isinstance(excluded_raw, list):
            raise ValueError("excluded should be a list of pair names")
        excluded = {_text(x, "excluded") for x in excluded_raw}
        raw_pairs = data.get("pairs", [])
        if not isinstance(raw_pairs, list):
            raise ValueError("pairs should be a list")
        warnings: list[str] = []
        pairs, dropped = _listed_pairs(folder, raw_pairs, excluded, warnings)
        pairs += _unlisted_pairs(folder, pairs, excluded, warnings)
        for w in warnings:
            log.warning("%s", w)
        s = cls(folder, board, resolution, cameras, _text(data.get("created", ""), "created"),
                pairs, has_manifest=True, warnings=warnings)
        swapped = data.get("swapped", False)
        if not isinstance(swapped, bool):
            raise ValueError("swapped should be true or false")
        s.swapped = swapped
        controls = data.get("camera_controls")
        if controls is not None:
            try:
                s.camera_controls = PairSettings.from_json(controls, "camera_controls")
            except ValueError as exc:  # the pairs still hold: only the controls are unknown
                s.warnings.append(f"{folder / MANIFEST}: {exc}; the cameras' controls of this "
                                  "session are not known")
                log.warning("%s", s.warnings[-1])
        s._unreadable_manifest = dropped > 0  # what was left out is kept for the person
        return s

    # ---- reading ----------------------------------------------------------------------------
    @property
    def manifest_path(self) -> Path:
        return self.folder / MANIFEST

    @property
    def pairs(self) -> tuple[PairEntry, ...]:
        with self._lock:
            return tuple(self._pairs)

    def included_pairs(self) -> tuple[PairEntry, ...]:
        return tuple(p for p in self.pairs if not p.excluded)

    def pair(self, name: str) -> PairEntry:
        for p in self.pairs:
            if p.name == name:
                return p
        raise InputError(f"session {self.folder} has no pair named {name!r}")

    def _first_image_size(self) -> tuple[int, int] | None:
        for p in self._pairs:
            img = cv2.imread(str(p.left), cv2.IMREAD_UNCHANGED)
            if img is not None:
                return (int(img.shape[1]), int(img.shape[0]))
        return None

    # ---- changing ---------------------------------------------------------------------------
    def add_pair(self, left: np.ndarray, right: np.ndarray, time: str | None = None) -> PairEntry:
        """Save a pair (raw images, PNG) under the next free number and record it.

        Raises InputError (and leaves the folder as it was) when the images do not fit the
        session or cannot be written, for instance on a full disk or a vanished folder.
        """
        if left is None or right is None or left.shape[:2] != right.shape[:2]:
            raise InputError("left and right images of a pair must have the same size")
        size = (int(left.shape[1]), int(left.shape[0]))
        with self._lock:
            if self.resolution is not None and size != tuple(self.resolution):
                raise InputError(f"pair of {size[0]}x{size[1]} px does not fit session "
                                 f"{self.folder} "
                                 f"of {self.resolution[0]}x{self.resolution[1]} px")
            # encode both before writing anything, so that a bad image writes nothing
            ok_l, png_l = cv2.imencode(".png", left)
            ok_r, png_r = cv2.imencode(".png", right)
            if not (ok_l and ok_r):
                raise InputError("the images of the pair could not be encoded as PNG")
            n = max((p.number for p in self._pairs), default=0) + 1
            while True:  # never overwrite a file, even one the session does not know about
                lpath = self.folder / LEFT_PATTERN.format(n=n)
                rpath = self.folder / RIGHT_PATTERN.format(n=n)
                if not (lpath.exists() or rpath.exists()):
                    break
                n += 1
            if not self.folder.is_dir():
                raise InputError(f"session folder {self.folder} does not exist any more")
            entry = PairEntry(pair_name(n), n, lpath, rpath, time or _now())
            written: list[Path] = []
            old_resolution = self.resolution
            try:
                write_bytes_atomic(lpath, png_l.tobytes())
                written.append(lpath)
                write_bytes_atomic(rpath, png_r.tobytes())
                written.append(rpath)
                self._pairs.append(entry)
                self.resolution = size
                self._write_manifest()
            except BaseException:
                # a half-saved pair would be worse than none: undo, keep the earlier state
                if entry in self._pairs:
                    self._pairs.remove(entry)
                self.resolution = old_resolution
                for p in written:
                    p.unlink(missing_ok=True)
                raise
        log.info("saved pair %s to %s", entry.name, self.folder)
        return entry

    def delete_pair(self, name: str) -> None:
        """Delete a pair's images and forget it. Only files inside the session folder are ever
        deleted (InputError otherwise)."""
        with self._lock:
            entry = self.pair(name)
            for p in (entry.left, entry.right):
                if not _is_inside(self.folder, p):
                    raise InputError(f"pair {name}: {p} is not inside the session folder "
                                     f"{self.folder}; nothing was deleted")
            for p in (entry.left, entry.right):
                try:
                    p.unlink(missing_ok=True)
                except OSError as exc:
                    raise InputError(f"cannot delete {p}: {exc.strerror or exc}") from exc
            self._pairs.remove(entry)
            self._write_manifest()

    def set_excluded(self, name: str, excluded: bool) -> PairEntry:
        """Mark a pair as left out of (or back in) calibration; return the updated entry."""
        with self._lock:
            entry = self.pair(name)
            i = self._pairs.index(entry)
            new = replace(entry, excluded=bool(excluded))
            self._pairs[i] = new
            try:
                self._write_manifest()
            except BaseException:
                self._pairs[i] = entry
                raise
            return new

    def set_swapped(self, swapped: bool) -> None:
        """Remember that the cameras are swapped (calibrations exchange left and right)."""
        with self._lock:
            old, self.swapped = self.swapped, bool(swapped)
            try:
                self._write_manifest()
            except BaseException:
                self.swapped = old
                raise

    def set_camera_controls(self, controls: PairSettings | None) -> None:
        """Remember the cameras' controls the pairs are taken with (written at once)."""
        with self._lock:
            if controls == self.camera_controls:
                return
            old, self.camera_controls = self.camera_controls, controls
            try:
                self._write_manifest()
            except BaseException:
                self.camera_controls = old
                raise

    def calibration_controls(self) -> PairSettings | None:
        """The controls as a calibration of this session names the cameras (exchanged when
        the session says the cameras are swapped)."""
        c = self.camera_controls
        return c.swapped() if c is not None and self.swapped else c

    def set_board(self, board: BoardSpec) -> None:
        with self._lock:
            old, self.board = self.board, board
            try:
                self._write_manifest()
            except BaseException:
                self.board = old
                raise

    # ---- manifest ---------------------------------------------------------------------------
    def manifest(self) -> dict[str, Any]:
        """The manifest as written to `session.json`."""
        def rel(p: Path) -> str:
            try:
                return p.relative_to(self.folder).as_posix()
            except ValueError:
                return str(p)

        b = self.board
        return {
            "format_version": FORMAT_VERSION,
            "created": self.created or _now(),
            "board": b.to_json() if b else None,
            "resolution": list(self.resolution) if self.resolution else None,
            "cameras": {"left": self.cameras.left, "right": self.cameras.right},
            "pairs": [{"name": p.name, "number": p.number, "left": rel(p.left),
                       "right": rel(p.right), "time": p.time} for p in self._pairs],
            "excluded": [p.name for p in self._pairs if p.excluded],
            **({"swapped": True} if self.swapped else {}),
            **({"camera_controls": self.camera_controls.to_json()}
               if self.camera_controls is not None else {}),
        }

    def _unreadable_backup(self) -> Path:
        path = self.folder / f"{MANIFEST}.unreadable"
        n = 1
        while path.exists():
            n += 1
            path = self.folder / f"{MANIFEST}.unreadable-{n}"
        return path

    def _write_manifest(self) -> None:
        if self._unreadable_manifest:
            # keep what could not be read (its board and exclusions may be repaired by hand)
            # instead of replacing it with a manifest that knows none of that
            try:
                os.replace(self.manifest_path, self._unreadable_backup())
            except OSError as exc:
                raise InputError(f"cannot keep the unreadable {self.manifest_path}: "
                                 f"{exc.strerror or exc}") from exc
            self._unreadable_manifest = False
        write_json_atomic(self.manifest_path, self.manifest())
        self.has_manifest = True
