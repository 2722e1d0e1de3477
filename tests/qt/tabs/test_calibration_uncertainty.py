"""The Calibration tab: the lens model, each value with its 1-sigma uncertainty, the warnings and
their one-click remedies (swap the cameras and recalibrate; the session remembers)."""

from __future__ import annotations

import shutil

import pytest

from stereo_gui.files.session import CaptureSession
from stereo_gui.qt.tabs.calibration import CalibrationTab
from stereo_gui.sources.sim import write_calibration_set


@pytest.fixture(scope="module")
def calib_set(tmp_path_factory):
    return write_calibration_set(tmp_path_factory.mktemp("calset"), n_pairs=12, seed=23)


@pytest.fixture
def swapped_folder(calib_set, tmp_path):
    """The set with every pair's left and right images exchanged (the cameras plugged in the
    wrong way round)."""
    dst = tmp_path / "swapped"
    dst.mkdir()
    for f in calib_set.glob("chessboard-*.png"):
        name = f.name.replace("-L", "-X").replace("-R", "-L").replace("-X", "-R")
        shutil.copy(f, dst / name)
    return dst


def _calibrate(tab, qtbot, start=None):
    with qtbot.waitSignal(tab.calibrationFinished, timeout=120000) as blocker:
        if start is None:
            assert tab.start_calibration()
        else:
            start()
    qtbot.waitUntil(lambda: not tab.is_running(), timeout=30000)
    return blocker.args[0]


def test_values_show_their_uncertainty_and_the_model(make_tab, qtbot, calib_set, tmp_path):
    folder = tmp_path / "s"
    shutil.copytree(calib_set, folder)
    tab = make_tab(CalibrationTab)
    tab.folder_edit.setText(str(folder))
    tab.model_combo.setCurrentIndex(tab.model_combo.findData("pinhole"))
    run = _calibrate(tab, qtbot)
    c = run.result.calibration
    f = tab.figures
    assert "±" in f.baseline_label.text() and "±" in f.rotation_label.text()
    assert "fx" in f.left_label.text() and "±" in f.left_label.text()
    sigma = c.uncertainty.sigma("left.fx")
    assert f"±{sigma:.2f}" in f.left_label.text()
    assert "px left" in f.corners_label.text()
    assert "none worth undoing" in f.shading_label.text()  # the rig's corners are not darker
    assert "1 sigma" in f.model_label.text() and "pinhole" in f.model_label.text()
    assert "± 1 sigma" in tab.matrices_text.toPlainText()
    assert "swapped" not in [w.code for w in run.result.report.warnings]


def test_swapped_cameras_are_fixed_in_one_click_and_the_session_remembers(
        make_tab, ctx, qtbot, swapped_folder):
    tab = make_tab(CalibrationTab)
    tab.folder_edit.setText(str(swapped_folder))
    run = _calibrate(tab, qtbot)
    assert "swapped" in [w.code for w in run.result.report.warnings]
    assert "swap" in tab.warnings.buttons
    assert any("swapped" in t for t in tab.warnings.texts())
    button = tab.warnings.buttons["swap"]
    assert button.text() == "Swap the cameras and recalibrate"
    run = _calibrate(tab, qtbot, start=button.click)
    assert "swapped" not in [w.code for w in run.result.report.warnings]
    c = run.result.calibration
    assert c.swapped_inputs and c.T[0, 0] < 0
    assert CaptureSession.open(swapped_folder).swapped  # the session remembers
    assert tab.swap_check.isChecked()
    # and so does the next calibration, and the command line's
    again = _calibrate(tab, qtbot)
    assert again.result.calibration.swapped_inputs
    assert "swapped" not in [w.code for w in again.result.report.warnings]


def test_fix_k3_remedy_recalibrates_with_k3_held(make_tab, ctx, qtbot, calib_set, tmp_path):
    folder = tmp_path / "s"
    shutil.copytree(calib_set, folder)
    tab = make_tab(CalibrationTab)
    tab.folder_edit.setText(str(folder))
    run = _calibrate(tab, qtbot, start=lambda: tab.calibration_actions.apply_remedy("fix_k3"))
    assert tab.fix_k3_check.isChecked() and ctx.settings.fix_k3
    c = run.result.calibration
    assert c.D1[0, 4] == 0.0 and c.uncertainty.index("left.k3") is None
    assert "k3 fixed" in c.origin


@pytest.mark.slow
def test_the_lens_shading_is_measured_and_shown(make_tab, qtbot, tmp_path):
    from dataclasses import replace

    from stereo_gui.sources.sim import RigConfig

    folder = tmp_path / "dark-corners"
    folder.mkdir()
    write_calibration_set(folder, n_pairs=10, seed=23,
                          config=replace(RigConfig(), vignetting=0.3))
    tab = make_tab(CalibrationTab)
    tab.folder_edit.setText(str(folder))
    run = _calibrate(tab, qtbot)
    shading = run.result.calibration.lens_shading
    assert shading is not None and abs(shading.left.corner_loss - 0.3) < 0.04
    text = tab.figures.shading_label.text()
    assert "darker than the centre" in text and "undone before matching" in text
