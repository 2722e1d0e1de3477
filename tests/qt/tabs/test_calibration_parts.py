"""The Calibration tab's parts on their own: the session it works on (`SessionFolder`), the
review of single pairs (`PairReview`) and the one-click actions (`CalibrationActions`), each
handed what it uses."""

from __future__ import annotations

import dataclasses
import shutil

import pytest
from PySide6.QtWidgets import QCheckBox, QWidget

from stereo_gui.core.errors import InputError
from stereo_gui.files.session import CaptureSession
from stereo_gui.qt.tabs.calibration_actions import CalibrationActions
from stereo_gui.qt.tabs.calibration_pairs import PairReview, SessionFolder


@pytest.fixture
def run(calibration_run, tmp_path):
    """The run, over a copy of its session (exclusions written here stay here)."""
    folder = tmp_path / "session"
    shutil.copytree(calibration_run.folder, folder)
    return dataclasses.replace(calibration_run, folder=folder)


@pytest.fixture
def owner(qtbot):
    w = QWidget()
    qtbot.addWidget(w)
    return w


def _review(ctx, owner, run, running=False):
    return PairReview(ctx.calibration_model, lambda: run,
                      SessionFolder(lambda: run.folder if run is not None else None), ctx,
                      ctx.workers, lambda: running, owner)


# ---- SessionFolder ---------------------------------------------------------------------------
def test_without_a_folder_there_is_no_session_and_nothing_excluded(tmp_path):
    none = SessionFolder(lambda: None)
    assert not none.named() and none.excluded() == [] and none.pair("1") is None
    with pytest.raises(InputError, match="choose the folder"):
        none.open()
    assert none.swapped() is None


def test_a_folder_is_read_again_at_each_use(run):
    session = SessionFolder(lambda: run.folder)
    name = sorted(run.files)[0]
    assert session.named() and session.excluded() == [] and session.swapped() is False
    CaptureSession.open(run.folder).set_excluded(name, True)  # (another tab, meanwhile)
    assert session.excluded() == [name] and session.pair(name).excluded


# ---- PairReview ------------------------------------------------------------------------------
def test_a_run_shown_selects_its_first_pair_and_rectifies_it_off_the_ui_thread(
        qtbot, ctx, owner, run):
    review = _review(ctx, owner, run)
    calib = run.result.calibration
    ctx.calibration_model.set(calib, None)
    review.show(calib)
    names = [p.name for p in calib.per_pair]
    assert review.chart.names == names and review.selected_pair == names[0]
    qtbot.waitUntil(lambda: review.rect_view.shown == names[0], timeout=10000)
    assert review.rejected_lines() == ["none"]
    assert review.exclude_button.isEnabled() and review.exclude_button.text() == "Exclude pair"


def test_excluding_writes_the_session_and_lists_the_pair(ctx, owner, run):
    review = _review(ctx, owner, run)
    calib = run.result.calibration
    ctx.calibration_model.set(calib, None)
    review.show(calib)
    said = []
    ctx.statusMessage.connect(said.append)
    name = review.chart.names[1]
    review.select_pair(name)
    review.exclude_button.click()
    assert CaptureSession.open(run.folder).pair(name).excluded
    assert said == [f"Pair {name} excluded: press Recalibrate"]
    assert review.rejected_lines() == [f"{name}: excluded (Recalibrate leaves it out)"]
    assert review.chart.excluded_bars() == [name]
    assert review.exclude_button.text() == "Include pair again"
    review.exclude_button.click()
    assert not CaptureSession.open(run.folder).pair(name).excluded
    assert review.rejected_lines() == ["none"] and review.chart.excluded_bars() == []


