"""Typed, versioned application settings stored as JSON in the platform's configuration folder.

The folder is `$STEREO_GUI_CONFIG_DIR` when set (tests set it, so they never touch the real
user's settings), else `platformdirs.user_config_dir("stereo-gui")`. Loading never raises: a
corrupt file, an unknown format version, unknown keys and wrongly typed values are reported as
warnings (and logged) and replaced by defaults, so a bad file never stops the application.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import types
import typing
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

from stereo_gui.core.board import (
    MAX_BOARD_CORNERS,
    MAX_SQUARE_MM,
    MIN_SQUARE_MM,
    BoardSpec,
)
from stereo_gui.core.errors import InputError
from stereo_gui.core.measure import PATCH_PX
from stereo_gui.files.atomic import write_json_atomic
from stereo_gui.files.readers import set_aside

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
SETTINGS_FILE = "settings.json"
APP_NAME = "stereo-gui"
RECENT_LIMIT = 10


@dataclass(frozen=True)
class Settings:
    """Everything the application remembers between runs. Units are in the field names."""

    source: str = "auto"  # as --source takes it: auto, sim, cams:L,R, sbs:N, a folder or a video
    # the cameras of a cams:/sbs: source by name and USB ids (CameraInfo.identity), in the
    # spec's order, so that one plugged in again under another index is found again
    cameras: tuple[str, ...] = ()
    resolution: tuple[int, int] = (640, 480)  # (width, height), px
    swap_lr: bool = False
    board_cols: int = 9  # inner corners (chessboard), circles, or squares (ChArUco)
    board_rows: int = 6
    square_mm: float = 25.0
    board_target: str = "chessboard"  # core.board.TARGETS
    marker_mm: float = 0.0  # ChArUco marker side / circle diameter; 0: the target's default
    board_dictionary: str = "DICT_4X4_50"  # ChArUco's ArUco dictionary
    lens_model: str = "pinhole"  # core.lens.LENS_MODELS, the Calibration tab's choice
    fix_k3: bool = False
    nominal_baseline_mm: float = 110.0
    preset: str = "live"  # matcher preset name
    last_calibration: str | None = None  # path of the calibration loaded at start-up
    # the calibration chosen last was the simulated rig's true one: used again whenever the rig
    # is the source (last_calibration stays for other sources)
    sim_true_calibration: bool = False
    last_session: str | None = None  # path of the last capture session folder
    last_export_dir: str | None = None
    recordings_dir: str | None = None  # where new recordings go (None: ~/stereo-gui-recordings)
    window_geometry: str = ""  # QMainWindow.saveGeometry() as base64
    window_state: str = ""  # QMainWindow.saveState() as base64
    recent_files: tuple[str, ...] = ()  # newest first
    colormap: str = "ocean"
    patch_size: int = PATCH_PX  # side of the square patch a click measures, px (odd)
    auto_capture: bool = False
    measure_model: str = "triangulation"  # or the name of a fitted model ("cubic", "inverse")
    visible_views: tuple[str, ...] = ()  # live views shown; empty means the window's default
    # the Live tab's watched region: its box (x0, y0, x1, y1) px of the depth view, () for none,
    # and its alarm distance (0: no alarm)
    region_box: tuple[int, ...] = ()
    region_alarm_m: float = 0.0

    @property
    def board(self) -> BoardSpec:
        """The target these settings describe (a chessboard of the same size when the target
        fields do not make a valid one)."""
        try:
            return BoardSpec(self.board_cols, self.board_rows, self.square_mm, self.board_target,
                             self.marker_mm, self.board_dictionary)
        except InputError as exc:
            log.warning("settings: %s; using a chessboard", exc)
            return BoardSpec(self.board_cols, self.board_rows, self.square_mm)

    def with_board(self, board: BoardSpec) -> Settings:
        return replace(self, board_cols=board.cols, board_rows=board.rows,
                       square_mm=board.square_mm, board_target=board.target,
                       marker_mm=board.marker_mm, board_dictionary=board.dictionary)

    def with_recent(self, path: str | os.PathLike, limit: int = RECENT_LIMIT) -> Settings:
        """These settings with `path` first in the recent files (no duplicates, at most `limit`)."""
        p = str(path)
        recent = (p,) + tuple(r for r in self.recent_files if r != p)
        return replace(self, recent_files=recent[:limit])

    def with_updates(self, **changes) -> Settings:
        return replace(self, **changes)


def config_dir() -> Path:
    """The folder that holds the settings file (not created here)."""
    env = os.environ.get("STEREO_GUI_CONFIG_DIR")
    if env:
        return Path(env)
    import platformdirs

    return Path(platformdirs.user_config_dir(APP_NAME, appauthor=False))


def settings_path() -> Path:
    return config_dir() / SETTINGS_FILE


# ---- validation -----------------------------------------------------------------------------
# extra checks on values that have the right type; a failing check is reported like a bad type
MAX_TEXT = 4096  # characters of a path or name; longer is a damaged file
MAX_GEOMETRY = 65536  # characters of a base64 window geometry or state
_BASE64 = re.compile(r"[A-Za-z0-9+/=]*")


def _text_ok(v) -> bool:
    return v is None or (len(v) <= MAX_TEXT and "\0" not in v)


_CHECKS: dict[str, tuple[typing.Callable[[object], bool], str]] = {
    "resolution": (lambda v: 0 < v[0] <= 100_000 and 0 < v[1] <= 100_000,
                   "two positive integers up to 100000"),
    # circle grids can have 2 a side (BoardSpec checks each target's own least)
    "board_cols": (lambda v: 2 <= v <= MAX_BOARD_CORNERS,
                   f"an integer from 2 to {MAX_BOARD_CORNERS}"),
    "board_rows": (lambda v: 2 <= v <= MAX_BOARD_CORNERS,
                   f"an integer from 2 to {MAX_BOARD_CORNERS}"),
    "board_target": (lambda v: v in ("chessboard", "circles", "acircles", "charuco"),
                     "chessboard, circles, acircles or charuco"),
    "marker_mm": (lambda v: math.isfinite(v) and 0 <= v <= MAX_SQUARE_MM,
                  f"a number of millimetres from 0 to {MAX_SQUARE_MM:g}"),
    "lens_model": (lambda v: v in ("pinhole", "rational", "fisheye"), "pinhole, rational or fisheye"),
    "square_mm": (lambda v: MIN_SQUARE_MM <= v <= MAX_SQUARE_MM,
                  f"a number of millimetres from {MIN_SQUARE_MM:g} to {MAX_SQUARE_MM:g}"),
    "nominal_baseline_mm": (lambda v: math.isfinite(v) and 0 < v <= 1e5,
                            "a positive number up to 100000"),
    "patch_size": (lambda v: 1 <= v <= 101 and v % 2 == 1, "an odd integer from 1 to 101"),
    # QByteArray.fromBase64 needs ASCII: anything else would stop the window from opening
    "window_geometry": (lambda v: len(v) <= MAX_GEOMETRY and bool(_BASE64.fullmatch(v)),
                        "base64 text"),
    "window_state": (lambda v: len(v) <= MAX_GEOMETRY and bool(_BASE64.fullmatch(v)),
                     "base64 text"),
    "recent_files": (lambda v: len(v) <= 100 and all(map(_text_ok, v)),
                     "a list of at most 100 paths"),
    "visible_views": (lambda v: len(v) <= 100 and all(map(_text_ok, v)),
                      "a list of view names"),
    "region_box": (lambda v: v == () or (len(v) == 4 and 0 <= v[0] < v[2] <= 100_000
                                         and 0 <= v[1] < v[3] <= 100_000),
                   "no box, or x0, y0, x1, y1 with x0 < x1 and y0 < y1 (px)"),
    "region_alarm_m": (lambda v: math.isfinite(v) and 0 <= v <= 1000, "metres from 0 to 1000"),
}
for _key in ("source", "preset", "last_calibration", "last_session", "last_export_dir",
             "recordings_dir", "colormap", "measure_model"):
    _CHECKS[_key] = (_text_ok, f"text of at most {MAX_TEXT} characters")


def _convert(value, tp):
    """`value` (parsed JSON) converted to type `tp`, or raise TypeError."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return None
        for a in args:
            if a is type(None):
                continue
            try:
                return _convert(value, a)
            except TypeError:
                pass
        raise TypeError
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, list | tuple):
            raise TypeError
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(v, args[0]) for v in value)
        if len(value) != len(args):
            raise TypeError
        return tuple(_convert(v, a) for v, a in zip(value, args, strict=True))
    if tp is bool:
        if not isinstance(value, bool):
            raise TypeError
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeError
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise TypeError
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise TypeError
        return value
    raise TypeError


