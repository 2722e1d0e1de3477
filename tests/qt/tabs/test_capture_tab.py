"""The Capture tab on the simulated rig: freeze and save pairs, cancel, auto-capture, sessions."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.files.session import CaptureSession
from stereo_gui.qt.tabs.capture import CaptureTab, make_capture_processor
from stereo_gui.qt.tabs.capture_state import CaptureState
from stereo_gui.sources.sim import SimSource, write_calibration_set


@pytest.fixture
def tab(make_tab):
    return make_tab(CaptureTab)


def _board_frames(n=40, seed=0):
    """Processed frames of the simulated rig with the board in view of both cameras."""
    src = SimSource(mode="board", paced=False, seed=seed, frames_per_move=6)
    proc = make_capture_processor(BoardSpec())
    out = []
    try:
        for _ in range(n):
            f = src.read()
            o = proc(f)
            if o.detection.found:
                out.append((o, f))
            if len(out) >= 3:
                break
    finally:
        src.close()
    assert out, "the simulated rig never showed the board to both cameras"
    return out


def test_both_sides_found_freezes_and_save_writes_both_images(tab, tmp_path, qtbot):
    tab.new_session(tmp_path / "session")
    out, frame = _board_frames()[0]
    tab.show_output(out, frame)
    assert tab.state is CaptureState.REVIEW
    assert tab.save_button.isEnabled() and tab.cancel_button.isEnabled()
    assert "board found" in tab.view.titles[0].text and "board found" in tab.view.titles[1].text
    with qtbot.waitSignal(tab.pairSaved, timeout=30000) as blocker:
        tab.save_button.click()
    name = blocker.args[0]
    assert tab.state is CaptureState.LIVE
    session = CaptureSession.open(tmp_path / "session")
    assert [p.name for p in session.pairs] == [name]
    p = session.pairs[0]
    left, right = cv2.imread(str(p.left)), cv2.imread(str(p.right))
    assert np.array_equal(left, frame.left) and np.array_equal(right, frame.right)
    assert tab.saved_names() == [name]
    assert tab.coverage.bar_values()["X"] >= 0
    assert tab.coverage.count_label.text().startswith("1 pair kept")  # not "1 pairs"


def test_cancel_discards_and_same_pose_does_not_freeze_again(tab, tmp_path):
    tab.new_session(tmp_path / "s")
    out, frame = _board_frames()[0]
    tab.show_output(out, frame)
    assert tab.state is CaptureState.REVIEW
    tab.cancel_button.click()
    assert tab.state is CaptureState.LIVE
    tab.show_output(out, frame)  # the board has not moved: no second freeze
    assert tab.state is CaptureState.LIVE
    assert "new pose" in tab.prompt.text()
    assert CaptureSession.open(tmp_path / "s").pairs == ()


def test_choosing_a_session_during_review_drops_the_ask_for_one_note(tab, tmp_path):
    """A pair frozen before any session says Save will ask for a folder; once the technician
    chose one with New session..., the prompt must stop saying so."""
    out, frame = _board_frames()[0]
    tab.show_output(out, frame)
    assert tab.state is CaptureState.REVIEW and "session folder first" in tab.prompt.text()
    tab.new_session(tmp_path / "s")
    assert tab.state is CaptureState.REVIEW
    assert "Save this pair (S)" in tab.prompt.text()
    assert "session folder first" not in tab.prompt.text()


def test_only_one_side_sees_board(tab, tmp_path):
    out, frame = _board_frames()[0]
    from dataclasses import replace

    half = replace(out, detection=replace(out.detection, right=None))
    tab.show_output(half, frame)
    assert tab.state is CaptureState.LIVE
    assert "no board" in tab.view.titles[1].text
    assert "Only the left camera" in tab.prompt.text()


def test_auto_capture_takes_steady_new_poses_only(tab, tmp_path, ctx):
    tab.new_session(tmp_path / "auto")
    tab.auto_check.setChecked(True)
    assert ctx.settings.auto_capture is True
    out, frame = _board_frames()[0]
    for _ in range(6):  # the same view again and again: steady; taken once, then not new
        tab.show_output(out, frame)
    assert tab.state is CaptureState.LIVE
    assert len(CaptureSession.open(tmp_path / "auto").pairs) == 1
    assert "already captured" in tab.prompt.text()


def test_open_session_lists_pairs_with_coverage_and_delete(tab, tmp_path, qtbot):
    (tmp_path / "set").mkdir()
    folder = write_calibration_set(tmp_path / "set", n_pairs=4, seed=3)
    tab.open_session(folder)
    qtbot.waitUntil(lambda: not tab.scanning(), timeout=20000)
    assert len(tab.saved_names()) == 4
    # Delete pair deletes the pair on screen: none yet (live), so there is nothing to delete
    assert not tab.delete_button.isEnabled()
    assert tab.pair_list.item(0).icon() is not None and not tab.pair_list.item(0).icon().isNull()
    assert tab.coverage.left_map.covered_fraction() > 0
    assert sum(tab.coverage.bar_values().values()) > 0
    first = tab.saved_names()[0]
    tab.show_saved_pair(first)
    assert tab.state is CaptureState.SAVED
    assert tab.live_button.isEnabled() and tab.delete_button.isEnabled()
    files = CaptureSession.open(folder).pair(first)
    tab.delete_pair(first)
    assert first not in tab.saved_names() and len(tab.saved_names()) == 3
    assert not files.left.exists() and not files.right.exists()
    assert tab.state is CaptureState.LIVE


def test_opening_a_session_with_an_unreadable_manifest_says_so(tab, ctx, tmp_path, qtbot):
    """The technician is told that the board and exclusions of session.json were not read."""
    (tmp_path / "set").mkdir()
    folder = write_calibration_set(tmp_path / "set", n_pairs=2, seed=3)
    (folder / "session.json").write_text('{"format_version": 1, "pairs": [')
    errors = []
    ctx.errorOccurred.connect(errors.append)
    tab.open_session(folder)
    qtbot.waitUntil(lambda: not tab.scanning(), timeout=20000)
    assert len(tab.saved_names()) == 2
    assert errors and "session.json is unreadable" in errors[0]


def test_delete_pair_button_asks_before_removing_the_files(tab, tmp_path, qtbot, monkeypatch):
    from PySide6.QtWidgets import QMessageBox

    (tmp_path / "set").mkdir()
    folder = write_calibration_set(tmp_path / "set", n_pairs=2, seed=3)
    tab.open_session(folder)
    qtbot.waitUntil(lambda: not tab.scanning(), timeout=20000)
    first = tab.saved_names()[0]
    files = CaptureSession.open(folder).pair(first)
    tab.show_saved_pair(first)  # as a click on it in the list
    assert tab.delete_button.isEnabled()
    monkeypatch.setattr(QMessageBox, "question",
                        lambda *a, **k: QMessageBox.StandardButton.No)
    tab.delete_button.click()
    assert files.left.exists() and first in tab.saved_names()
    monkeypatch.setattr(QMessageBox, "question",
                        lambda *a, **k: QMessageBox.StandardButton.Yes)
    tab.delete_button.click()
    assert not files.left.exists() and first not in tab.saved_names()


def test_board_settings_are_persisted(tab, ctx):
    tab.cols_spin.setValue(7)
    tab.rows_spin.setValue(5)
    tab.square_spin.setValue(30.0)
    s = ctx.settings
    assert (s.board_cols, s.board_rows, s.square_mm) == (7, 5, 30.0)
    assert tab.board == BoardSpec(7, 5, 30.0)


def test_live_through_frame_worker_freezes_on_board(tab, ctx, qtbot, tmp_path):
    tab.new_session(tmp_path / "live")
    ctx.frames.set_source(SimSource(mode="board", paced=False, frames_per_move=8))
    tab.set_active(True)
    qtbot.waitUntil(lambda: tab.state is CaptureState.REVIEW, timeout=30000)
    assert tab.frozen is not None and tab.frozen.detection.found
    with qtbot.waitSignal(tab.pairSaved, timeout=30000):
        tab.save_frozen()
    assert len(CaptureSession.open(tmp_path / "live").pairs) == 1


def test_keys_s_and_c_save_and_cancel(tab, tmp_path, qtbot):
    from PySide6.QtCore import Qt

    tab.new_session(tmp_path / "keys")
    tab.show()
    with qtbot.waitActive(tab):
        tab.activateWindow()
    tab.view.setFocus()
    frames = _board_frames()
    out, frame = frames[0]
    tab.show_output(out, frame)
    assert tab.state is CaptureState.REVIEW
    qtbot.keyClick(tab, Qt.Key.Key_C)
    # a shortcut animates the click
    qtbot.waitUntil(lambda: tab.state is CaptureState.LIVE, timeout=3000)
    tab.rules.last_reviewed_pose = None  # as if the board had left the view in between
    tab.show_output(out, frame)
    assert tab.state is CaptureState.REVIEW
    with qtbot.waitSignal(tab.pairSaved, timeout=30000):
        qtbot.keyClick(tab, Qt.Key.Key_S)
    assert len(CaptureSession.open(tmp_path / "keys").pairs) == 1


def test_list_follows_exclusions_made_elsewhere(tab, tmp_path, qtbot):
    (tmp_path / "ex").mkdir()
    folder = write_calibration_set(tmp_path / "ex", n_pairs=3, seed=4)
    tab.open_session(folder)
    qtbot.waitUntil(lambda: not tab.scanning(), timeout=20000)
    name = tab.saved_names()[1]
    CaptureSession.open(folder).set_excluded(name, True)  # as the Calibration tab does
    tab.set_active(True)
    assert "(excluded)" in tab.pair_list.item(1).text()
    assert "(excluded)" not in tab.pair_list.item(0).text()


@pytest.mark.slow
def test_a_new_source_without_a_board_drops_the_frozen_pair(tab, ctx, qtbot, tmp_path, sim_rig):
    """A pair frozen from the previous source is not offered (Save enabled)
    once the source is a folder whose pairs show no board; the view shows the new frames."""
    from stereo_gui.sources.playback import PlaybackSource
    from stereo_gui.sources.sim import Scene

    rng = np.random.default_rng(5)
    folder = tmp_path / "no-board"
    folder.mkdir()
    for k in (1, 2):
        left, right = sim_rig.render_scene(Scene.wall(1200.0 + 300 * k), rng)
        cv2.imwrite(str(folder / f"left{k}.png"), left)
        cv2.imwrite(str(folder / f"right{k}.png"), right)
    tab.set_active(True)
    ctx.frames.set_source(SimSource(rig=sim_rig, mode="board", paced=False, frames_per_move=8))
    qtbot.waitUntil(lambda: tab.state is CaptureState.REVIEW, timeout=30000)
    assert tab.save_button.isEnabled()
    ctx.frames.set_source(PlaybackSource(folder, fps=20))
    assert tab.state is CaptureState.LIVE and tab.frozen is None
    assert not tab.save_button.isEnabled()
    assert tab.view.images[0].image is None  # not the old picture while the new one comes
    n = tab.frames_shown
    qtbot.waitUntil(lambda: tab.frames_shown >= n + 3, timeout=30000)
    assert tab.state is CaptureState.LIVE and not tab.save_button.isEnabled()
    shown = tab.shown_frame.left
    assert any(np.array_equal(shown, cv2.imread(str(folder / f"left{k}.png"))) for k in (1, 2))
    assert "Hold the" in tab.prompt.text()


def test_keyboard_selection_shows_the_pair_and_delete_deletes_what_is_shown(
        tab, tmp_path, qtbot, monkeypatch, questions):
    """Moving through the saved pairs with the keyboard shows each pair, and
    Delete pair asks about (and deletes) the pair on screen, never another one."""
    from PySide6.QtCore import Qt

    (tmp_path / "set").mkdir()
    folder = write_calibration_set(tmp_path / "set", n_pairs=4, seed=3)
    tab.open_session(folder)
    qtbot.waitUntil(lambda: not tab.scanning(), timeout=20000)
    names = tab.saved_names()
    tab.show()
    tab.pair_list.setFocus()
    tab.show_saved_pair(names[0])  # as a click
    assert tab.shown_pair == names[0]
    qtbot.keyClick(tab.pair_list, Qt.Key.Key_Down)
    qtbot.keyClick(tab.pair_list, Qt.Key.Key_Down)
    assert tab.state is CaptureState.SAVED and tab.shown_pair == names[2]
    assert tab.saved_panel.current_name() == names[2]
    assert f"saved pair {names[2]}" in tab.view.titles[0].text
    qtbot.keyClick(tab.pair_list, Qt.Key.Key_Delete)  # the Del key in the list: Delete pair
    assert questions.asked and f"pair {names[2]}?" in questions.asked[0]
    assert tab.saved_names() == [names[0], names[1], names[3]]
    assert tab.state is CaptureState.LIVE and tab.saved_panel.current_name() is None
    assert not tab.delete_button.isEnabled()  # nothing on screen to delete


def test_new_session_in_a_folder_with_files_asks_before_writing_into_it(
        tab, tmp_path, monkeypatch, questions):
    """New session… in a non-empty folder without a session asks first; No
    writes nothing there, Yes starts the session (the pairs there are listed)."""
    from PySide6.QtWidgets import QMessageBox

    from stereo_gui.qt.widgets import folder_dialog

    folder = tmp_path / "photos"
    folder.mkdir()
    write_calibration_set(folder, n_pairs=2, seed=3)
    (folder / "notes.txt").write_text("holiday")
    before = sorted(p.name for p in folder.iterdir())
    monkeypatch.setattr(folder_dialog, "choose_folder", lambda *a, **k: str(folder))
    asked = questions.asked
    questions.reply = QMessageBox.StandardButton.No
    tab.new_button.click()
    assert asked and "not empty" in asked[0] and "2 image pairs" in asked[0]
    assert tab.session is None
    assert sorted(p.name for p in folder.iterdir()) == before  # no session.json
    questions.reply = QMessageBox.StandardButton.Yes
    tab.new_button.click()
    assert tab.session is not None and (folder / "session.json").exists()
    assert len(tab.session.pairs) == 2
    # an empty folder is not asked about
    empty = tmp_path / "empty"
    empty.mkdir()
    monkeypatch.setattr(folder_dialog, "choose_folder", lambda *a, **k: str(empty))
    asked.clear()
    tab.new_button.click()
    assert not asked and (empty / "session.json").exists()


def test_new_session_in_a_session_folder_offers_to_open_it(tab, tmp_path, monkeypatch, qtbot):
    from PySide6.QtWidgets import QMessageBox

    from stereo_gui.qt.widgets import folder_dialog

    folder = tmp_path / "s"
    CaptureSession.create(folder, BoardSpec(), (640, 480))
    monkeypatch.setattr(folder_dialog, "choose_folder", lambda *a, **k: str(folder))
    monkeypatch.setattr(QMessageBox, "question",
                        lambda *a, **k: QMessageBox.StandardButton.Yes)
    tab.new_button.click()
    assert tab.session is not None and tab.session.folder == folder


@pytest.mark.slow
def test_a_saved_pair_is_scrolled_into_view_and_counted_in_words(tab, tmp_path, qtbot):
    """The saved-pairs list shows the pair just saved (not the top of a long
    list); "1 pair kept", "2 pairs kept"."""
    from PySide6.QtCore import Qt

    (tmp_path / "set").mkdir()
    folder = write_calibration_set(tmp_path / "set", n_pairs=12, seed=3)
    tab.open_session(folder)
    qtbot.waitUntil(lambda: not tab.scanning(), timeout=20000)
    tab.resize(1000, 600)
    tab.show()
    qtbot.waitExposed(tab)
    lst = tab.pair_list
    lst.scrollToTop()
    out, frame = _board_frames()[0]
    tab.show_output(out, frame)
    with qtbot.waitSignal(tab.pairSaved, timeout=30000) as blocker:
        tab.save_button.click()
    last = lst.item(lst.count() - 1)
    assert last.data(Qt.ItemDataRole.UserRole) == blocker.args[0]
    assert lst.viewport().rect().intersects(lst.visualItemRect(last))
    assert not lst.viewport().rect().intersects(lst.visualItemRect(lst.item(0)))
    assert "13 pairs kept" in tab.coverage.count_label.text()
    from stereo_gui.qt.widgets.coverage import pairs_kept

    assert (pairs_kept(1), pairs_kept(2), pairs_kept(0)) == (
        "1 pair kept", "2 pairs kept", "0 pairs kept")


def test_new_session_in_a_folder_typed_that_does_not_exist_yet_creates_it(
        tab, tmp_path, questions, qtbot):
    """The folder dialog: a new folder's name typed and OK offers to create it (Qt's own
    dialog said "Directory not found"); No keeps the dialog open, Yes creates the folder and
    the session goes there."""
    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QApplication, QDialog, QMessageBox

    from stereo_gui.qt.widgets.folder_dialog import FolderDialog

    new = tmp_path / "calib-2026-11-22"
    seen = []

    def answer_dialog():
        dialog = next(w for w in QApplication.topLevelWidgets()
                      if isinstance(w, FolderDialog) and w.isVisible())
        dialog.selectFile(str(new))
        questions.reply = QMessageBox.StandardButton.No
        dialog.accept()
        seen.append((dialog.isVisible(), new.exists()))
        questions.reply = QMessageBox.StandardButton.Yes
        dialog.accept()
        seen.append((dialog.result() == QDialog.DialogCode.Accepted, new.is_dir()))

    QTimer.singleShot(0, answer_dialog)
    tab.new_button.click()
    assert seen == [(True, False), (True, True)]
    assert "There is no folder" in questions.asked[0] and str(new) in questions.asked[0]
    assert tab.session is not None and tab.session.folder == new
    assert (new / "session.json").exists()
