"""Recording the stereo stream: folder layout, header, timestamps, video, failures."""

from __future__ import annotations

import csv
import json

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.files import recording as rec_mod
from stereo_gui.files.pairs import discover_pairs
from stereo_gui.files.recording import RecordingWriter, open_recording
from stereo_gui.sources.base import StereoFrame

W, H = 48, 32


def _frames(n, seed=0):
    rng = np.random.default_rng(seed)
    t0 = 1234.5678901234567
    out = []
    for i in range(n):
        # smooth pictures with a little noise: lossless checks stay strict, JPEG stays close
        left = cv2.resize(rng.integers(20, 236, (4, 6, 3), np.uint8), (W, H),
                          interpolation=cv2.INTER_LINEAR) + rng.integers(0, 3, (H, W, 3), np.uint8)
        right = np.roll(left, -3, axis=1)
        t = t0 + i / 30.0 + rng.uniform(0, 0.003)
        out.append(StereoFrame(left, right, t, t + 0.0007, 100 + i))
    return out


@pytest.mark.parametrize("background", [True, False])
def test_recording_folder_holds_images_times_and_header(tmp_path, background):
    frames = _frames(5)
    w = RecordingWriter(tmp_path / "rec", source_name="Simulated rig", fps=30.0,
                        background=background)
    for f in frames:
        w.write(f)
    rec = w.close()
    folder = tmp_path / "rec"
    header = json.loads((folder / "recording.json").read_text())
    assert header["format_version"] == rec_mod.FORMAT_VERSION
    assert header["size"] == [W, H] and header["nominal_fps"] == 30.0
    assert header["fps"] == pytest.approx(4 / (frames[-1].t_left - frames[0].t_left))
    assert header["source"] == "Simulated rig" and header["frames"] == 5 and header["complete"]
    rows = list(csv.reader((folder / "frames.csv").open()))
    assert rows[0] == ["index", "t_left", "t_right", "left", "right"]
    assert rows[1][3:] == ["left/000001.png", "right/000001.png"]
    # read back: same pixels (PNG is lossless), same timestamps to the last bit
    assert rec.complete and rec.has_images and len(rec.frames) == 5 and rec.warnings == ()
    for f, r in zip(frames, rec.frames, strict=True):
        np.testing.assert_array_equal(cv2.imread(str(r.left)), f.left)
        np.testing.assert_array_equal(cv2.imread(str(r.right)), f.right)
        assert (r.t_left, r.t_right) == (f.t_left, f.t_right)
    assert open_recording(folder) == rec
    # the folder is also a plain folder of pairs
    assert len(discover_pairs(folder).pairs) == 5


def test_header_says_the_rate_recorded_not_the_one_promised(tmp_path):
    """A source meant for 30 fps that delivered 10.7: recording.json says 10.7."""
    frames = _frames(12)
    t0 = 50.0
    frames = [StereoFrame(f.left, f.right, t0 + i / 10.7, t0 + i / 10.7, f.index)
              for i, f in enumerate(frames)]
    with RecordingWriter(tmp_path / "rec", fps=30.0, background=False) as w:
        for f in frames:
            w.write(f)
    header = json.loads((tmp_path / "rec" / "recording.json").read_text())
    assert header["fps"] == pytest.approx(10.7) and header["nominal_fps"] == 30.0
    assert open_recording(tmp_path / "rec").fps == pytest.approx(10.7)


def test_frames_made_faster_than_any_camera_record_the_nominal_rate(tmp_path):
    """An unpaced source (frames 0.2 ms apart): the header keeps the nominal rate, and the
    recording opens (a rate above what the reader accepts made it unreadable)."""
    frames = [StereoFrame(f.left, f.right, 5.0 + i * 2e-4, 5.0 + i * 2e-4, f.index)
              for i, f in enumerate(_frames(6))]
    with RecordingWriter(tmp_path / "rec", fps=30.0, background=False) as w:
        for f in frames:
            w.write(f)
    assert json.loads((tmp_path / "rec" / "recording.json").read_text())["fps"] == 30.0
    assert open_recording(tmp_path / "rec").fps == 30.0


def test_writer_copies_frames_before_returning(tmp_path):
    f = _frames(1)[0]
    expected = f.left.copy()
    with RecordingWriter(tmp_path / "rec") as w:
        w.write(f)
        f.left[:] = 0  # the caller reuses its buffer at once
    np.testing.assert_array_equal(cv2.imread(str(tmp_path / "rec" / "left" / "000001.png")),
                                  expected)


@pytest.mark.parametrize("codec", ["MJPG", "FFV1"])
def test_side_by_side_video(tmp_path, codec):
    frames = _frames(4)
    with RecordingWriter(tmp_path / "rec", video=codec, images=False, fps=15.0) as w:
        for f in frames:
            w.write(f)
    rec = open_recording(tmp_path / "rec")
    assert rec.video is not None and rec.video.name == "stereo.avi" and not rec.has_images
    assert not (tmp_path / "rec" / "left").exists()
    assert not [p for p in (tmp_path / "rec").iterdir() if p.name.startswith(".")]
    cap = cv2.VideoCapture(str(rec.video))
    assert cap.get(cv2.CAP_PROP_FRAME_COUNT) == 4
    ok, first = cap.read()
    cap.release()
    assert ok and first.shape == (H, 2 * W, 3)
    sbs = np.hstack([frames[0].left, frames[0].right]).astype(int)
    err = np.abs(first.astype(int) - sbs)
    if codec == "FFV1":
        assert err.max() == 0  # lossless
    else:
        assert err.mean() < 6  # JPEG: lossy but the same picture
    assert [f.t_left for f in rec.frames] == [f.t_left for f in frames]


