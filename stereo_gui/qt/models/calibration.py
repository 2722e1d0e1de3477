"""The calibration model: the calibration in use, where it came from, and its files."""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol, TypeVar

from PySide6.QtCore import QObject, Signal

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.any_calibration import load_any_calibration
from stereo_gui.files.calibration_file import export_ros, import_ros, save_calibration
from stereo_gui.files.kalibr_calibration import write_kalibr_camchain
from stereo_gui.qt.models.settings import SettingsModel

log = logging.getLogger(__name__)

T = TypeVar("T")  # what an export returns

# the note of the simulated rig's true calibration (the status bar and the Live tab show it)
TRUE_CALIBRATION_NOTE = "simulated rig's TRUE calibration"


class Reporter(Protocol):
    """Where a model reports to the user (the application context)."""

    def report_error(self, text: str) -> None: ...

    def show_status(self, text: str) -> None: ...


def order_left_right(files: Sequence[str]) -> tuple[str, str]:
    """(left, right) of two chosen files: by "left"/"right" in the names, else in name order."""
    a, b = sorted(files, key=lambda f: Path(f).name)
    na, nb = Path(a).name.lower(), Path(b).name.lower()
    if "right" in na and "right" not in nb or "left" in nb and "left" not in na:
        return b, a
    return a, b


class CalibrationModel(QObject):
    """The calibration used from now on (`calibration`, None for none), the file it came from
    (`path`) or, for one never saved, a note saying where it came from (`note`).

    Changed only by `set` and the file methods; each change is announced once by `changed`.
    Files are read and written here so that every place that opens one behaves the same, and
    the settings remember what the next start should load.
    """

    changed = Signal(object)  # StereoCalibration | None (object: None is emitted too)

    def __init__(self, settings: SettingsModel, report: Reporter,
                 frame_size: Callable[[], tuple[int, int]],
                 parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._settings = settings
        self._report = report
        self._frame_size = frame_size  # (width, height) px for a file that states no size
        self._calibration: StereoCalibration | None = None
        self._path: Path | None = None
        self._note = ""

    @property
    def calibration(self) -> StereoCalibration | None:
        return self._calibration

    @property
    def path(self) -> Path | None:
        return self._path

    @property
    def note(self) -> str:
        return self._note

    def set(self, calib: StereoCalibration | None, path: str | Path | None = None,
            note: str = "", remember: bool = True) -> None:
        """Use `calib` (or None) from now on; `path` is the file it came from, if any.

        `note` says where an unsaved calibration came from (e.g. TRUE_CALIBRATION_NOTE); the
        status bar shows it instead of a file name. Whether it is the simulated rig's true
        calibration is remembered for the next start (`Settings.sim_true_calibration`) unless
        `remember` is False (the start itself restoring the last one).
        """
        self._calibration = calib
        self._path = Path(path) if path is not None else None
        self._note = note
        true = calib is not None and note == TRUE_CALIBRATION_NOTE
        if remember and self._settings.current.sim_true_calibration != true:
            self._settings.update(sim_true_calibration=true)
        self.changed.emit(calib)

    def open_file(self, path: str | Path) -> bool:
        """Load the calibration file `path` (ours, OpenCV's, ROS's or Middlebury's: see
        files.any_calibration), use it and remember it for the next start; False (after
        reporting why) when it cannot be read. A file without an image size takes the size of
        the frames shown."""
        try:
            loaded = load_any_calibration(path, self._frame_size)
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"Cannot load calibration {path}: {exc}")
            return False
        self._use_file(loaded.calibration, path)
        extra = "" if loaded.kind == "stereo-gui" else f" ({loaded.description})"
        self._report.show_status(f"Loaded calibration {path}{extra}")
        return True

    def save_file(self, calib: StereoCalibration, path: str | Path) -> bool:
        """Write `calib` to `path`, use it from there and remember it for the next start; False
        (after reporting why) when it cannot be written."""
        try:
            save_calibration(calib, path)
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"Cannot save calibration {path}: {exc}")
            return False
        self._use_file(calib, path)
        self._report.show_status(f"Saved calibration {path}")
        return True

    def export_ros(self, folder: str | Path) -> tuple[Path, Path] | None:
        """Write the calibration as ROS camera_info left.yaml and right.yaml into `folder`;
        both paths, or None (after reporting why)."""
        paths = self._export(lambda c: export_ros(c, folder),
                             f"Cannot export ROS camera_info into {folder}")
        if paths is not None:
            hartley = self._calibration is not None and not self._calibration.metric
            extra = " (Hartley calibration: the baseline is not metric)" if hartley else ""
            self._report.show_status(f"Exported ROS camera_info {paths[0].name} and "
                                     f"{paths[1].name} into {folder}{extra}")
        return paths

    def export_kalibr(self, path: str | Path) -> Path | None:
        """Write the calibration as a Kalibr camchain.yaml; its path, or None (after reporting
        why: no calibration, or lenses Kalibr has no model for)."""
        done = self._export(lambda c: write_kalibr_camchain(path, c),
                            f"Cannot export a Kalibr camchain to {path}")
        if done is not None:
            self._report.show_status(f"Exported the Kalibr camchain {done}")
        return done

    def _export(self, write: Callable[[StereoCalibration], T], failed: str) -> T | None:
        """`write(calibration)`'s result, or None after saying why (no calibration; `failed`
        and the reason)."""
        if self._calibration is None:
            self._report.report_error(
                "There is no calibration to export: calibrate or open one first.")
            return None
        try:
            return write(self._calibration)
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"{failed}: {exc}")
            return None

    def import_ros(self, left: str | Path, right: str | Path) -> bool:
        """Use the calibration of a ROS camera_info pair (not saved: the note names the two
        files); False (after reporting why) when they cannot be read."""
        try:
            calib = import_ros(left, right)
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"Cannot import ROS camera_info {left} + {right}: {exc}")
            return False
        self.set(calib, None, note=f"ROS {Path(left).name} + {Path(right).name}")
        self._report.show_status(
            f"Imported ROS camera_info {left} + {right}: baseline {calib.baseline_mm:.1f} mm, "
            f"{calib.width}x{calib.height} px (save it with File > Save calibration as…)")
        return True

    def _use_file(self, calib: StereoCalibration, path: str | Path) -> None:
        self.set(calib, path)
        self._settings.remember_recent(str(path), last_calibration=str(Path(path).resolve()))
