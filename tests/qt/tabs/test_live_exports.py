"""The Live tab's depth exports of the frame shown (read back with their readers and compared with
the pipeline's values), and calibrations made at another resolution (scaled, or refused)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

import stereo_gui.files.depth_export as depth_export
from stereo_gui.qt.tabs.live import TRUE_CALIBRATION_NOTE


def _show_wall(qtbot, ctx, live, calib, wall_pair, array_source):
    _scene, left, right = wall_pair
    ctx.calibration_model.set(calib, None, note=TRUE_CALIBRATION_NOTE)
    ctx.frames.set_source(array_source(left, right, fps=30))
    with qtbot.waitSignal(live.frameShown, timeout=30000) as sig:
        pass
    live.set_paused(True)  # (at once: the frame signalled is the one the views show)
    return sig.args[0].result


def _read_ply(path):
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert header[:2] == ["ply", "format binary_little_endian 1.0"]
    n = int(next(line.split()[2] for line in header if line.startswith("element vertex")))
    props = [line.split()[2] for line in header if line.startswith("property")]
    assert props == ["x", "y", "z", "red", "green", "blue"]
    dtype = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"),
             ("blue", "u1")]
    vertices = np.frombuffer(data[end:], dtype=dtype)
    assert len(vertices) == n
    return vertices


def test_export_frame_writes_the_four_files_off_the_ui_thread(
        qtbot, ctx, live, sim_rig, wall_pair, array_source, tmp_path):
    import cv2

    result = _show_wall(qtbot, ctx, live, sim_rig.true_calibration(), wall_pair, array_source)
    d = result.final_px
    valid = np.isfinite(d)
    assert valid.mean() > 0.5
    with qtbot.waitSignal(ctx.jobs.finished, timeout=30000):
        job = live.export_frame(tmp_path)
    assert job is not None and len(live.last_export) == 4
    files = {p.name.split("-", 3)[-1]: p for p in live.last_export}
    assert set(files) == {"disparity-x16.png", "disparity.npy", "depth-mm.png", "cloud.ply"}
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left

    png = cv2.imread(str(files["disparity-x16.png"]), cv2.IMREAD_UNCHANGED)
    assert png.dtype == np.uint16 and png.shape == d.shape
    assert np.array_equal(png[valid], np.rint(d[valid] * 16).astype(np.uint16))
    assert not png[~valid].any()

    npy = np.load(files["disparity.npy"])
    assert npy.dtype == np.float32 and np.array_equal(npy, d, equal_nan=True)

    # depth through Q, written here from the matrix itself: Z = Q[2,3] / (Q[3,2] d + Q[3,3])
    Q = result.calibration.Q
    z = Q[2, 3] / (Q[3, 2] * d.astype(np.float64) + Q[3, 3])
    depth = cv2.imread(str(files["depth-mm.png"]), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16
    ok = depth > 0
    assert ok.sum() >= 0.95 * valid.sum()
    assert np.abs(depth[ok] - z[ok]).max() <= 0.51
    # and in millimetres of the rendered wall (per-pixel WLS disparities are biased by ~1-2 %
    # here; clicks refine the disparity, exports write the pipeline's values as they are)
    scene = wall_pair[0]
    for x, y in ((200, 150), (320, 240), (450, 330)):
        truth = sim_rig.true_point_rectified(result.calibration, scene, x, y)
        patch = depth[y - 4:y + 5, x - 4:x + 5]
        assert np.median(patch[patch > 0]) == pytest.approx(truth[2], rel=0.03)

    cloud = _read_ply(files["cloud.ply"])
    assert len(cloud) == ok.sum()
    np.testing.assert_allclose(cloud["z"], z[ok], rtol=1e-4)
    rgb = result.rectified_left[ok][:, ::-1]
    assert np.array_equal(np.stack([cloud["red"], cloud["green"], cloud["blue"]], 1), rgb)


def test_export_one_file_says_where(qtbot, ctx, live, sim_rig, wall_pair, array_source,
                                    tmp_path):
    _show_wall(qtbot, ctx, live, sim_rig.true_calibration(), wall_pair, array_source)
    status = []
    ctx.statusMessage.connect(status.append)
    with qtbot.waitSignal(ctx.jobs.finished, timeout=30000):
        live.export_frame(tmp_path / "wall.ply", kinds=("ply",))
    assert (tmp_path / "wall.ply").is_file()
    assert "point cloud" in status[-1] and "wall.ply" in status[-1] and "points" in status[-1]
    errors = []
    ctx.errorOccurred.connect(errors.append)
    with qtbot.waitSignal(ctx.jobs.failed, timeout=30000):
        live.export_frame(tmp_path / "missing" / "d.png", kinds=("disparity_png",))
    assert "Export of the disparity" in errors[-1]


@pytest.mark.parametrize("fails", [False, True])
def test_closing_waits_for_the_export_being_written_and_says_how_it_ended(
        qtbot, ctx, live, sim_rig, wall_pair, array_source, tmp_path, monkeypatch, fails):
    _show_wall(qtbot, ctx, live, sim_rig.true_calibration(), wall_pair, array_source)
    writing, gate = threading.Event(), threading.Event()
    real = depth_export.write_disparity_npy

    def held(path, disparity):
        writing.set()
        gate.wait(30)
        if fails:
            raise OSError("No space left on device")
        real(path, disparity)

    monkeypatch.setattr(depth_export, "write_disparity_npy", held)
    path = tmp_path / "d.npy"
    assert live.export_frame(path, kinds=("disparity_npy",)) is not None
    assert writing.wait(30)
    what = f"the export of the disparity in px as float32 .npy (NaN = invalid) to {path}"
    assert live.unfinished_work() == [what]
    threading.Timer(0.2, gate.set).start()
    said = live.cancel_unfinished_work(timeout_ms=30000)  # a running export is waited for
    assert said == [f"T{what[1:]} {'failed' if fails else 'was written'}."]
    assert live.unfinished_work() == [] and path.is_file() != fails


def test_a_calibration_of_another_resolution_is_scaled_and_says_so(
        qtbot, ctx, live, sim_rig, wall_pair, array_source):
    scene = wall_pair[0]
    true = sim_rig.true_calibration()
    made_at_1280 = true.scaled_to((1280, 960))  # as if calibrated at 1280x960
    status = []
    ctx.statusMessage.connect(status.append)
    result = _show_wall(qtbot, ctx, live, made_at_1280, wall_pair, array_source)
    assert result.calibration.image_size == (640, 480)
    assert live.scale_label.isVisibleTo(live)
    assert "1280x960" in live.scale_label.text() and "640x480" in live.scale_label.text()
    assert any("scaled" in s for s in status)
    # the parameter panel shows what runs on the source's frames: the range of the scaled
    # calibration, and no note of a lower scale (it would be 0.25 for 1280x960 frames)
    shown = live.params_panel.editors["num_disparities"].value()
    assert shown == live.params_panel.params().matcher.disparity_range(result.calibration)[1]
    assert shown < made_at_1280.focal_px * made_at_1280.baseline_mm / 450.0
    assert not live.params_panel.scale_note.isVisibleTo(live.params_panel)
    with qtbot.waitSignal(live.measured, timeout=30000) as sig:
        live.measure_at(300.0, 250.0)
    m = sig.args[0]
    truth = sim_rig.true_point_rectified(true, scene, m.x, m.y)
    assert m.valid and m.Z_mm == pytest.approx(truth[2], rel=0.01)


def test_a_calibration_of_another_aspect_ratio_is_refused_with_the_reason(
        qtbot, ctx, live, sim_rig, wall_pair, array_source):
    _scene, left, right = wall_pair
    # (made at 1280x720 as far as it says: a 4:3 size to scale from would be refused)
    wide = sim_rig.true_calibration().scaled_to((1280, 960)).with_updates(image_size=(1280, 720),
                                                                          scaled_from=None)
    ctx.calibration_model.set(wide)
    with qtbot.waitSignal(ctx.errorOccurred, timeout=30000) as sig:
        ctx.frames.set_source(array_source(left, right, fps=30))
    text = sig.args[0]
    assert "1280x720" in text and "640x480" in text and "aspect ratio" in text
    assert live.frames_shown == 0  # nothing silently wrong is shown
    with qtbot.waitSignal(ctx.errorOccurred, timeout=2000) as err:
        assert live.measure_at(320.0, 240.0) is None  # nor measured on
    assert err.args[0] == "No frame to measure on yet."
