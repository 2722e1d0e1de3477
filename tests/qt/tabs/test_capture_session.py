"""The Capture tab's session and saved pairs as a part of their own: handed the settings, a
panel, the board and what the source is, they open and create sessions, read the saved pairs
off the UI thread for coverage, add and delete pairs, and say what went wrong."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from PySide6.QtWidgets import QWidget

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.errors import StereoGuiError
from stereo_gui.files.session import CaptureSession
from stereo_gui.qt.tabs.capture_session import SessionPairs
from stereo_gui.qt.widgets.saved_pairs import SavedPairsPanel
from stereo_gui.sources.sim import write_calibration_set

BOARD = BoardSpec(9, 6, 25.0)


@pytest.fixture(scope="module")
def pairs_folder(tmp_path_factory):
    """A plain folder of four chessboard pairs (no manifest)."""
    return write_calibration_set(tmp_path_factory.mktemp("pairs"), n_pairs=4, seed=5)


@pytest.fixture
def made(qtbot, ctx):
    """(SessionPairs, the boards it asked to adopt); the frames seen were 640x480 from "rig"."""
    owner = QWidget()
    qtbot.addWidget(owner)
    adopted: list[BoardSpec] = []
    pairs = SessionPairs(ctx.settings_model, ctx, ctx.workers, SavedPairsPanel(owner),
                         lambda: BOARD, adopted.append, lambda: (640, 480), lambda: "rig", owner)
    yield pairs, adopted
    pairs.cancel_scan()


def test_a_new_session_records_the_board_the_size_and_the_cameras(ctx, made, qtbot, tmp_path):
    pairs, adopted = made
    with qtbot.waitSignal(pairs.sessionChanged) as changed:
        pairs.new_session(tmp_path / "s")
    session = changed.args[0]
    assert pairs.session is session
    again = CaptureSession.open(tmp_path / "s")
    assert again.board == BOARD and tuple(again.resolution) == (640, 480)
    assert (again.cameras.left, again.cameras.right) == ("rig left", "rig right")
    assert ctx.settings.last_session == str(session.folder) and adopted == []
    assert not pairs.scanning() and pairs.saved_names() == []


def test_opening_a_session_adopts_its_board_and_reads_its_pairs_for_coverage(
        made, qtbot, pairs_folder, tmp_path):
    pairs, adopted = made
    folder = tmp_path / "session"
    shutil.copytree(pairs_folder, folder)
    other = BoardSpec(7, 5, 30.0)
    CaptureSession.create(folder, other)
    with qtbot.waitSignal(pairs.pairsChanged, timeout=30000):
        pairs.open_session(folder)
        assert pairs.scanning()
    assert adopted == [other]
    assert not pairs.scanning() and len(pairs.saved_names()) == 4
    # (the pairs show a 9x6 board, the one in use here: found in every one)
    assert len(pairs.saved_poses()) == 4


def test_pairs_are_added_and_deleted_with_their_files(ctx, made, qtbot, tmp_path):
    pairs, _ = made
    said = []
    ctx.statusMessage.connect(said.append)
    pairs.new_session(tmp_path / "s")
    img = np.zeros((480, 640, 3), np.uint8)
    name = pairs.add_pair(img, img, None)
    assert name is not None and pairs.saved_names() == [name]
    left, right, det = pairs.load_pair(name)
    assert left.shape == (480, 640, 3) and det is None
    assert said[-1] == f"Saved pair {name} to {pairs.session.folder}"
    with qtbot.waitSignal(pairs.pairsChanged):
        assert pairs.delete_pair(name)
    assert pairs.saved_names() == [] and said[-1] == f"Deleted pair {name}"
    assert list((tmp_path / "s").glob("*.png")) == []
    with pytest.raises(StereoGuiError, match="no longer in the session"):
        pairs.load_pair(name)


def test_what_cannot_be_done_is_said(ctx, made, tmp_path):
    pairs, _ = made
    errors = []
    ctx.errorOccurred.connect(errors.append)
    assert not pairs.delete_pair("1")  # no session: nothing to delete, nothing said
    assert not pairs.reload()
    pairs.new_session(tmp_path / "s")
    assert pairs.add_pair(np.zeros((10, 10, 3), np.uint8), np.zeros((12, 10, 3), np.uint8),
                          None) is None
    assert len(errors) == 1 and errors[0].startswith("could not save the pair")
    assert not pairs.delete_pair("7")
    assert errors[-1].startswith("could not delete pair 7")
