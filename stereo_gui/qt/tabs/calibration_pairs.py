"""The Calibration tab's review of single pairs: each pair shown rectified with its detected and
reprojected corners, the pairs excluded (by hand or above an error threshold) and the list of
rejected and excluded pairs, kept in the capture session so that Recalibrate leaves them out.

`PairReview` is owned by `calibration.CalibrationTab` and is handed what it uses: the calibration
model (the calibration shown is the one in use), the tab's last run, the session
(`SessionFolder`), where to report, the worker registry and whether a calibration is running. It
makes the widgets of the review, which the tab places. A pair is read and rectified on its own
pair-view thread, never on the UI thread.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
from PySide6.QtCore import QObject, Qt
from PySide6.QtWidgets import (
    QDoubleSpinBox,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QWidget,
)

from stereo_gui.core.errors import InputError, StereoGuiError
from stereo_gui.core.stereo_calibration import RectifyMaps, StereoCalibration
from stereo_gui.files.session import CaptureSession, PairEntry
from stereo_gui.pipeline.calibration import CalibrationRun, read_image
from stereo_gui.qt.models.calibration import CalibrationModel, Reporter
from stereo_gui.qt.models.workers import WorkerRegistry
from stereo_gui.qt.widgets.calibration_charts import (
    ErrorBarChart,
    RectifiedPairView,
    error_scale,
)
from stereo_gui.qt.workers.job_runner import JobRunner


class SessionFolder:
    """The capture session the Calibration tab works on: the folder of its last run, else the
    Pairs folder typed. Opened again at each use (the Capture tab may have changed it)."""

    def __init__(self, folder: Callable[[], Path | None]) -> None:
        self._folder = folder  # None: no run and no Pairs folder named

    def named(self) -> bool:
        return self._folder() is not None

    def open(self) -> CaptureSession:
        """The session; StereoGuiError or OSError when there is none or it cannot be read."""
        folder = self._folder()
        if folder is None:
            raise InputError("choose the folder of calibration pairs first")
        return CaptureSession.open(folder)

    def pair(self, name: str) -> PairEntry | None:
        """The session's pair `name`, read once (None: not in it, or no session to read)."""
        if not self.named():
            return None
        try:
            return next((p for p in self.open().pairs if p.name == name), None)
        except (StereoGuiError, OSError):
            return None

    def excluded(self) -> list[str]:
        """The names of the pairs excluded in the session now ([] without one)."""
        if not self.named():
            return []
        try:
            return [p.name for p in self.open().pairs if p.excluded]
        except (StereoGuiError, OSError):
            return []

    def swapped(self) -> bool | None:
        """Whether the session exchanges left and right (None: it cannot be read)."""
        try:
            return bool(self.open().swapped)
        except (StereoGuiError, OSError):
            return None


