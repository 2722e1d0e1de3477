"""The Calibration tab on a simulated calibration set: results, exclude + recalibrate, cancel."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.files.session import CaptureSession
from stereo_gui.qt.tabs.calibration import CalibrationTab
from stereo_gui.qt.tabs.calibration_state import CalibrationState
from stereo_gui.sources.sim import write_calibration_set

N_PAIRS = 12


@pytest.fixture(scope="module")
def calib_set(tmp_path_factory):
    folder = tmp_path_factory.mktemp("calset")
    return write_calibration_set(folder, n_pairs=N_PAIRS, seed=11)


@pytest.fixture
def session_folder(calib_set, tmp_path):
    """A fresh copy, so that exclusions written by one test do not leak into another."""
    import shutil

    dst = tmp_path / "session"
    shutil.copytree(calib_set, dst)
    return dst


@pytest.fixture
def tab(make_tab):
    return make_tab(CalibrationTab)


def _calibrate(tab, qtbot, timeout=120000):
    with qtbot.waitSignal(tab.calibrationFinished, timeout=timeout) as blocker:
        assert tab.start_calibration()
    qtbot.waitUntil(lambda: not tab.is_running(), timeout=30000)
    return blocker.args[0]


def test_calibrate_session_shows_results(tab, ctx, qtbot, session_folder):
    tab.folder_edit.setText(str(session_folder))
    run = _calibrate(tab, qtbot)
    rep = run.result.report
    assert rep.pairs_found == N_PAIRS
    assert ctx.calibration is run.result.calibration
    for lab in (tab.figures.rms_left_label, tab.figures.rms_right_label, tab.figures.rms_stereo_label, tab.figures.epipolar_label):
        assert lab.text().endswith("px") or " px " in lab.text(), lab.text()
    assert float(tab.figures.rms_stereo_label.text().split()[0]) < 1.0
    assert "nominal 110.0 mm" in tab.figures.baseline_label.text()
    assert "Mrekt" in tab.matrices_text.toPlainText()
    assert "without rectification" in tab.matrices_text.toPlainText()
    assert tab.chart.bar_count() == rep.pairs_used
    assert f"{rep.pairs_used} used of {N_PAIRS}" in tab.figures.pairs_label.text()
    assert tab.progress.value() == 100
    # the first pair is shown rectified (read and rectified on the pair-view thread)
    qtbot.waitUntil(lambda: tab.rect_view.shown == tab.chart.names[0], timeout=5000)


@pytest.mark.slow
def test_click_exclude_and_recalibrate_changes_used_count(tab, qtbot, session_folder):
    tab.folder_edit.setText(str(session_folder))
    run = _calibrate(tab, qtbot)
    used = run.result.report.pairs_used
    name = tab.chart.names[2]
    # a click in the middle of the third bar selects that pair
    vb = tab.chart.plotItem.vb
    tab.chart.resize(600, 300)
    tab.chart.show()
    qtbot.waitExposed(tab.chart)
    from PySide6.QtCore import QPointF, Qt

    pos = tab.chart.mapFromScene(vb.mapViewToScene(QPointF(2.0, 0.01)))
    with qtbot.waitSignal(tab.chart.pairClicked, timeout=2000) as clicked:
        qtbot.mouseClick(tab.chart.viewport(), Qt.MouseButton.LeftButton, pos=pos)
    assert clicked.args == [name]
    qtbot.waitUntil(lambda: tab.rect_view.shown == name, timeout=5000)
    assert tab.exclude_button.isEnabled()
    tab.exclude_button.click()
    assert CaptureSession.open(session_folder).pair(name).excluded
    assert tab.exclude_button.text() == "Include pair again"
    run2 = _calibrate(tab, qtbot)
    assert run2.result.report.pairs_used == used - 1
    assert name not in run2.result.report.used
    assert tab.chart.bar_count() == used - 1
    assert f"{name}: excluded by you" in tab.review.rejected_lines()
    # the excluded pair stays selectable from the list, and can be included again
    item = tab.rejected_list.findItems(f"{name}: excluded by you", Qt.MatchFlag.MatchExactly)[0]
    tab.rejected_list.itemClicked.emit(item)
    assert tab.review.selected_pair == name
    qtbot.waitUntil(lambda: tab.rect_view.shown == name, timeout=5000)
    assert tab.exclude_button.text() == "Include pair again"
    tab.exclude_button.click()
    assert not CaptureSession.open(session_folder).pair(name).excluded
    run3 = _calibrate(tab, qtbot)
    assert run3.result.report.pairs_used == used


def test_cancel_stops_calibration(tab, ctx, qtbot, session_folder):
    tab.folder_edit.setText(str(session_folder))
    finished = []
    tab.calibrationFinished.connect(finished.append)
    tab.start_calibration()
    assert tab.cancel_button.isEnabled()
    with qtbot.waitSignal(tab.worker.cancelled, timeout=60000):
        tab.cancel_button.click()
    qtbot.waitUntil(lambda: not tab.is_running(), timeout=30000)
    assert finished == []
    assert ctx.calibration is None
    assert tab.state is CalibrationState.CANCELLED
    assert "cancelled" in tab.progress_label.text()
    assert tab.calibrate_button.isEnabled() and not tab.cancel_button.isEnabled()


def test_bad_folder_reports_error(tab, ctx, qtbot, tmp_path):
    errors = []
    ctx.errorOccurred.connect(errors.append)
    tab.folder_edit.setText(str(tmp_path / "nope"))
    assert not tab.start_calibration()
    assert errors and "does not exist" in errors[0]
    empty = tmp_path / "empty"
    empty.mkdir()
    tab.folder_edit.setText(str(empty))
    with qtbot.waitSignal(ctx.errorOccurred, timeout=20000) as blocker:
        assert tab.start_calibration()
    assert "pairs" in blocker.args[0] or "no" in blocker.args[0]
    qtbot.waitUntil(lambda: not tab.is_running(), timeout=30000)
    assert tab.state is CalibrationState.FAILED and "failed" in tab.progress_label.text()


def test_save_and_load_calibration_file(tab, ctx, qtbot, session_folder, tmp_path):
    tab.folder_edit.setText(str(session_folder))
    assert tab.state is CalibrationState.IDLE
    run = _calibrate(tab, qtbot)
    assert tab.state is CalibrationState.UNSAVED
    assert "NOT SAVED" in tab.figures.source_label.text()
    path = tmp_path / "calib.yaml"
    assert tab.calibration_actions.save_calibration(path) and path.exists()
    assert ctx.calibration_path == path and "calib.yaml" in tab.figures.source_label.text()
    # the run's line no longer says "Not saved yet" once it is saved
    assert "Not saved yet" not in tab.progress_label.text()
    assert "Saved as calib.yaml" in tab.progress_label.text()
    assert tab.state is CalibrationState.SAVED
    # the file saved here is the one loaded at the next start, as from the File menu
    assert ctx.settings.last_calibration == str(path.resolve())
    ctx.calibration_model.set(None)  # another calibration (none) replaces the run's
    assert tab.state is CalibrationState.IDLE and tab.run is None
    assert tab.figures.rms_stereo_label.text() == "—" and tab.chart.bar_count() == 0
    assert tab.calibration_actions.load_calibration(path)
    assert ctx.calibration.rms_stereo == pytest.approx(run.result.calibration.rms_stereo)
    assert tab.chart.bar_count() == len(run.result.calibration.per_pair)
    errors = []
    ctx.errorOccurred.connect(errors.append)
    bad = tmp_path / "bad.yaml"
    bad.write_text("not a calibration")
    assert not tab.calibration_actions.load_calibration(bad)
    assert errors and "bad.yaml" in errors[0]


def test_hartley_states_its_limits(tab, qtbot, session_folder):
    tab.folder_edit.setText(str(session_folder))
    tab.method_combo.setCurrentIndex(tab.method_combo.findData("hartley"))
    run = _calibrate(tab, qtbot)
    assert run.result.calibration.method == "hartley"
    assert "no metric scale" in tab.figures.baseline_label.text()
    assert "NOT in millimetres" in tab.figures.note_label.text()
    qtbot.waitUntil(lambda: "no metric scale" in tab.rect_view.title.text, timeout=5000)


def test_shutdown_while_calibrating_joins_the_worker(tab, ctx, qtbot, session_folder):
    tab.folder_edit.setText(str(session_folder))
    assert tab.start_calibration()
    worker = tab.worker
    assert ctx.shutdown(2000)  # what closing the window does: cancel and join every worker
    assert not worker.isRunning()
    qtbot.waitUntil(lambda: not tab.is_running(), timeout=30000)


def test_empty_error_chart_axis_reads_pair_without_an_si_prefix(qtbot):
    from stereo_gui.qt.widgets.calibration_charts import ErrorBarChart

    chart = ErrorBarChart()
    qtbot.addWidget(chart)
    chart.show()
    qtbot.waitExposed(chart)
    chart.setXRange(0.0, 0.002)  # an empty plot's tiny range is what made pyqtgraph add a prefix
    axis = chart.getPlotItem().getAxis("bottom")
    axis.updateAutoSIPrefix()
    label = axis.labelString()
    assert "pair" in label and "x0.001" not in label and "(m" not in label


def test_exclusions_are_shown_before_recalibration_and_after_a_restart(
        tab, ctx, qtbot, make_tab, session_folder, tmp_path):
    """A pair excluded is marked on the chart at once (not only after
    Recalibrate), and after a restart the list names the session's excluded pairs, not "none"."""
    tab.folder_edit.setText(str(session_folder))
    _calibrate(tab, qtbot)
    assert tab.review.rejected_lines() == ["none"] and tab.chart.excluded_bars() == []
    name = tab.chart.names[2]
    tab.review.select_pair(name)
    tab.exclude_button.click()
    assert tab.chart.excluded_bars() == [name]
    assert f"{name}: excluded (Recalibrate leaves it out)" in tab.review.rejected_lines()
    assert tab.calibration_actions.save_calibration(tmp_path / "calib.yaml")
    # a restart: a new tab, the calibration loaded from its file, no run
    ctx.calibration_model.set(None)
    assert ctx.calibration_model.open_file(tmp_path / "calib.yaml")
    again = make_tab(CalibrationTab)
    again.folder_edit.setText(str(session_folder))
    assert again.run is None
    assert f"{name}: excluded (Recalibrate leaves it out)" in again.review.rejected_lines()
    assert again.chart.excluded_bars() == [name]
    again.review.select_pair(name)  # it can be included again without calibrating first
    assert again.exclude_button.isEnabled()
    assert again.exclude_button.text() == "Include pair again"
    again.exclude_button.click()
    assert not CaptureSession.open(session_folder).pair(name).excluded
    assert again.review.rejected_lines() == ["none"] and again.chart.excluded_bars() == []


