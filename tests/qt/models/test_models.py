"""The application's models without a window: each changes only through its methods and says so
once by its signal; files are read and written through them; workers stop together."""

from __future__ import annotations

import pytest

from stereo_gui.files.measurement_log import load_log
from stereo_gui.files.settings import Settings, load_settings
from stereo_gui.files.spreadsheet import MeasurementRecord
from stereo_gui.qt.context import AppContext
from stereo_gui.qt.models import TRUE_CALIBRATION_NOTE


def _record(z_mm: float) -> MeasurementRecord:
    return MeasurementRecord(time="2026-01-02T10:11:12+00:00", x_px=320.0, y_px=240.0,
                             disparity_px=40.0, X_mm=0.0, Y_mm=0.0, Z_mm=z_mm, range_mm=z_mm,
                             valid=True, valid_fraction=1.0, expected_error_mm=1.0)


class _Announced:
    """Collects what a signal announced."""

    def __init__(self, signal):
        self.args: list = []
        signal.connect(lambda *a: self.args.append(a))


# ---- settings ---------------------------------------------------------------------------------
def test_settings_change_only_through_the_model_and_each_change_is_announced(ctx):
    changed = _Announced(ctx.settings_model.changed)
    ctx.settings_model.update(patch_size=7)
    assert ctx.settings.patch_size == 7 and changed.args[-1][0] is ctx.settings
    ctx.settings_model.remember_recent("/a/b.yaml")
    ctx.settings_model.remember_recent("/a/b.yaml")  # already first: nothing changes
    assert ctx.settings.recent_files[0] == "/a/b.yaml" and len(changed.args) == 2
    with pytest.raises(AttributeError):
        ctx.settings = Settings()  # a read-only view of the model
    with pytest.raises(TypeError):
        ctx.settings_model.update(no_such_setting=1)


def test_settings_are_saved_where_the_next_start_reads_them(ctx):
    ctx.settings_model.update(preset="seed", window_geometry="AAAA")
    assert ctx.settings_model.save()
    saved, warnings = load_settings()
    assert not warnings and saved.preset == "seed" and saved.window_geometry == "AAAA"


# ---- calibration ------------------------------------------------------------------------------
def test_a_calibration_is_announced_once_with_where_it_came_from(ctx, sim_rig):
    changed = _Announced(ctx.calibration_model.changed)
    calib = sim_rig.true_calibration()
    ctx.calibration_model.set(calib, None, note=TRUE_CALIBRATION_NOTE)
    assert changed.args == [(calib,)]
    assert ctx.calibration is calib and ctx.calibration_path is None
    assert ctx.calibration_note == TRUE_CALIBRATION_NOTE
    assert ctx.settings.sim_true_calibration  # chosen again at the next start on the rig
    ctx.calibration_model.set(None)
    assert ctx.calibration is None and not ctx.settings.sim_true_calibration


def test_calibration_files_round_trip_through_the_model(ctx, sim_rig, tmp_path):
    errors = _Announced(ctx.errorOccurred)
    calib = sim_rig.true_calibration()
    path = tmp_path / "rig.yaml"
    assert ctx.calibration_model.save_file(calib, path)
    assert ctx.calibration_path == path and ctx.settings.recent_files[0] == str(path)
    assert ctx.settings.last_calibration == str(path.resolve())
    ctx.calibration_model.set(None)
    assert ctx.calibration_model.open_file(path)
    assert ctx.calibration.image_size == calib.image_size
    assert not ctx.calibration_model.open_file(tmp_path / "none.yaml")
    assert "none.yaml" in errors.args[-1][0] and ctx.calibration_path == path
    left, right = ctx.calibration_model.export_ros(tmp_path)
    assert ctx.calibration_model.import_ros(left, right)
    assert ctx.calibration_path is None and ctx.calibration_note == "ROS left.yaml + right.yaml"


# ---- the measurement log ----------------------------------------------------------------------
def test_clear_can_be_undone_until_the_next_reading(ctx):
    log = ctx.measurement_log
    changed = _Announced(log.changed)
    log.add(_record(1000.0))
    log.add(_record(2000.0))
    log.clear()
    assert log.records == () and log.can_undo_clear
    assert log.undo_clear() and [r.Z_mm for r in log.records] == [1000.0, 2000.0]
    log.clear()
    log.add(_record(3000.0))  # a reading after Clear: the cleared ones are gone for good
    assert not log.can_undo_clear and not log.undo_clear()
    assert len(changed.args) == 6


def test_the_kept_log_is_saved_once_after_a_burst_of_changes(qtbot, ctx, tmp_path):
    path = tmp_path / "log.json"
    log = ctx.measurement_log
    assert log.keep(path) == [] and not log.save_pending  # restoring is no change
    for z in (1000.0, 2000.0, 3000.0):
        log.add(_record(z))
    assert log.save_pending and not path.exists()
    qtbot.waitUntil(lambda: path.exists() and not log.save_pending, timeout=10000)
    kept, warnings = load_log(path)
    assert not warnings and [r.Z_mm for r in kept.records] == [1000.0, 2000.0, 3000.0]
    other = AppContext()
    try:
        assert other.measurement_log.keep(path) == []
        assert [r.Z_mm for r in other.measurement_log.records] == [1000.0, 2000.0, 3000.0]
    finally:
        assert other.shutdown(2000)


def test_a_pending_save_is_written_at_shutdown(tmp_path):
    path = tmp_path / "log.json"
    c = AppContext()
    c.measurement_log.keep(path)
    c.measurement_log.add(_record(1500.0))
    assert c.shutdown(2000)
    assert [r.Z_mm for r in load_log(path)[0].records] == [1500.0]


# ---- workers ----------------------------------------------------------------------------------
class _Worker:
    def __init__(self, ok: bool = True, broken: bool = False):
        self.ok, self.broken, self.stopped_within = ok, broken, None

    def stop(self, timeout_ms: int = 2000) -> bool:
        self.stopped_within = timeout_ms
        if self.broken:
            raise RuntimeError("broken")
        return self.ok


def test_every_registered_worker_is_stopped_even_past_a_broken_one(ctx):
    broken, stuck, fine = _Worker(broken=True), _Worker(ok=False), _Worker()
    for w in (broken, stuck, fine):
        ctx.workers.register(w)
    ctx.workers.register(fine)  # once is enough
    assert not ctx.workers.shutdown(2000)
    assert all(w.stopped_within is not None and w.stopped_within <= 2000
               for w in (broken, stuck, fine))
    ctx.workers.unregister(broken)
    ctx.workers.unregister(stuck)
    assert ctx.workers.shutdown(2000)
