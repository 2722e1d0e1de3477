"""The measurement log kept between runs: the readings, the readings last cleared (so Clear log
can be undone until the next reading, across a restart too) and the fit live readings use.

One JSON file, written atomically every time the log changes. Loading never raises: a file
that cannot be used is reported as a warning (and set aside as `<name>.unreadable`, so the next
save does not overwrite what a person may still want), and the log starts empty.
"""

from __future__ import annotations

import json
import logging
import math
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import platformdirs

from stereo_gui.core.errors import InputError
from stereo_gui.core.regression import FitResult, fit_from_dict, fit_to_dict
from stereo_gui.files.atomic import write_text_atomic
from stereo_gui.files.measurement_record import RULER_METHOD, MeasurementRecord
from stereo_gui.files.readers import read_user_text, set_aside

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
LOG_FILE = "measurement-log.json"
APP_NAME = "stereo-gui"


@dataclass(frozen=True)
class KeptLog:
    """What the log file holds: readings oldest first, the readings of the last Clear log
    (empty once a reading followed it) and the fit live readings use (None: triangulation)."""

    records: tuple[MeasurementRecord, ...] = ()
    cleared: tuple[MeasurementRecord, ...] = ()
    active_fit: FitResult | None = None


MAX_PIXEL = 100_000.0  # a reading's pixel beyond this is off any camera's image
MAX_SAID = 5  # warnings about single readings said at load; the rest are counted
LARGE_LOG = 20_000  # readings (with the cleared ones) beyond which a save takes about 0.5 s

def data_dir() -> Path:
    """The application's data folder: `$STEREO_GUI_DATA_DIR` when set, else the platform's."""
    env = os.environ.get("STEREO_GUI_DATA_DIR")
    if env:
        return Path(env)
    return Path(platformdirs.user_data_dir(APP_NAME, appauthor=False))


def default_log_path() -> Path:
    return data_dir() / LOG_FILE


def _record_to_json(r: MeasurementRecord) -> dict[str, object]:
    def value(v: object) -> object:
        return None if isinstance(v, float) and not math.isfinite(v) else v

    return {k: value(v) for k, v in asdict(r).items()}


_FLOAT_FIELDS = {f.name for f in fields(MeasurementRecord) if "float" in str(f.type)}
_TEXT_FIELDS = {"time", "reason", "method", "calibration_file", "note"}
_VALID_NEEDS = ("Z_mm", "range_mm")
NO_DISTANCE_KEPT = "no distance was kept for it"


def _record_from_json(doc: object, where: str,
                      warnings: list[str] | None = None) -> MeasurementRecord:
    if not isinstance(doc, dict):
        raise InputError(f"{where}: a reading is not a JSON object")
    kw: dict[str, Any] = {}  # the record's fields as JSON gave them, checked one by one
    for f in fields(MeasurementRecord):
        if f.name not in doc:
            continue
        v = doc[f.name]
        if f.name == "valid":
            if not isinstance(v, bool):
                raise InputError(f"{where}: 'valid' must be true or false, not {v!r}")
        elif f.name in _TEXT_FIELDS:
            if not isinstance(v, str):
                raise InputError(f"{where}: {f.name!r} must be text, not {v!r}")
        elif f.name == "true_mm":
            if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)
                                  or not _finite(v) or v <= 0):
                raise InputError(f"{where}: 'true_mm' must be a positive number, not "
                                 f"{v!r:.40}")
            v = None if v is None else float(v)
        elif f.name in _FLOAT_FIELDS:
            if v is None:
                v = float("nan")
            elif isinstance(v, bool) or not isinstance(v, int | float):
                raise InputError(f"{where}: {f.name!r} must be a number, not {v!r:.40}")
            try:
                v = float(v)
            except OverflowError:  # an integer such as 10**400 has no float
                raise InputError(f"{where}: {f.name!r} is an integer beyond 1e308") from None
        kw[f.name] = v
    missing = {"time", "x_px", "y_px", "disparity_px", "X_mm", "Y_mm", "Z_mm", "range_mm",
               "valid"} - set(kw)
    if missing:
        raise InputError(f"{where}: a reading lacks {', '.join(sorted(missing))}")
    # a valid reading is a distance: without one it would be listed, exported and fitted as one
    needs = ("range_mm",) if str(kw.get("method", "")).startswith(RULER_METHOD) else _VALID_NEEDS
    unknown = [k for k in needs if not math.isfinite(kw[k])] if kw["valid"] else []
    if unknown:
        kw["valid"], kw["reason"] = False, NO_DISTANCE_KEPT
        if warnings is not None:
            warnings.append(f"{where}: a reading marked valid has no {', '.join(unknown)}; it is "
                            "kept as invalid")
    elif kw["valid"] and not kw["range_mm"] > 0:
        kw["valid"], kw["reason"] = False, NO_DISTANCE_KEPT
        if warnings is not None:
            warnings.append(f"{where}: a reading marked valid has a distance of "
                            f"{kw['range_mm']:g} mm; it is kept as invalid")
    if warnings is not None and not (abs(kw["x_px"]) <= MAX_PIXEL and abs(kw["y_px"]) <= MAX_PIXEL):
        warnings.append(f"{where}: a reading at pixel ({kw['x_px']:g}, {kw['y_px']:g}) lies off "
                        "any image")
    return MeasurementRecord(**kw)


