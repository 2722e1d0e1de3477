"""Closing the window never throws work away without asking: an unsaved calibration asks Save /
Discard / Cancel, a running export is waited for (or cancelled, and the user told, with nothing
half-written left), a true distance typed just before closing is in the kept log.

The dialogs are the real ones: a timer finds the modal dialog when it is shown and presses one
of its buttons, as a person would."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication, QMessageBox

import stereo_gui.files.spreadsheet as spreadsheet
import stereo_gui.qt.dialogs.closing as closing
from stereo_gui.core.states import TransitionError
from stereo_gui.files.measurement_log import load_log
from stereo_gui.files.spreadsheet import MeasurementRecord
from stereo_gui.qt.main_window import CLOSE_MOVES, ClosePhase, CloseState, MainWindow
from stereo_gui.qt.widgets.measurement_table import TRUE_COL


@pytest.mark.parametrize("a,b", [(a, b) for a in ClosePhase for b in ClosePhase])
def test_closing_moves_only_as_the_window_does(a, b):
    """Waiting for work and closing start from an open window; the waiter ends once, back to
    OPEN; nothing follows CLOSING."""
    real = {(ClosePhase.OPEN, ClosePhase.WAITING), (ClosePhase.OPEN, ClosePhase.CLOSING),
            (ClosePhase.WAITING, ClosePhase.OPEN)}
    assert CLOSE_MOVES.allows(a, b) == ((a, b) in real)


def test_a_new_attempt_to_close_forgets_the_answers_but_never_reopens_a_closing_window():
    state = CloseState(calibration_discarded=True)
    state.move(ClosePhase.WAITING)
    state.start_over(work_settled=True)
    assert (state.phase, state.calibration_discarded, state.work_settled) == (
        ClosePhase.OPEN, False, True)
    state.move(ClosePhase.CLOSING)
    with pytest.raises(TransitionError):
        state.start_over()


class Dialogs:
    """Answers the modal dialogs the window shows: `answer(name, press)` queues `press(dialog)`
    for the next dialog whose objectName is `name`; `seen` keeps (name, text) of each."""

    def __init__(self):
        self.seen: list[tuple[str, str]] = []
        self.queue: list[tuple[str, object]] = []
        self.timer = QTimer()
        self.timer.setInterval(20)
        self.timer.timeout.connect(self.look)
        self.timer.start()

    def answer(self, name: str, press) -> None:
        self.queue.append((name, press))

    def look(self) -> None:
        if not self.queue:
            return
        dlg = QApplication.activeModalWidget()
        name, press = self.queue[0]
        if dlg is None or dlg.objectName() != name or not dlg.isVisible():
            return
        self.queue.pop(0)
        text = dlg.text() + "\n" + dlg.informativeText() if isinstance(dlg, QMessageBox) \
            else dlg.label.text()
        self.seen.append((name, text))
        press(dlg)

    def stop(self) -> None:
        self.timer.stop()


@pytest.fixture
def dialogs(qtbot):
    d = Dialogs()
    yield d
    d.stop()
    assert not d.queue, f"dialogs never shown: {[n for n, _ in d.queue]}"


def button(std):
    return lambda box: box.button(std).click()


@pytest.fixture
def win(qtbot, ctx):
    w = MainWindow(ctx)  # not qtbot.addWidget: its closing at teardown would ask again
    w.show()
    qtbot.waitExposed(w)
    yield w
    if w.isVisible():  # left open by the test: close without asking again
        w.close_without_asking()
    w.deleteLater()


def closed(w) -> bool:
    return not w.isVisible()


# ---- an unsaved calibration ------------------------------------------------------------------
@pytest.mark.slow
def test_unsaved_calibration_cancel_keeps_the_window_open(win, ctx, calibration_run, dialogs):
    win.calibration_tab.use_run(calibration_run)  # what the tab does when its job is done
    assert "calibrated from" in win.calibration_tab.unsaved_calibration()
    dialogs.answer("unsaved-calibration", button(QMessageBox.StandardButton.Cancel))
    win.close()
    assert not closed(win) and ctx.calibration is calibration_run.result.calibration
    name, text = dialogs.seen[0]
    assert "not saved" in text and str(calibration_run.folder) in text


def test_unsaved_calibration_discard_closes(qtbot, win, ctx, calibration_run, dialogs):
    win.calibration_tab.use_run(calibration_run)
    dialogs.answer("unsaved-calibration", button(QMessageBox.StandardButton.Discard))
    win.close()
    assert closed(win) and len(dialogs.seen) == 1


def test_unsaved_calibration_save_writes_it_then_closes(qtbot, win, ctx, calibration_run,
                                                       dialogs, tmp_path, monkeypatch):
    import stereo_gui.qt.main_window as mw
    from stereo_gui.files.calibration_file import load_calibration

    win.calibration_tab.use_run(calibration_run)
    # Save, but the file dialog is cancelled: nothing written, the window stays
    monkeypatch.setattr(mw.QFileDialog, "getSaveFileName", lambda *a, **k: ("", ""))
    dialogs.answer("unsaved-calibration", button(QMessageBox.StandardButton.Save))
    win.close()
    assert not closed(win)
    target = tmp_path / "rig.yaml"
    monkeypatch.setattr(mw.QFileDialog, "getSaveFileName", lambda *a, **k: (str(target), ""))
    dialogs.answer("unsaved-calibration", button(QMessageBox.StandardButton.Save))
    win.close()
    assert closed(win)
    saved = load_calibration(target)
    assert np.allclose(saved.M1, calibration_run.result.calibration.M1)
    assert ctx.settings.last_calibration == str(target.resolve())


def test_a_saved_or_loaded_calibration_closes_without_asking(win, ctx, calibration_run, dialogs,
                                                             tmp_path, sim_rig):
    win.calibration_tab.use_run(calibration_run)
    assert win.save_calibration(str(tmp_path / "c.yaml"))
    assert win.calibration_tab.unsaved_calibration() == ""
    ctx.calibration_model.set(sim_rig.true_calibration(), None,
                              note="simulated rig's TRUE calibration")
    assert win.calibration_tab.unsaved_calibration() == ""  # not the tab's work: nothing lost
    win.close()
    assert closed(win) and not dialogs.seen


# ---- the measurement log ---------------------------------------------------------------------
def _reading(i: int, true_mm=None) -> MeasurementRecord:
    return MeasurementRecord(time="2024-05-01T12:00:00+00:00", x_px=10.0 + i % 600, y_px=20.0,
                             disparity_px=40.0 + (i % 50) * 0.5, X_mm=1.0, Y_mm=2.0,
                             Z_mm=1500.0 + i % 100, range_mm=1501.0, valid=True,
                             valid_fraction=0.9, expected_error_mm=5.0, true_mm=true_mm)


def test_a_true_distance_typed_just_before_closing_is_kept(qtbot, win, ctx, tmp_path):
    log = tmp_path / "log.json"
    ctx.measurement_log.keep(log)
    for i in range(3):
        ctx.measurement_log.add(_reading(i))
    table = win.measurements_tab.table
    model = table.model()
    # entered (Enter pressed) and the window closed at once, before the log's save timer
    assert model.setData(model.index(0, TRUE_COL), "1234")
    # still being typed in its cell when the window closes
    win.show_tab("measurements")
    table.setFocus()
    index = model.index(2, TRUE_COL)
    table.setCurrentIndex(index)
    table.edit(index)
    editor = QApplication.focusWidget()
    assert editor is not None and table.isAncestorOf(editor)
    editor.setText("2500")
    win.close()
    assert closed(win)
    kept, warnings = load_log(log)
    assert not warnings
    assert [r.true_mm for r in kept.records] == [1234.0, None, 2500.0]


# ---- a running export ------------------------------------------------------------------------
@pytest.fixture
def held_export(monkeypatch):
    """The real workbook writer, held after its first rows until `gate` is set (or it is
    cancelled): an export still running when the window is closed."""
    gate = threading.Event()
    real = spreadsheet.write_workbook

    def held(path, records, *args, cancel=None, progress=None, **kwargs):
        def hold(done, total, text):
            progress(done, total, text)
            while not gate.is_set() and not cancel():
                gate.wait(0.01)

        return real(path, records, *args, cancel=cancel, progress=hold, **kwargs)

    monkeypatch.setattr(spreadsheet, "write_workbook", held)
    return gate


def _start_export(qtbot, win, ctx, path, n=2000):
    ctx.measurement_log.add_many([_reading(i, 1500.0 if i % 2 else None) for i in range(n)])
    assert win.measurements_tab.export_xlsx(path)
    qtbot.waitUntil(lambda: "500 of 2,000 rows" in " ".join(win.unfinished_work()),
                    timeout=30000)


def _waiter(qtbot, win):
    qtbot.waitUntil(lambda: win.close_waiter() is not None and win.close_waiter().isVisible(),
                    timeout=10000)
    return win.close_waiter()


@pytest.mark.slow
def test_closing_waits_for_a_running_export_then_closes(qtbot, win, ctx, held_export, tmp_path):
    path = tmp_path / "m.xlsx"
    _start_export(qtbot, win, ctx, path)
    win.close()
    waiter = _waiter(qtbot, win)
    assert not closed(win)
    assert "the export of the measurement log to m.xlsx (500 of 2,000 rows)" in \
        waiter.label.text()
    assert "Waiting at most 60 s more" in waiter.label.text()
    held_export.set()  # the export goes on and ends: the window closes by itself
    qtbot.waitUntil(lambda: closed(win), timeout=60000)
    assert len(spreadsheet.read_measurements(path)) == 2000


def test_insisting_cancels_the_export_says_so_and_leaves_nothing(qtbot, win, ctx, held_export,
                                                                 tmp_path, dialogs):
    path = tmp_path / "m.xlsx"
    path.write_bytes(b"an earlier export")
    _start_export(qtbot, win, ctx, path)
    win.close()
    waiter = _waiter(qtbot, win)
    dialogs.answer("export-cancelled", lambda box: box.accept())
    waiter.cancel_button.click()
    qtbot.waitUntil(lambda: closed(win), timeout=30000)
    _name, text = dialogs.seen[0]
    assert f"The export to {path} was cancelled: nothing was written (m.xlsx was left as it " \
           "was)." in text
    assert path.read_bytes() == b"an earlier export"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.xlsx"]  # no temporary file left


def test_closing_again_while_waiting_is_insisting(qtbot, win, ctx, held_export, tmp_path,
                                                  dialogs):
    path = tmp_path / "m.xlsx"
    _start_export(qtbot, win, ctx, path)
    win.close()
    _waiter(qtbot, win)
    dialogs.answer("export-cancelled", lambda box: box.accept())
    win.close()
    qtbot.waitUntil(lambda: closed(win), timeout=30000)
    assert "was cancelled: nothing was written." in dialogs.seen[0][1]
    assert not list(tmp_path.iterdir())


def test_an_export_that_does_not_finish_in_time_is_cancelled(qtbot, win, ctx, held_export,
                                                            tmp_path, dialogs, monkeypatch):
    monkeypatch.setattr(closing, "CLOSE_WAIT_S", 0.5)
    _start_export(qtbot, win, ctx, tmp_path / "m.xlsx")
    dialogs.answer("export-cancelled", lambda box: box.accept())
    win.close()
    qtbot.waitUntil(lambda: closed(win), timeout=30000)
    assert "did not finish within 0.5 s of closing; it was cancelled" in dialogs.seen[0][1]
    assert not list(tmp_path.iterdir())


def test_dont_close_keeps_the_window_and_the_export(qtbot, win, ctx, held_export, tmp_path):
    path = tmp_path / "m.xlsx"
    _start_export(qtbot, win, ctx, path)
    win.close()
    waiter = _waiter(qtbot, win)
    waiter.keep_button.click()
    assert not closed(win) and win.close_waiter() is None
    with qtbot.waitSignal(win.measurements_tab.exportFinished, timeout=60000):
        held_export.set()
    assert path.is_file()
    win.close()  # nothing runs any more: closes at once
    assert closed(win)


def test_a_queued_snapshot_is_waited_for_or_cancelled(qtbot, win, ctx, sim_rig, wall_pair,
                                                     array_source, tmp_path, dialogs):
    _scene, left, right = wall_pair
    ctx.calibration_model.set(sim_rig.true_calibration(), None)
    win.show_tab("live")
    with qtbot.waitSignal(win.live_tab.frameShown, timeout=60000):
        ctx.frames.set_source(array_source(left, right, fps=30))
    gate = threading.Event()
    ctx.jobs.submit(lambda _control: gate.wait(30))  # the job thread is busy: the snapshot waits
    assert win.live_tab.snapshot(tmp_path) is not None
    win.close()
    waiter = _waiter(qtbot, win)
    assert f"the snapshot into {tmp_path}" in waiter.label.text()
    # the busy job ends once the snapshot was dropped (closing then joins the job thread)
    dialogs.answer("export-cancelled", lambda box: (gate.set(), box.accept()))
    waiter.insist()
    qtbot.waitUntil(lambda: closed(win), timeout=30000)
    assert f"The snapshot into {tmp_path} was cancelled: nothing was written." in \
        dialogs.seen[0][1]
    assert not list(tmp_path.iterdir())