class PairReview(QObject):
    """Selecting, checking and excluding pairs (see the module docstring)."""

    def __init__(self, calibration: CalibrationModel, run: Callable[[], CalibrationRun | None],
                 session: SessionFolder, report: Reporter, workers: WorkerRegistry,
                 running: Callable[[], bool], parent: QWidget) -> None:
        super().__init__(parent)
        self._calibration = calibration
        self._run = run  # the tab's last run (None: none, or a calibration loaded since)
        self._session = session
        self._report = report
        self._running = running  # a calibration is being computed: nothing is excluded
        self._selected: str | None = None
        self._maps: RectifyMaps | None = None  # the rectify maps of the calibration _maps_for
        self._maps_for: StereoCalibration | None = None
        self._jobs = JobRunner("pair-view", self)  # reads and rectifies the pair clicked
        workers.register(self._jobs)
        self._jobs.finished.connect(self._pair_ready)
        self._jobs.failed.connect(self._pair_failed)
        self._job: int | None = None
        self._make_widgets()

    def _make_widgets(self) -> None:
        self.chart = ErrorBarChart()
        self.chart.pairClicked.connect(self.select_pair)
        self.pair_label = QLabel("Click a bar to see that pair")
        self.exclude_button = QPushButton("Exclude pair")
        self.exclude_button.setToolTip("Mark the pair as excluded in the session (its files stay)")
        self.exclude_button.clicked.connect(self._toggle_exclude_selected)
        self.threshold_spin = QDoubleSpinBox()
        self.threshold_spin.setRange(0.0, 100.0)
        self.threshold_spin.setDecimals(3)
        self.threshold_spin.setSingleStep(0.01)
        self.threshold_spin.setSuffix(" px")
        self.threshold_spin.setToolTip("Pairs whose error in either camera is above this can be "
                                       "excluded at once")
        self.threshold_spin.valueChanged.connect(self._threshold_edited)
        self.chart.thresholdMoved.connect(self.threshold_spin.setValue)
        self.exclude_above_button = QPushButton("Exclude pairs above")
        self.exclude_above_button.clicked.connect(
            lambda: self.exclude_above(self.threshold_spin.value()))
        self.rejected_list = QListWidget()
        self.rejected_list.setMaximumHeight(56)
        self.rejected_list.setToolTip(
            "Click a pair to look at it (and include an excluded one again)")
        self.rejected_list.itemClicked.connect(
            lambda item: self.select_pair(item.data(Qt.ItemDataRole.UserRole)))
        self.rect_view = RectifiedPairView()

    @property
    def selected_pair(self) -> str | None:
        """The pair clicked last (None before one is)."""
        return self._selected

    # ---- showing a calibration ---------------------------------------------------------------
    def use_maps(self, maps: RectifyMaps, calib: StereoCalibration) -> None:
        """The rectify maps of `calib`, made already (a run's): pairs shown need no new ones."""
        self._maps, self._maps_for = maps, calib

    def show(self, calib: StereoCalibration | None) -> None:
        """Show the pairs of `calib` (the calibration in use): their errors, the exclusions, and
        a pair rectified (the one selected, when it is still there)."""
        if calib is not self._maps_for:
            self._maps = None
            self._maps_for = None
        run = self._run()
        if calib is None:
            self.chart.set_errors([], [], [])
            self.rect_view.clear_pair()
            self.rejected_list.clear()
            self.update_buttons()
            return
        names = [p.name for p in calib.per_pair]
        self.chart.set_errors(names, [p.error_left for p in calib.per_pair],
                              [p.error_right for p in calib.per_pair])
        if self.chart.mean_px is not None:  # a start: twice the mean error
            self.threshold_spin.setValue(round(2.0 * self.chart.mean_px, 3))
        self.show_exclusions()
        if names and run is not None:
            keep = self._selected
            if keep is not None and (keep in names or keep in run.excluded):
                self.select_pair(keep)  # an excluded pair stays in view, to include it again
            else:
                self.select_pair(names[0])
        else:
            self.rect_view.clear_pair()
        self.update_buttons()

    # ---- pairs: select, rectification check, exclude --------------------------------------------
    def select_pair(self, name: str) -> None:
        """Show pair `name` rectified (when its files are known) and offer to exclude it."""
        self._selected = name
        self.chart.select(name)
        c = self._calibration.calibration
        err = next((p for p in (c.per_pair if c else ()) if p.name == name), None)
        txt = f"Pair {name}"
        if err is not None:
            txt += f": error left {err.error_left:.3f} px, right {err.error_right:.3f} px"
        self.pair_label.setText(txt)
        self.update_buttons()
        files = self._pair_files(name)
        if c is None or files is None:
            self._job = None  # (a pair still being read is not shown)
            self.rect_view.clear_pair()
            self.rect_view.title.setText(f"Pair {name}: images not available (calibrate from "
                                         f"the session to see them)")
            return
        maps = self._maps if self._maps_for is c else None
        # reading and rectifying the pair (and making the maps, the first time) runs on the
        # pair-view thread: the UI thread only draws what comes back (_pair_ready)
        self._job = self._jobs.submit(lambda _control: _read_rectified(name, files, c, maps)).id

    def _pair_ready(self, job_id: int, result: RectifiedPair) -> None:
        if job_id != self._job:
            return  # an older click's pair, or one of another calibration
        self._job = None
        name, lr, rr, c, maps = result
        if c is not self._calibration.calibration or name != self._selected:
            return
        if self._maps_for is not c:
            self._maps, self._maps_for = maps, c
        if lr is None or rr is None:  # the images are not of the calibration's size
            self.rect_view.clear_pair()
            return
        note = " (Hartley: row-aligned, no metric scale)" if not c.metric else ""
        self.rect_view.show_pair(name, lr, rr, note, self._rectified_corners(name, c),
                                 error_scale(self.chart.mean_px))

    def _pair_failed(self, job_id: int, message: str) -> None:
        if job_id == self._job:
            self._job = None
            self._report.report_error(message)

    def _rectified_corners(self, name: str, c: StereoCalibration
                           ) -> tuple[tuple[np.ndarray, np.ndarray], ...] | None:
        """The pair's detected and reprojected corners in rectified pixels (None when this
        calibration's run did not reproject it: a loaded file, an excluded pair)."""
        run = self._run()
        rp = (run.reprojections.get(name)
              if run is not None and run.result.calibration is c else None)
        if rp is None:
            return None
        return ((c.rectify_points("left", rp.detected_left),
                 c.rectify_points("left", rp.reprojected_left)),
                (c.rectify_points("right", rp.detected_right),
                 c.rectify_points("right", rp.reprojected_right)))

    def _pair_files(self, name: str) -> tuple[str, str] | None:
        run = self._run()
        if run is None:
            return None
        if name in run.files:
            return run.files[name]
        try:  # an excluded pair: not in the run, but in the session
            p = self._session.open().pair(name)
        except (StereoGuiError, OSError):
            return None
        return (str(p.left), str(p.right))

    def rejected_lines(self) -> list[str]:
        """The texts of the rejected/excluded list (for tests and screenshots)."""
        return [self.rejected_list.item(i).text() for i in range(self.rejected_list.count())]

    def _toggle_exclude_selected(self) -> None:
        name = self._selected
        if name is None:
            return
        pair = self._session.pair(name)
        self.set_excluded(name, not (pair is not None and pair.excluded))

    def set_excluded(self, name: str, excluded: bool = True) -> None:
        """Exclude (or include again) a pair in the session; Recalibrate then leaves it out."""
        try:
            self._session.open().set_excluded(name, excluded)
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"could not change pair {name}: {exc}")
            return
        self._report.show_status(f"Pair {name} {'excluded' if excluded else 'included again'}: "
                                 f"press Recalibrate")
        self.pair_label.setText(f"Pair {name} {'excluded' if excluded else 'included'}: press "
                                f"Recalibrate")
        self.show_exclusions()
        self.update_buttons()

    def show_exclusions(self) -> None:
        """The rejected/excluded list and the chart's excluded bars, from the run and the
        session as it is now: after a restart (no run) the session's exclusions are listed, not
        "none", and a pair excluded since the calibration is marked before Recalibrate."""
        excluded_now = self._session.excluded()
        self.chart.set_excluded(excluded_now)
        run = self._run()
        entries = []
        if run is not None:
            entries += [(r.name, f"{r.name}: {r.reason}") for r in run.result.report.rejected]
            entries += [(n, f"{n}: excluded by you") for n in run.excluded if n in excluded_now]
        in_calibration = set(self.chart.names)
        for n in excluded_now:
            if run is not None and n in run.excluded:
                continue
            entries.append((n, f"{n}: excluded (Recalibrate leaves it out)" if n in in_calibration
                            else f"{n}: excluded in the session"))
        if run is not None:  # included again since the run: used at the next Recalibrate
            entries += [(n, f"{n}: included again (Recalibrate uses it)")
                        for n in run.excluded if n not in excluded_now]
        self.rejected_list.clear()
        for name, text in entries:
            item = QListWidgetItem(text)
            item.setData(Qt.ItemDataRole.UserRole, name)
            item.setToolTip(text)
            self.rejected_list.addItem(item)
        if self.rejected_list.count() == 0:
            item = QListWidgetItem("none")
            item.setFlags(Qt.ItemFlag.NoItemFlags)
            self.rejected_list.addItem(item)

    # ---- exclude above a threshold ---------------------------------------------------------------
    def pairs_above(self, px: float) -> list[str]:
        """Pairs of the calibration shown whose error in either camera is above `px`, not yet
        excluded."""
        c = self._calibration.calibration
        if c is None:
            return []
        excluded = set(self._session.excluded())
        return [p.name for p in c.per_pair
                if max(p.error_left, p.error_right) > px and p.name not in excluded]

    def _threshold_edited(self, px: float) -> None:
        self.chart.set_threshold(px)
        self.update_buttons()

    def exclude_above(self, px: float) -> list[str]:
        """Exclude in the session every pair above `px` (see pairs_above); their names."""
        names = self.pairs_above(px)
        if not names:
            return []
        try:
            session = self._session.open()
            for name in names:
                session.set_excluded(name, True)
        except (StereoGuiError, OSError) as exc:
            self._report.report_error(f"could not exclude the pairs: {exc}")
            names = []
        if names:
            self._report.show_status(
                f"Excluded {len(names)} pair{'s' if len(names) != 1 else ''} above {px:.3f} px "
                f"({', '.join(names)}): press Recalibrate")
        self.show_exclusions()
        self.update_buttons()
        return names

    def update_buttons(self) -> None:
        """Exclude pair and Exclude pairs above: offered when they can act now."""
        running = self._running()
        sel = self._selected
        # after a restart (no run) a pair of the session can still be excluded or included
        pair = self._session.pair(sel) if sel is not None else None  # (one read of the session)
        known = sel is not None and (self._run() is not None or pair is not None)
        self.exclude_button.setEnabled(not running and known)
        n_above = len(self.pairs_above(self.threshold_spin.value())) if not running else 0
        self.exclude_above_button.setText(
            f"Exclude {n_above} pair{'s' if n_above != 1 else ''} above")
        self.exclude_above_button.setEnabled(n_above > 0)
        if known:
            excluded = pair is not None and pair.excluded
            self.exclude_button.setText("Include pair again" if excluded else "Exclude pair")


# (name, rectified left, rectified right, calibration, maps): what the pair-view thread gives
RectifiedPair = tuple[str, np.ndarray | None, np.ndarray | None, StereoCalibration, RectifyMaps]


def _read_rectified(name: str, files: tuple[str, str], c: StereoCalibration,
                    maps: RectifyMaps | None) -> RectifiedPair:
    """(name, rectified left, rectified right, c, maps) of a pair (on the pair-view thread);
    the images are None when they are not of the calibration's size. StereoGuiError when a
    file cannot be read."""
    left, right = read_image(files[0]), read_image(files[1])
    if maps is None:
        maps = c.rectify_maps()
    if (left.shape[1], left.shape[0]) != tuple(c.image_size):
        return name, None, None, c, maps
    lr: np.ndarray = cv2.remap(left, maps.left_x, maps.left_y, cv2.INTER_LINEAR)
    rr: np.ndarray = cv2.remap(right, maps.right_x, maps.right_y, cv2.INTER_LINEAR)
    return name, lr, rr, c, maps
