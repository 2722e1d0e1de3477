"""The window opens other tools' calibrations too (File > Open calibration, --calib, the
remembered one); a file without an image size takes the size of the frames or the source."""

from __future__ import annotations

import cv2
import numpy as np

from stereo_gui.core.stereo_calibration import StereoCalibration


def _write_sample_pair(folder, calib) -> None:
    """intrinsics.yml + extrinsics.yml as OpenCV's stereo_calib sample writes them (no size)."""
    fs = cv2.FileStorage(str(folder / "intrinsics.yml"), cv2.FILE_STORAGE_WRITE)
    for name in ("M1", "D1", "M2", "D2"):
        fs.write(name, np.asarray(getattr(calib, name)))
    fs.release()
    fs = cv2.FileStorage(str(folder / "extrinsics.yml"), cv2.FILE_STORAGE_WRITE)
    for name in ("R", "T", "R1", "R2", "P1", "P2", "Q"):
        fs.write(name, np.asarray(getattr(calib, name)))
    fs.release()


def _calib(size=(320, 240)):
    c = StereoCalibration.identity(size, 300.0, 110.0)
    return c.with_updates(method="bouguet")


def test_open_calibration_takes_the_size_of_the_frames_shown(qtbot, ctx, array_source, tmp_path):
    _write_sample_pair(tmp_path, _calib())
    rng = np.random.default_rng(0)
    img = rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)
    ctx.frames.set_source(array_source(img, img))
    qtbot.waitUntil(lambda: ctx.frames.latest() is not None, timeout=5000)
    statuses = []
    ctx.statusMessage.connect(statuses.append)
    assert ctx.calibration_model.open_file(tmp_path / "extrinsics.yml")
    assert ctx.calibration.image_size == (320, 240)
    assert ctx.calibration_path == tmp_path / "extrinsics.yml"
    assert "OpenCV stereo calibration" in statuses[-1]
    assert ctx.settings.last_calibration == str((tmp_path / "extrinsics.yml").resolve())


def test_open_calibration_reports_a_foreign_file_it_cannot_use(qtbot, ctx, tmp_path):
    fs = cv2.FileStorage(str(tmp_path / "intrinsics.yml"), cv2.FILE_STORAGE_WRITE)
    fs.write("M1", np.eye(3))
    fs.release()
    errors = []
    ctx.errorOccurred.connect(errors.append)
    assert not ctx.calibration_model.open_file(tmp_path / "intrinsics.yml")
    assert ctx.calibration is None and "missing" in errors[-1]


def test_command_line_calib_without_size_takes_the_recordings_size(qtbot, tmp_path):
    from stereo_gui.qt.app import build_window

    pairs = tmp_path / "pairs"
    pairs.mkdir()
    rng = np.random.default_rng(1)
    for i in (1, 2):
        for side in "LR":
            cv2.imwrite(str(pairs / f"chessboard-{side}{i}.png"),
                        rng.integers(0, 255, (240, 320, 3), dtype=np.uint8))
    _write_sample_pair(tmp_path, _calib())
    ctx, window = build_window(source=str(pairs), calib=str(tmp_path / "intrinsics.yml"))
    qtbot.addWidget(window)
    try:
        assert ctx.calibration is not None and ctx.calibration.image_size == (320, 240)
        assert ctx.calibration_path == (tmp_path / "intrinsics.yml").resolve()
    finally:
        window.close()


def test_command_line_rectified_spec_is_used_and_remembered(qtbot, tmp_path):
    from stereo_gui.files.settings import load_settings
    from stereo_gui.qt.app import build_window

    pairs = tmp_path / "pairs"
    pairs.mkdir()
    img = np.zeros((120, 160, 3), np.uint8)
    for side in "LR":
        cv2.imwrite(str(pairs / f"chessboard-{side}1.png"), img)
    ctx, window = build_window(source=str(pairs), calib="rectified:200,110,12")
    qtbot.addWidget(window)
    try:
        c = ctx.calibration
        assert c.image_size == (160, 120) and c.disparity_offset_px == 12.0
        assert ctx.calibration_path is None and "doffs 12 px" in ctx.calibration_note
    finally:
        window.close()
    assert load_settings()[0].last_calibration == "rectified:200,110,12"