def test_refuses_to_overwrite(tmp_path):
    (tmp_path / "rec").mkdir()
    (tmp_path / "rec" / "keep.txt").write_text("x")
    with pytest.raises(InputError, match="never overwrites"):
        RecordingWriter(tmp_path / "rec")
    assert (tmp_path / "rec" / "keep.txt").read_text() == "x"


def test_bad_options():
    with pytest.raises(InputError):
        RecordingWriter("/nonexistent/x", images=False, video=None)
    with pytest.raises(InputError, match="codec"):
        RecordingWriter("/nonexistent/x", video="H264")


def test_size_change_is_an_error_on_the_next_write(tmp_path):
    w = RecordingWriter(tmp_path / "rec", background=False)
    w.write(_frames(1)[0])
    small = StereoFrame(np.zeros((8, 8, 3), np.uint8), np.zeros((8, 8, 3), np.uint8), 0, 0, 1)
    with pytest.raises(InputError, match="8x8"):
        w.write(small)
    assert len(w.close().frames) == 1


def test_disk_error_in_background_is_raised_and_earlier_frames_stay(tmp_path, monkeypatch):
    frames = _frames(4)
    w = RecordingWriter(tmp_path / "rec")
    w.write(frames[0])
    w.write(frames[1])
    real = rec_mod.write_bytes_atomic
    def full_disk(path, data):
        raise OSError(28, "No space left on device")

    w.flush()
    assert w.frames_written == 2
    monkeypatch.setattr(rec_mod, "write_bytes_atomic", full_disk)
    w.write(frames[2])
    with pytest.raises(InputError, match="No space left"):
        w.close()
    monkeypatch.setattr(rec_mod, "write_bytes_atomic", real)
    rec = open_recording(tmp_path / "rec")
    assert len(rec.frames) == 2 and not rec.complete
    assert not [p for p in (tmp_path / "rec" / "left").iterdir() if p.name.startswith(".")]


def test_a_crashed_recording_opens_with_what_was_saved(tmp_path):
    w = RecordingWriter(tmp_path / "rec", background=False)
    for f in _frames(3):
        w.write(f)
    # no close(): the process died. A torn last line must not matter either.
    w.flush()
    with open(tmp_path / "rec" / "frames.csv", "a", encoding="utf-8") as frames:
        frames.write("3,12.5")
    rec = open_recording(tmp_path / "rec")
    assert len(rec.frames) == 3 and not rec.complete
    assert any("line 5" in x for x in rec.warnings)
    w.close()


def test_open_recording_refuses_other_folders(tmp_path):
    with pytest.raises(InputError, match="not a recording"):
        open_recording(tmp_path)
    (tmp_path / "recording.json").write_text('{"kind": "something else"}')
    with pytest.raises(InputError, match="not a stereo-gui recording"):
        open_recording(tmp_path)
    (tmp_path / "recording.json").write_text("[1, 2]")
    with pytest.raises(InputError, match="recording.json does not hold a JSON object"):
        open_recording(tmp_path)


def test_a_torn_last_line_is_left_out_and_the_rest_plays(tmp_path):
    """A last line cut after `left/000004.png,` (a crash mid-write) must not stop playback."""
    from stereo_gui.sources.playback import PlaybackSource

    w = RecordingWriter(tmp_path / "rec", background=False)
    for f in _frames(4):
        w.write(f)
    w.flush()
    text = (tmp_path / "rec" / "frames.csv").read_text()
    last = text.rstrip("\n").rsplit("\n", 1)[1]
    torn = text[: len(text) - len(last) - 1] + last[: last.index(".png,") + 5] + "\n"
    (tmp_path / "rec" / "frames.csv").write_text(torn)
    rec = open_recording(tmp_path / "rec")
    assert [f.index for f in rec.frames] == [0, 1, 2]
    assert any("torn last line" in x for x in rec.warnings)
    src = PlaybackSource(tmp_path / "rec", paced=False)
    try:
        got = [src.read() for _ in range(3)]
    finally:
        src.close()
    assert all(f.left is not None and f.right is not None for f in got)


@pytest.mark.parametrize(("line", "message"), [
    ("0,5000,5000,left/000001.png,right/000001.png", "does not follow"),  # duplicate index
    ("-5,5000,5000,left/000001.png,right/000001.png", "negative"),
    ("7,nan,5000,left/000001.png,right/000001.png", "seconds of a clock"),
    ("7,-100,5000,left/000001.png,right/000001.png", "backwards"),
    ("7,5000,5000,../../etc/passwd,right/000001.png", "not a file inside"),
])
def test_damaged_frame_lists_are_refused_naming_line_and_field(tmp_path, line, message):
    w = RecordingWriter(tmp_path / "rec", background=False)
    for f in _frames(2):
        w.write(f)
    w.close()
    fpath = tmp_path / "rec" / "frames.csv"
    rows = fpath.read_text().splitlines()
    fpath.write_text("\n".join(rows[:2] + [line] + rows[2:]) + "\n")
    with pytest.raises(InputError, match=f"frames.csv, line 3: .*{message}"):
        open_recording(tmp_path / "rec")


def test_the_skew_between_the_cameras_is_recorded(tmp_path):
    """The header says how far apart the cameras took their pictures (median and worst), and
    the recording read back says it from the frames' own times."""
    frames = _frames(6)
    with RecordingWriter(tmp_path / "rec", fps=30.0, background=False) as w:
        for f in frames:
            w.write(f)
    header = json.loads((tmp_path / "rec" / "recording.json").read_text())
    assert header["skew_ms"] == {"median": pytest.approx(0.7), "worst": pytest.approx(0.7),
                                 "frames": 6}
    skew = open_recording(tmp_path / "rec").skew
    assert skew.median_ms == pytest.approx(0.7) and skew.frames == 6