def test_review_draws_corners_a_mean_line_and_excludes_above_a_threshold(
        tab, qtbot, session_folder):
    """The selected pair shows its detected and reprojected corners, the
    chart a mean-error line, and the pairs above a threshold are excluded in one step."""
    tab.folder_edit.setText(str(session_folder))
    run = _calibrate(tab, qtbot)
    calib = run.result.calibration
    errs = [(p.name, p.error_left, p.error_right) for p in calib.per_pair]
    assert tab.chart.mean_px == pytest.approx(
        sum(e[1] + e[2] for e in errs) / (2 * len(errs)))
    name = tab.chart.names[1]
    tab.review.select_pair(name)
    qtbot.waitUntil(lambda: tab.rect_view.shown == name, timeout=5000)
    det, rep = tab.rect_view.corner_points(0)
    assert len(det) == len(run.detections[name].left.corners) and det.shape == rep.shape
    # rectified pixels: the two sit within a pixel of each other, inside the rectified image
    assert float(np.abs(det - rep).max()) < 1.0
    w, h = calib.image_size
    assert (det[:, 0] > 0).all() and (det[:, 0] < w).all()
    det_r, _ = tab.rect_view.corner_points(1)
    # a corner lies on the same row in both rectified images
    assert float(np.abs(np.median(det[:, 1] - det_r[:, 1]))) < 0.5
    tab.rect_view.corners_check.setChecked(False)
    assert len(tab.rect_view.corner_points(0)[0]) == 0
    # exclude above a threshold between the errors: exactly those above it
    worst = sorted(max(e[1], e[2]) for e in errs)
    px = (worst[-3] + worst[-4]) / 2
    tab.threshold_spin.setValue(px)
    px = tab.threshold_spin.value()  # (to the spin box's 0.001 px)
    assert tab.chart.threshold_px == pytest.approx(px)
    assert tab.exclude_above_button.text() == "Exclude 3 pairs above"
    names = tab.review.exclude_above(tab.threshold_spin.value())
    expected = {e[0] for e in errs if max(e[1], e[2]) > px}
    assert set(names) == expected and len(expected) == 3
    session = CaptureSession.open(session_folder)
    assert {p.name for p in session.pairs if p.excluded} == expected
    assert set(tab.chart.excluded_bars()) == expected
    assert not tab.exclude_above_button.isEnabled()  # nothing left above it
    run2 = _calibrate(tab, qtbot)
    assert run2.result.report.pairs_used == len(errs) - 3


