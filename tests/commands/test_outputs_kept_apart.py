"""An output that is an input of the same run, another output, a device or a pipe, or empty, is
refused with one line before anything is written: the user's pictures, their set's truth and
their calibration are left as they were."""

from __future__ import annotations

import os

import pytest

from stereo_gui.cli import main
from tests.cli_output import one_line


@pytest.fixture(scope="module")
def sim_set(tmp_path_factory):
    out = tmp_path_factory.mktemp("set")
    assert main(["simulate", str(out), "--pairs", "12"]) == 0
    return out


def _run(argv, capsys) -> tuple[int, str]:
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


def test_disparity_does_not_write_over_its_left_image(wall_files, capsys):
    folder, _rig, _scene, calib = wall_files
    from stereo_gui.files.calibration_file import save_calibration

    save_calibration(calib, folder / "calib.yaml")
    left = folder / "left.png"
    before = left.read_bytes()
    base = ["disparity", "--calib", str(folder / "calib.yaml"), str(left),
            str(folder / "right.png")]
    for outputs in (["-o", str(left)], ["-o", str(folder / "view.png"), "--png16", str(left)]):
        code, err = _run(base + outputs, capsys)
        one_line(err, code, "is an input")
        assert left.read_bytes() == before
    link = folder / "link.png"
    link.symlink_to(left)
    code, err = _run(["disparity", "--calib", str(folder / "calib.yaml"), str(left),
                      str(folder / "right.png"), "-o", str(link)], capsys)
    one_line(err, code, "is an input")


def test_calibrate_keeps_the_sets_pictures_truth_and_calibration(sim_set, capsys, tmp_path):
    pair = sorted(sim_set.glob("chessboard-L*.png"))[0]
    truth = sim_set / "truth.json"
    before = pair.read_bytes(), truth.read_bytes()
    for target in (pair, truth):
        code, err = _run(["calibrate", str(sim_set), "-o", str(target)], capsys)
        one_line(err, code)
    assert (pair.read_bytes(), truth.read_bytes()) == before
    ros = tmp_path / "ros"
    ros.mkdir()
    code, err = _run(["calibrate", str(sim_set), "-o", str(ros / "left.yaml"), "--ros-dir",
                      str(ros)], capsys)
    one_line(err, code, "two outputs")
    code, err = _run(["calibrate", str(sim_set), "-o", str(tmp_path / "c.yaml"), "--ros-dir",
                      ""], capsys)
    one_line(err, code, "--ros-dir is empty")
    other = tmp_path / "notes.yaml"
    other.write_text("my notes: keep them\n")
    code, err = _run(["calibrate", str(sim_set), "-o", str(other)], capsys)
    one_line(err, code, "not a calibration")
    assert other.read_text() == "my notes: keep them\n"


def test_a_pipe_is_not_an_output(wall_files, capsys, tmp_path):
    folder, _rig, _scene, calib = wall_files
    from stereo_gui.files.calibration_file import save_calibration

    save_calibration(calib, tmp_path / "calib.yaml")
    fifo = tmp_path / "view.png"
    os.mkfifo(fifo)
    code, err = _run(["disparity", "--calib", str(tmp_path / "calib.yaml"),
                      str(folder / "left.png"), str(folder / "right.png"), "-o", str(fifo)],
                     capsys)
    one_line(err, code, "not a regular file")


def test_simulate_into_an_empty_name_is_refused(capsys):
    code, err = _run(["simulate", ""], capsys)
    one_line(err, code, "OUT_DIR is empty")


def test_a_target_at_nan_dpi_is_refused_whatever_the_format(capsys, tmp_path):
    code, err = _run(["target", "--dpi", "nan", "-o", str(tmp_path / "t.pdf")], capsys)
    one_line(err, code, "--dpi")
    assert not (tmp_path / "t.pdf").exists()


def _small_recording(folder, frames: int = 3):
    """A recording of `frames` black 64x48 pairs at 30 fps: its folder."""
    import numpy as np

    from stereo_gui.files.recording import RecordingWriter
    from stereo_gui.sources.base import StereoFrame

    img = np.zeros((48, 64, 3), np.uint8)
    with RecordingWriter(folder, fps=30.0, background=False) as w:
        for i in range(frames):
            w.write(StereoFrame(img, img, i / 30, i / 30, i))
    return folder


def test_a_recording_at_a_frame_per_thirty_years_is_refused(tmp_path):
    import json

    from stereo_gui.core.errors import InputError
    from stereo_gui.files.recording import open_recording

    header = _small_recording(tmp_path / "rec") / "recording.json"
    doc = json.loads(header.read_text())
    doc["fps"] = 1e-9
    header.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="fps"):
        open_recording(tmp_path / "rec")


def test_a_recording_with_frame_times_no_clock_has_is_refused_by_line(tmp_path):
    """Frame times of 1e300 s ended in "timestamp out of range" far from the file."""
    from stereo_gui.core.errors import InputError
    from stereo_gui.files.recording import open_recording

    frames = _small_recording(tmp_path / "rec") / "frames.csv"
    lines = frames.read_text().splitlines()
    parts = lines[2].split(",")
    parts[1] = "1e300"
    lines[2] = ",".join(parts)
    frames.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="line 3.*seconds of a clock"):
        open_recording(tmp_path / "rec")