def test_pairs_above_a_threshold_are_excluded_at_once(ctx, owner, run):
    review = _review(ctx, owner, run)
    calib = run.result.calibration
    ctx.calibration_model.set(calib, None)
    review.show(calib)
    errors = {p.name: max(p.error_left, p.error_right) for p in calib.per_pair}
    review.threshold_spin.setValue(sorted(errors.values())[-3])  # (to the box's 0.001 px)
    px = review.threshold_spin.value()
    above = {n for n, e in errors.items() if e > px}
    assert 0 < len(above) < len(errors)
    n = len(above)
    assert review.exclude_above_button.text() == f"Exclude {n} pair{'s' if n != 1 else ''} above"
    assert set(review.exclude_above(px)) == above
    session = CaptureSession.open(run.folder)
    assert {p.name for p in session.pairs if p.excluded} == above
    assert review.pairs_above(px) == [] and not review.exclude_above_button.isEnabled()


def test_nothing_is_excluded_while_a_calibration_runs(ctx, owner, run):
    review = _review(ctx, owner, run, running=True)
    calib = run.result.calibration
    ctx.calibration_model.set(calib, None)
    review.show(calib)
    review.threshold_spin.setValue(0.0)
    assert not review.exclude_button.isEnabled()
    assert not review.exclude_above_button.isEnabled()


def test_a_calibration_without_a_run_has_no_images_to_show(ctx, owner, run):
    review = _review(ctx, owner, None)
    calib = run.result.calibration
    ctx.calibration_model.set(calib, None)
    review.show(calib)
    assert review.selected_pair is None and review.rejected_lines() == ["none"]
    review.select_pair(review.chart.names[0])
    assert "images not available" in review.rect_view.title.text
    assert not review.exclude_button.isEnabled()  # no session named: nothing to exclude in
    ctx.calibration_model.set(None)
    review.show(None)
    assert review.chart.bar_count() == 0 and review.rejected_lines() == []


# ---- CalibrationActions ----------------------------------------------------------------------
@pytest.fixture
def acted(ctx, owner, run):
    """(CalibrationActions on the run's session, the Fix k3 box, the calibrations started)."""
    started: list[bool] = []
    fix_k3 = QCheckBox("Fix k3", owner)
    actions = CalibrationActions(ctx.calibration_model, SessionFolder(lambda: run.folder), ctx,
                                 lambda: started.append(True) or True, fix_k3,
                                 lambda: str(run.folder), owner)
    return actions, fix_k3, started


def test_the_fix_k3_remedy_holds_k3_and_recalibrates(acted):
    actions, fix_k3, started = acted
    assert not actions.apply_remedy("something else") and started == []
    assert actions.apply_remedy("fix_k3")
    assert fix_k3.isChecked() and started == [True]


def test_the_swap_remedy_is_recorded_in_the_session_before_recalibrating(acted, run):
    actions, _fix_k3, started = acted
    actions.show_session_swap()
    assert actions.swap_check.isEnabled() and not actions.swap_check.isChecked()
    assert actions.apply_remedy("swap")
    assert CaptureSession.open(run.folder).swapped and started == [True]
    actions.swap_check.setChecked(False)  # the box, by hand: the session forgets it
    assert not CaptureSession.open(run.folder).swapped and started == [True]


def test_the_swap_box_is_off_without_a_folder(ctx, owner):
    actions = CalibrationActions(ctx.calibration_model, SessionFolder(lambda: None), ctx,
                                 lambda: True, QCheckBox(owner), lambda: "", owner)
    actions.show_session_swap()
    assert not actions.swap_check.isEnabled() and not actions.swap_check.isChecked()


def test_save_and_load_go_through_the_calibration_model(ctx, acted, run, tmp_path):
    actions, _fix_k3, _started = acted
    ctx.calibration_model.set(run.result.calibration, None)
    path = tmp_path / "rig.yaml"
    assert actions.save_calibration(path) and path.is_file()
    assert ctx.calibration_path == path
    ctx.calibration_model.set(None)
    assert actions.load_calibration(path) and ctx.calibration_path == path
    errors = []
    ctx.errorOccurred.connect(errors.append)
    assert not actions.load_calibration(tmp_path / "missing.yaml")
    assert len(errors) == 1 and "missing.yaml" in errors[0]
