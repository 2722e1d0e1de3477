"""The Capture tab with other targets: choosing one, coverage in words, auto-capture preferring
poses that reach empty regions, and Print a target..."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.detect import NEW_POSE_DISTANCE, Detection, PairDetection
from stereo_gui.files.session import CaptureSession
from stereo_gui.pipeline.capture import CaptureOutput, make_capture_processor
from stereo_gui.qt.tabs.capture import STEADY_FRAMES, CaptureTab
from stereo_gui.qt.widgets.target_dialog import TargetDialog
from stereo_gui.sources.base import StereoFrame
from stereo_gui.sources.sim import RigConfig, SimRig, SimSource

CHARUCO = BoardSpec(7, 5, 30.0, "charuco", 22.0)


def test_choosing_charuco_sets_the_board_the_settings_and_the_live_detector(make_tab, ctx):
    tab = make_tab(CaptureTab)
    row = tab.board_row
    row.target_combo.setCurrentIndex(row.target_combo.findData("charuco"))
    row.cols_spin.setValue(7)
    row.rows_spin.setValue(5)
    row.square_spin.setValue(30.0)
    row.marker_spin.setValue(22.0)
    assert tab.board == CHARUCO
    assert ctx.settings.board == CHARUCO
    assert row.count_label.text() == "Squares:" and row.dict_combo.isVisibleTo(row)
    # an impossible marker keeps the last valid board and says why
    row.marker_spin.setValue(35.0)
    assert tab.board == CHARUCO and "smaller than the squares" in row.error_label.text()


@pytest.mark.slow
def test_a_partly_visible_charuco_board_is_found_live():
    rig = SimRig(RigConfig(board=CHARUCO, supersample=1), seed=3)
    src = SimSource(rig, mode="board", paced=False, seed=3, frames_per_move=4)
    proc = make_capture_processor(CHARUCO)
    found = []
    try:
        for _ in range(40):
            out = proc(src.read())
            if out.detection.found:
                found.append(out.detection)
    finally:
        src.close()
    assert found
    assert any(len(d.common_ids()) < CHARUCO.point_count for d in found)


def _grid(x0, y0, step=14.0, cols=9, rows=6):
    xs, ys = np.meshgrid(x0 + step * np.arange(cols), y0 + step * np.arange(rows))
    return np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float32)


def _output(left_pts, right_pts):
    img = np.full((480, 640, 3), 128, np.uint8)
    det = PairDetection("live", Detection(left_pts, (640, 480), "classic"),
                        Detection(right_pts, (640, 480), "classic"), (640, 480))
    frame = StereoFrame(img, img.copy(), 0.0, 0.0, 0)
    return CaptureOutput(img, img, det, BoardSpec()), frame


def test_readiness_names_the_empty_regions_and_auto_capture_prefers_poses_that_fill_them(
        make_tab, tmp_path):
    tab = make_tab(CaptureTab)
    tab.new_session(tmp_path / "s")
    tab.auto_check.setChecked(True)
    first = _output(_grid(170, 200), _grid(110, 200))
    for _ in range(STEADY_FRAMES):
        tab.show_output(*first)
    assert len(CaptureSession.open(tmp_path / "s").pairs) == 1
    text = tab.coverage.readiness_label.text()
    assert text.startswith("Not ready yet") and "top-left corner" in text
    # a view only a little to the left of the kept one: not a new pose by ROS's measure, but
    # it reaches the left image's left edge, still empty: taken
    near = _output(_grid(100, 200), _grid(40, 200))
    board = BoardSpec()
    assert near[0].detection.left.pose(board).distance(
        first[0].detection.left.pose(board)) < NEW_POSE_DISTANCE
    for _ in range(STEADY_FRAMES):
        tab.show_output(*near)
    assert len(CaptureSession.open(tmp_path / "s").pairs) == 2
    # the same view again fills nothing new: not taken, and the prompt says where to go
    for _ in range(STEADY_FRAMES):
        tab.show_output(*near)
    assert len(CaptureSession.open(tmp_path / "s").pairs) == 2
    assert "not yet covered" in tab.prompt.text() and "corner" in tab.prompt.text()


def test_print_a_target_writes_a_pdf_and_refuses_a_board_too_large(qtbot, tmp_path):
    dlg = TargetDialog(CHARUCO, tmp_path)
    qtbot.addWidget(dlg)
    assert dlg.save_button.isEnabled() and "landscape" in dlg.status_label.text()
    with qtbot.waitSignal(dlg.written, timeout=5000):
        assert dlg.save(tmp_path / "board.pdf")
    assert (tmp_path / "board.pdf").read_bytes().startswith(b"%PDF")
    big = TargetDialog(BoardSpec(12, 9, 30.0, "charuco", 22.0, "DICT_5X5_100"), tmp_path)
    qtbot.addWidget(big)
    assert not big.save_button.isEnabled() and "Does not fit" in big.status_label.text()
    big.page_combo.setCurrentIndex(big.page_combo.findData("a2"))
    assert big.save_button.isEnabled()