def test_a_pair_is_read_and_rectified_off_the_ui_thread(tab, qtbot, session_folder,
                                                          monkeypatch):
    """Selecting a pair reads and rectifies it on the pair-view thread: the UI thread only draws
    (it took 20-30 ms a click, and the first one made the maps too); a later click wins."""
    import threading

    from stereo_gui.qt.tabs import calibration_pairs

    tab.folder_edit.setText(str(session_folder))
    _calibrate(tab, qtbot)
    readers = []
    real = calibration_pairs.read_image

    def recording(path):
        readers.append(threading.current_thread())
        return real(path)

    monkeypatch.setattr(calibration_pairs, "read_image", recording)
    first, second = tab.chart.names[1], tab.chart.names[3]
    tab.review.select_pair(first)
    tab.review.select_pair(second)  # at once: the first one's answer must not be shown after it
    # each pair read is its two images; the first request is dropped when the second comes
    # before the thread took it (the newest wins), so two or four reads
    # one thread answers in the order asked: once the second is shown, the first's answer
    # (if it was read at all) came before it and was dropped
    qtbot.waitUntil(lambda: tab.rect_view.shown == second and len(readers) in (2, 4),
                    timeout=5000)
    assert tab.rect_view.shown == second
    assert readers and all(t is not threading.main_thread() for t in readers)