def _describe(tp) -> str:
    return str(tp).replace("typing.", "").replace("<class '", "").replace("'>", "")


def settings_from_dict(data: dict) -> tuple[Settings, list[str]]:
    """Settings built from a parsed settings file, with a warning for every value not used."""
    warnings: list[str] = []
    hints = typing.get_type_hints(Settings)
    known = {f.name for f in fields(Settings)}
    values: dict[str, object] = {}
    for key, raw in data.items():
        if key == "format_version":
            continue
        if key not in known:
            warnings.append(f"unknown setting {key!r} ignored")
            continue
        try:
            value = _convert(raw, hints[key])
        except TypeError:
            warnings.append(f"setting {key!r} should be {_describe(hints[key])}, "
                            f"found {raw!r}; default used")
            continue
        check = _CHECKS.get(key)
        if check and not check[0](value):
            warnings.append(f"setting {key!r} should be {check[1]}, found {raw!r}; default used")
            continue
        values[key] = value
    return Settings(**values), warnings


def settings_to_dict(settings: Settings) -> dict:
    data = {"format_version": FORMAT_VERSION}
    for key, value in asdict(settings).items():
        data[key] = list(value) if isinstance(value, tuple) else value
    return data


# ---- load and save --------------------------------------------------------------------------
def load_settings(path: str | os.PathLike | None = None) -> tuple[Settings, list[str]]:
    """Read the settings; return them with warnings about whatever had to be ignored.

    Never raises for a bad file: a missing file gives the defaults silently, anything else
    unusable gives the defaults (or the usable part) and a warning. A file that cannot be read
    at all is set aside as `settings.json.unreadable` (one of a newer version stays as it is).
    """
    path = Path(path) if path is not None else settings_path()
    warnings: list[str] = []
    if path.parent.exists() and not path.parent.is_dir():
        warnings.append(f"the settings folder {path.parent} is a file, not a folder: settings "
                        "and presets cannot be kept until it is moved away")
        log.warning("%s", warnings[-1])
    if not path.exists():
        return Settings(), warnings
    try:
        text = path.read_text(encoding="utf-8")
        data = json.loads(text)
    except RecursionError:
        warnings.append(f"settings file {path} is nested too deeply to be settings; "
                        "defaults used")
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        warnings.append(f"settings file {path} could not be read ({exc}); defaults used")
    except ValueError:  # Python refuses integer literals of more than 4300 digits
        warnings.append(f"settings file {path} holds an integer too long to be a number; "
                        "defaults used")
    else:
        if not isinstance(data, dict):
            warnings.append(f"settings file {path} does not hold a JSON object; defaults used")
        else:
            version = data.get("format_version")
            if _newer(version):
                warnings.append(f"settings file {path} has format version {version}, from a "
                                "newer version of stereo-gui; defaults used, and the file is "
                                "left as it is")
            elif version != FORMAT_VERSION or isinstance(version, bool):
                warnings.append(f"settings file {path} has format version {version!r}, "
                                f"this version reads {FORMAT_VERSION}; defaults used")
            else:
                settings, more = settings_from_dict(data)
                warnings.extend(f"{path}: {w}" for w in more)
                for w in warnings:
                    log.warning("%s", w)
                return settings, warnings
    if warnings and not _newer(_version_on_disk(path)):
        # what could not be read is kept for the person, and the next save writes a new file
        aside = set_aside(path)
        if aside is not None:
            warnings[-1] += f"; the file was kept as {aside.name}"
    for w in warnings:
        log.warning("%s", w)
    return Settings(), warnings


def _newer(version) -> bool:
    return isinstance(version, int) and not isinstance(version, bool) and version > FORMAT_VERSION


def _version_on_disk(path: Path):
    """The format_version of the settings file at `path`, or None when there is none to read."""
    try:
        if path.stat().st_size > 16 << 20:
            return None
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    return data.get("format_version") if isinstance(data, dict) else None


def save_settings(settings: Settings, path: str | os.PathLike | None = None) -> Path:
    """Write the settings atomically (creating the folder); raise InputError if it cannot.

    A settings file written by a newer version of the application is never replaced (the newer
    version's settings would be lost to this version's defaults): InputError says so.
    """
    path = Path(path) if path is not None else settings_path()
    version = _version_on_disk(path)
    if _newer(version):
        raise InputError(f"settings not saved: {path} belongs to a newer version of stereo-gui "
                         f"(format {version}) and is left as it is")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(
            f"cannot create settings folder {path.parent}: {exc.strerror or exc}") from exc
    return write_json_atomic(path, settings_to_dict(settings))
