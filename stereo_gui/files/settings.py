"""Typed, versioned application settings stored as JSON in the platform's configuration folder.

The folder is `$STEREO_GUI_CONFIG_DIR` when set (tests set it, so they never touch the real
user's settings), else `platformdirs.user_config_dir("stereo-gui")`. Loading never raises: a
corrupt file, an unknown format version, unknown keys and wrongly typed values are reported as
warnings (and logged) and replaced by defaults, so a bad file never stops the application. What
each setting may hold is declared with its field (`core.params`), once.
"""

from __future__ import annotations

import json
import logging
import os
import re
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, TypeVar

import platformdirs

from stereo_gui.core.board import (
    MAX_BOARD_CORNERS,
    MAX_SQUARE_MM,
    MIN_SQUARE_MM,
    TARGETS,
    BoardSpec,
)
from stereo_gui.core.errors import InputError
from stereo_gui.core.lens import LENS_MODELS
from stereo_gui.core.measure import PATCH_PX
from stereo_gui.core.params import convert, describe_type, param, params_of
from stereo_gui.files.atomic import write_json_atomic
from stereo_gui.files.readers import copy_aside, read_user_text, set_aside

log = logging.getLogger(__name__)

MAX_SETTINGS_BYTES = 16 << 20  # settings are a few kB; more is not a settings file

FORMAT_VERSION = 1
SETTINGS_FILE = "settings.json"
APP_NAME = "stereo-gui"
RECENT_LIMIT = 10


# ---- what a value may be ----------------------------------------------------------------------
MAX_TEXT = 4096  # characters of a path or name; longer is a damaged file
MAX_GEOMETRY = 65536  # characters of a base64 window geometry or state
_BASE64 = re.compile(r"[A-Za-z0-9+/=]*")
_TEXT = f"text of at most {MAX_TEXT} characters"
T = TypeVar("T")


def _text_ok(v: str | None) -> bool:
    return v is None or (len(v) <= MAX_TEXT and "\0" not in v)


def _base64_ok(v: str) -> bool:
    # QByteArray.fromBase64 needs ASCII: anything else would stop the window from opening
    return len(v) <= MAX_GEOMETRY and bool(_BASE64.fullmatch(v))


def _text(default: T, help: str = "") -> T:
    # (a field as dataclasses.field is typed: as its default, so that the class's fields check)
    return param(default, check=_text_ok, check_text=_TEXT, help=help)


@dataclass(frozen=True)
class Settings:
    """Everything the application remembers between runs. Units are in the field names; each
    field's type, range and meaning are declared with it (a `Param`), and a file's value that
    does not fit them is warned about and replaced by the default."""

    source: str = _text("auto", "as --source takes it: auto, sim, cams:L,R, sbs:N, a folder or "
                                "a video")
    cameras: tuple[str, ...] = param(
        (), help="the cameras of a cams:/sbs: source by name and USB ids (CameraInfo.identity), "
                 "in the spec's order, so that one plugged in again under another index is "
                 "found again")
    resolution: tuple[int, int] = param(
        (640, 480), unit="px", check=lambda v: 0 < v[0] <= 100_000 and 0 < v[1] <= 100_000,
        check_text="two positive integers up to 100000", help="(width, height)")
    swap_lr: bool = False
    # circle grids can have 2 a side (BoardSpec checks each target's own least)
    board_cols: int = param(9, lo=2, hi=MAX_BOARD_CORNERS,
                            help="inner corners (chessboard), circles, or squares (ChArUco)")
    board_rows: int = param(6, lo=2, hi=MAX_BOARD_CORNERS)
    square_mm: float = param(25.0, lo=MIN_SQUARE_MM, hi=MAX_SQUARE_MM, unit="mm")
    board_target: str = param("chessboard", choices=TARGETS)
    marker_mm: float = param(0.0, lo=0.0, hi=MAX_SQUARE_MM, unit="mm",
                             help="ChArUco marker side / circle diameter; 0: the target's default")
    board_dictionary: str = param("DICT_4X4_50", help="ChArUco's ArUco dictionary")
    lens_model: str = param("pinhole", choices=LENS_MODELS, help="the Calibration tab's choice")
    fix_k3: bool = False
    nominal_baseline_mm: float = param(110.0, check=lambda v: 0 < v <= 1e5,
                                       check_text="a positive number up to 100000", unit="mm")
    preset: str = _text("live", "matcher preset name")
    last_calibration: str | None = _text(None, "path of the calibration loaded at start-up")
    # (last_calibration stays for other sources)
    sim_true_calibration: bool = param(
        False, help="the calibration chosen last was the simulated rig's true one: used again "
                    "whenever the rig is the source")
    last_session: str | None = _text(None, "path of the last capture session folder")
    last_export_dir: str | None = _text(None)
    recordings_dir: str | None = _text(None, "where new recordings go (None: "
                                             "~/stereo-gui-recordings)")
    window_geometry: str = param("", check=_base64_ok, check_text="base64 text",
                                 help="QMainWindow.saveGeometry() as base64")
    window_state: str = param("", check=_base64_ok, check_text="base64 text",
                              help="QMainWindow.saveState() as base64")
    recent_files: tuple[str, ...] = param(
        (), check=lambda v: len(v) <= 100 and all(map(_text_ok, v)),
        check_text="a list of at most 100 paths", help="newest first")
    colormap: str = _text("ocean")
    patch_size: int = param(PATCH_PX, lo=1, hi=101, odd=True, unit="px",
                            help="side of the square patch a click measures")
    auto_capture: bool = False
    measure_model: str = _text("triangulation", "or the name of a fitted model (\"cubic\", "
                                                "\"inverse\")")
    visible_views: tuple[str, ...] = param(
        (), check=lambda v: len(v) <= 100 and all(map(_text_ok, v)),
        check_text="a list of view names", help="live views shown; empty: the window's default")
    region_box: tuple[int, ...] = param(
        (), unit="px", check=lambda v: v == () or (len(v) == 4 and 0 <= v[0] < v[2] <= 100_000
                                                   and 0 <= v[1] < v[3] <= 100_000),
        check_text="no box, or x0, y0, x1, y1 with x0 < x1 and y0 < y1 (px)",
        help="the Live tab's watched region: its box (x0, y0, x1, y1) of the depth view, () "
             "for none")
    region_alarm_m: float = param(0.0, lo=0.0, hi=1000.0, unit="m",
                                  help="the watched region's alarm distance (0: no alarm)")
    stream_on: bool = param(False, help="the Live tab streams the depth to robots' programs "
                                        "(Foxglove WebSocket, this machine only) while it runs")
    stream_port: int = param(8765, lo=1, hi=65535,
                             help="the port the window's depth stream listens on")

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

    def with_recent(self, path: str | os.PathLike[str], limit: int = RECENT_LIMIT) -> Settings:
        """These settings with `path` first in the recent files (no duplicates, at most `limit`)."""
        p = str(path)
        recent = (p,) + tuple(r for r in self.recent_files if r != p)
        return replace(self, recent_files=recent[:limit])

    def with_updates(self, **changes: Any) -> Settings:
        # (any fields by name, each of its own type: replace refuses an unknown name)
        return replace(self, **changes)