def test_the_tab_shows_the_calibration_in_use_and_its_run_until_another_replaces_it(
        tab, ctx, calibration_run, sim_rig):
    """The tab keeps no copy of the calibration: it shows the model's, and a run handed to it
    stays its run until another calibration is put in use."""
    tab.use_run(calibration_run)
    calib = calibration_run.result.calibration
    assert ctx.calibration is calib and tab.calibration is calib
    assert tab.state is CalibrationState.UNSAVED and "Not saved yet" in tab.progress_label.text()
    assert tab.recalibrate_button.isEnabled() and tab.save_button.isEnabled()
    true = sim_rig.true_calibration()
    ctx.calibration_model.set(true, None)
    assert tab.calibration is true and tab.run is None and tab.state is CalibrationState.IDLE
    assert not tab.recalibrate_button.isEnabled()
    assert tab.chart.bar_count() == len(true.per_pair)


def test_the_alpha_box_offers_what_the_calibration_declares(tab):
    from stereo_gui.core.stereo_calibration import ALPHA

    assert (tab.alpha_spin.minimum(), tab.alpha_spin.maximum()) == (ALPHA.lo, ALPHA.hi)
    assert tab.alpha_spin.value() == ALPHA.default
    assert tab.alpha_spin.toolTip() == ALPHA.help