def log_to_json(kept: KeptLog) -> str:
    doc = {"format_version": FORMAT_VERSION,
           "records": [_record_to_json(r) for r in kept.records],
           "cleared": [_record_to_json(r) for r in kept.cleared],
           "active_fit": None if kept.active_fit is None else fit_to_dict(kept.active_fit)}
    return json.dumps(doc, indent=1, allow_nan=False) + "\n"


def log_from_json(text: str, where: str, warnings: list[str] | None = None) -> KeptLog:
    """The kept log in `text`; InputError naming `where` when it cannot be used. What is used
    only in part (a reading marked valid without a distance) is added to `warnings`."""
    try:
        doc = json.loads(text)
    except RecursionError:
        raise InputError(f"{where} is nested too deeply to be a measurement log") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{where} is not valid JSON: {exc}") from exc
    except ValueError:  # Python refuses integer literals of more than 4300 digits
        raise InputError(f"{where} holds an integer too long to be a number") from None
    if not isinstance(doc, dict):
        raise InputError(f"{where} does not hold a JSON object")
    version = doc.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= FORMAT_VERSION:
        raise InputError(f"{where} has format version {version!r}; this version reads "
                         f"{FORMAT_VERSION}")
    lists = []
    for key in ("records", "cleared"):
        items = doc.get(key, [])
        if not isinstance(items, list):
            raise InputError(f"{where}: {key!r} is not a list")
        lists.append(tuple(_record_from_json(d, f"{where}, {key}[{i}]", warnings)
                           for i, d in enumerate(items)))
    fit_doc = doc.get("active_fit")
    try:
        fit = None if fit_doc is None else fit_from_dict(fit_doc, f"{where}, active fit")
    except InputError as exc:
        if warnings is None:
            raise
        # the readings are worth keeping without the fit: live readings then triangulate
        warnings.append(f"{exc}; live readings use triangulation")
        fit = None
    return KeptLog(lists[0], lists[1], fit)


def save_log(kept: KeptLog, path: str | os.PathLike[str] | None = None) -> Path:
    """Write the log atomically (creating the folder); InputError if it cannot."""
    path = Path(path) if path is not None else default_log_path()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create folder {path.parent}: {exc.strerror or exc}") from exc
    return write_text_atomic(path, log_to_json(kept))


def load_log(path: str | os.PathLike[str] | None = None) -> tuple[KeptLog, list[str]]:
    """The kept log and warnings about what could not be used (never raises).

    A missing file is an empty log. A file that cannot be read or used is renamed to
    `<name>.unreadable` (numbered when one is there) and reported; a data folder that is a file
    is reported too (nothing can be kept there).
    """
    path = Path(path) if path is not None else default_log_path()
    if path.parent.exists() and not path.parent.is_dir():
        text = (f"the data folder {path.parent} is a file, not a folder: the measurement log "
                "cannot be kept between runs until it is moved away")
        log.warning("%s", text)
        return KeptLog(), [text]
    if not path.exists():
        return KeptLog(), []
    warnings: list[str] = []
    try:
        kept = log_from_json(read_user_text(path, "measurement log"), f"measurement log {path}",
                             warnings)
    except (OSError, UnicodeDecodeError, InputError) as exc:
        aside = set_aside(path)
        where = f"; it was kept as {aside.name}" if aside is not None else ""
        text = f"the measurement log could not be restored: {exc}{where}"
        log.warning("%s", text)
        return KeptLog(), [text]
    if len(warnings) > MAX_SAID:  # one line per reading would bury the window's error bar
        more = len(warnings) - MAX_SAID
        warnings = [*warnings[:MAX_SAID], f"measurement log {path}: {more} more reading(s) like "
                    "these were kept the same way"]
    n = len(kept.records) + len(kept.cleared)
    if n > LARGE_LOG:
        warnings.append(f"the measurement log {path} holds {n:,} readings; every change rewrites "
                        f"it, which takes seconds at this size: export the readings and clear "
                        "the log to keep the window quick")
    for w in warnings:
        log.warning("%s", w)
    return kept, warnings


def _finite(v: int | float) -> bool:
    """Whether a JSON number is a finite float (an integer such as 10**400 is not one)."""
    try:
        return math.isfinite(float(v))
    except OverflowError:
        return False
