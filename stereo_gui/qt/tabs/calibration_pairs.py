"""The Calibration tab's review of single pairs: each pair shown rectified with its detected and
reprojected corners, the pairs excluded (by hand or above an error threshold) and the list of
rejected and excluded pairs, kept in the capture session so that Recalibrate leaves them out.

`PairReview` is a part of `CalibrationTab` (a mixin: it uses the tab's widgets, run and session).
A pair is read and rectified on the tab's pair-view thread (`_pair_jobs`), never on the UI
thread.
"""

from __future__ import annotations

from pathlib import Path

import cv2
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QListWidgetItem

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.stereo_calibration import RectifyMaps, StereoCalibration
from stereo_gui.pipeline.calibration import read_image
from stereo_gui.qt.widgets.calibration_charts import error_scale


class PairReview:
    """Selecting, checking and excluding pairs (see the module docstring)."""

    # ---- pairs: select, rectification check, exclude --------------------------------------------
    def select_pair(self, name: str) -> None:
        """Show pair `name` rectified (when its files are known) and offer to exclude it."""
        self.selected_pair = name
        self.chart.select(name)
        c = self.calibration
        err = next((p for p in (c.per_pair if c else ()) if p.name == name), None)
        txt = f"Pair {name}"
        if err is not None:
            txt += f": error left {err.error_left:.3f} px, right {err.error_right:.3f} px"
        self.pair_label.setText(txt)
        self._update_buttons()
        files = self._pair_files(name)
        if c is None or files is None:
            self._pair_job = None  # (a pair still being read is not shown)
            self.rect_view.clear_pair()
            self.rect_view.title.setText(f"Pair {name}: images not available (calibrate from "
                                         f"the session to see them)")
            return
        maps = self._maps if self._maps_for is c else None
        # reading and rectifying the pair (and making the maps, the first time) runs on the
        # pair-view thread: the UI thread only draws what comes back (_pair_ready)
        self._pair_job = self._pair_jobs.submit(
            lambda _control: _read_rectified(name, files, c, maps)).id

    def _pair_ready(self, job_id: int, result) -> None:
        if job_id != self._pair_job:
            return  # an older click's pair, or one of another calibration
        self._pair_job = None
        name, lr, rr, c, maps = result
        if c is not self.calibration or name != self.selected_pair:
            return
        if self._maps_for is not c:
            self._maps, self._maps_for = maps, c
        if lr is None:  # the images are not of the calibration's size
            self.rect_view.clear_pair()
            return
        note = " (Hartley: row-aligned, no metric scale)" if not c.metric else ""
        self.rect_view.show_pair(name, lr, rr, note, self._rectified_corners(name, c),
                                 error_scale(self.chart.mean_px))

    def _pair_failed(self, job_id: int, message: str) -> None:
        if job_id == self._pair_job:
            self._pair_job = None
            self.ctx.report_error(message)

    def _rectified_corners(self, name: str, c: StereoCalibration):
        """The pair's detected and reprojected corners in rectified pixels (None when this
        calibration's run did not reproject it: a loaded file, an excluded pair)."""
        rp = (self.run.reprojections.get(name)
              if self.run is not None and self.run.result.calibration is c else None)
        if rp is None:
            return None
        return ((c.rectify_points("left", rp.detected_left),
                 c.rectify_points("left", rp.reprojected_left)),
                (c.rectify_points("right", rp.detected_right),
                 c.rectify_points("right", rp.reprojected_right)))

    def _pair_files(self, name: str) -> tuple[str, str] | None:
        if self.run is not None and name in self.run.files:
            return self.run.files[name]
        if self.run is not None:  # an excluded pair: not in the run, but in the session
            try:
                p = self._session().pair(name)
            except (StereoGuiError, OSError):
                return None
            return (str(p.left), str(p.right))
        return None

    def rejected_lines(self) -> list[str]:
        """The texts of the rejected/excluded list (for tests and screenshots)."""
        return [self.rejected_list.item(i).text() for i in range(self.rejected_list.count())]

    def _session(self):
        from stereo_gui.files.session import CaptureSession

        folder = self.run.folder if self.run is not None else Path(self.folder_edit.text())
        return CaptureSession.open(folder)

    def _session_pair(self, name: str):
        """The session's pair `name`, read once (None: not in it, or no session to read)."""
        if self.run is None and not self.folder_edit.text().strip():
            return None
        try:
            return next((p for p in self._session().pairs if p.name == name), None)
        except (StereoGuiError, OSError):
            return None

    def _is_excluded(self, name: str) -> bool:
        pair = self._session_pair(name)
        return pair is not None and pair.excluded

    def _toggle_exclude_selected(self) -> None:
        name = self.selected_pair
        if name is None:
            return
        self.set_excluded(name, not self._is_excluded(name))

    def set_excluded(self, name: str, excluded: bool = True) -> None:
        """Exclude (or include again) a pair in the session; Recalibrate then leaves it out."""
        try:
            self._session().set_excluded(name, excluded)
        except (StereoGuiError, OSError) as exc:
            self.ctx.report_error(f"could not change pair {name}: {exc}")
            return
        self.ctx.show_status(f"Pair {name} {'excluded' if excluded else 'included again'}: "
                             f"press Recalibrate")
        self.pair_label.setText(f"Pair {name} {'excluded' if excluded else 'included'}: press "
                                f"Recalibrate")
        self._show_exclusions()
        self._update_buttons()

    def _session_excluded(self) -> list[str]:
        """The pairs excluded in the session now (those of the Pairs folder without a run)."""
        if self.run is None and not self.folder_edit.text().strip():
            return []
        try:
            return [p.name for p in self._session().pairs if p.excluded]
        except (StereoGuiError, OSError):
            return []

    def _show_exclusions(self) -> None:
        """The rejected/excluded list and the chart's excluded bars, from the run and the
        session as it is now: after a restart (no run) the session's exclusions are listed, not
        "none", and a pair excluded since the calibration is marked before Recalibrate."""
        excluded_now = self._session_excluded()
        self.chart.set_excluded(excluded_now)
        entries = []
        if self.run is not None:
            entries += [(r.name, f"{r.name}: {r.reason}") for r in self.run.result.report.rejected]
            entries += [(n, f"{n}: excluded by you") for n in self.run.excluded
                        if n in excluded_now]
        in_calibration = set(self.chart.names)
        for n in excluded_now:
            if self.run is not None and n in self.run.excluded:
                continue
            entries.append((n, f"{n}: excluded (Recalibrate leaves it out)" if n in in_calibration
                            else f"{n}: excluded in the session"))
        if self.run is not None:  # included again since the run: used at the next Recalibrate
            entries += [(n, f"{n}: included again (Recalibrate uses it)")
                        for n in self.run.excluded if n not in excluded_now]
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
        c = self.calibration
        if c is None:
            return []
        excluded = set(self._session_excluded())
        return [p.name for p in c.per_pair
                if max(p.error_left, p.error_right) > px and p.name not in excluded]

    def _threshold_edited(self, px: float) -> None:
        self.chart.set_threshold(px)
        self._update_buttons()

    def exclude_above(self, px: float) -> list[str]:
        """Exclude in the session every pair above `px` (see pairs_above); their names."""
        names = self.pairs_above(px)
        if not names:
            return []
        try:
            session = self._session()
            for name in names:
                session.set_excluded(name, True)
        except (StereoGuiError, OSError) as exc:
            self.ctx.report_error(f"could not exclude the pairs: {exc}")
            names = []
        if names:
            self.ctx.show_status(f"Excluded {len(names)} pair{'s' if len(names) != 1 else ''} "
                                 f"above {px:.3f} px ({', '.join(names)}): press Recalibrate")
        self._show_exclusions()
        self._update_buttons()
        return names


def _read_rectified(name: str, files: tuple[str, str], c: StereoCalibration,
                    maps: RectifyMaps | None):
    """(name, rectified left, rectified right, c, maps) of a pair (on the pair-view thread);
    the images are None when they are not of the calibration's size. StereoGuiError when a
    file cannot be read."""
    left, right = read_image(files[0]), read_image(files[1])
    if maps is None:
        maps = c.rectify_maps()
    if (left.shape[1], left.shape[0]) != tuple(c.image_size):
        return name, None, None, c, maps
    lr = cv2.remap(left, maps.left_x, maps.left_y, cv2.INTER_LINEAR)
    rr = cv2.remap(right, maps.right_x, maps.right_y, cv2.INTER_LINEAR)
    return name, lr, rr, c, maps