def config_dir() -> Path:
    """The folder that holds the settings file (not created here)."""
    env = os.environ.get("STEREO_GUI_CONFIG_DIR")
    if env:
        return Path(env)
    return Path(platformdirs.user_config_dir(APP_NAME, appauthor=False))


def settings_path() -> Path:
    return config_dir() / SETTINGS_FILE


def settings_from_dict(data: dict[str, object]) -> tuple[Settings, list[str]]:
    """Settings built from a parsed settings file, with a warning for every value not used."""
    warnings: list[str] = []
    specs = params_of(Settings)
    values: dict[str, Any] = {}  # each converted to its field's type and checked below
    for key, raw in data.items():
        if key == "format_version":
            continue
        spec = specs.get(key)
        if spec is None:
            warnings.append(f"unknown setting {key!r} ignored")
            continue
        try:
            value = convert(raw, spec.type)
        except TypeError:
            warnings.append(f"setting {key!r} should be {describe_type(spec.type)}, "
                            f"found {raw!r:.40}; default used")
            continue
        if spec.problem(value) is not None:
            warnings.append(f"setting {key!r} should be {spec.wants()}, found {raw!r:.40}; "
                            "default used")
            continue
        values[key] = value
    return Settings(**values), warnings


def settings_to_dict(settings: Settings) -> dict[str, object]:
    data: dict[str, object] = {"format_version": FORMAT_VERSION}
    for key, value in asdict(settings).items():
        data[key] = list(value) if isinstance(value, tuple) else value
    return data


# ---- load and save --------------------------------------------------------------------------
def load_settings(path: str | os.PathLike[str] | None = None) -> tuple[Settings, list[str]]:
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
        text = read_user_text(path, "settings file", MAX_SETTINGS_BYTES)
        data = json.loads(text)
    except InputError as exc:  # a pipe, a device, a file too large
        warnings.append(f"{exc}; defaults used")
        return Settings(), warnings
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
                if more:  # the next save leaves those out: the file as it was is kept
                    copy = copy_aside(path)
                    if copy is not None:
                        warnings[-1] += f" (the file as it was is kept as {copy.name})"
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


def _newer(version: object) -> bool:
    return isinstance(version, int) and not isinstance(version, bool) and version > FORMAT_VERSION


def _version_on_disk(path: Path) -> object:
    """The format_version of the settings file at `path`, or None when there is none to read."""
    try:
        data = json.loads(read_user_text(path, "settings file", MAX_SETTINGS_BYTES))
    except (InputError, OSError, ValueError, RecursionError):
        return None
    return data.get("format_version") if isinstance(data, dict) else None


def save_settings(settings: Settings, path: str | os.PathLike[str] | None = None) -> Path:
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
