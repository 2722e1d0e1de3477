"""Playback of recordings, folders of pairs and side-by-side videos: frames, times, controls."""

from __future__ import annotations

import threading

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import SourceError, StereoGuiError
from stereo_gui.files.recording import RecordingWriter
from stereo_gui.sources.base import StereoFrame
from stereo_gui.sources.playback import PlaybackSource

W, H = 40, 24


def _frames(n, dt=1 / 30.0, seed=0):
    rng = np.random.default_rng(seed)
    return [StereoFrame(rng.integers(0, 256, (H, W, 3), np.uint8),
                        rng.integers(0, 256, (H, W, 3), np.uint8),
                        500.0 + i * dt + 0.001 * i * i, 500.0 + i * dt + 0.0004, i)
            for i in range(n)]


def _record(folder, frames, **kw):
    with RecordingWriter(folder, source_name="test", fps=30.0, **kw) as w:
        for f in frames:
            w.write(f)
    return folder


@pytest.fixture
def recorded(tmp_path):
    frames = _frames(5)
    return _record(tmp_path / "rec", frames), frames


def _same(a: StereoFrame, b: StereoFrame) -> bool:
    return (np.array_equal(a.left, b.left) and np.array_equal(a.right, b.right)
            and a.t_left == b.t_left and a.t_right == b.t_right)


def test_plays_back_the_same_images_and_timestamps_then_loops(recorded):
    folder, frames = recorded
    src = PlaybackSource(folder, paced=False)
    # the capabilities it has and has not: its own playback controls, no cameras, no rig
    assert src.playback() is src
    assert src.camera_controls() is None and src.simulated_rig() is None
    # the rate the frames were recorded at (recording.json), not the source's nominal 30 fps
    recorded_fps = 4 / (frames[-1].t_left - frames[0].t_left)
    assert src.frame_count == 5 and src.name == "Playback of rec"
    assert src.nominal_fps == pytest.approx(recorded_fps)
    got = [src.read() for _ in range(7)]
    for k, g in enumerate(got):
        assert g.index == k % 5
        assert _same(g, frames[k % 5])
    src.close()
    with pytest.raises(SourceError, match="closed"):
        src.read()


def test_without_loop_holds_the_last_frame_or_raises(recorded):
    folder, frames = recorded
    src = PlaybackSource(folder, loop=False, paced=False)
    for k in range(5):
        assert src.read().index == k
    assert src.finished and src.paused
    assert src.read().index == 4  # held
    src.resume()  # after the end, play again from the start
    assert src.read().index == 0 and not src.finished

    src = PlaybackSource(folder, loop=False, paced=False, at_end="raise")
    for _ in range(5):
        src.read()
    with pytest.raises(SourceError, match="end of the recording"):
        src.read()
    src.seek(2)
    assert src.read().index == 2


def test_pause_step_seek_resume(recorded):
    folder, frames = recorded
    src = PlaybackSource(folder, paced=False)
    src.read(), src.read()  # frames 0, 1 shown
    src.pause()
    assert src.paused and src.position == 1
    assert [src.read().index for _ in range(3)] == [1, 1, 1]  # the paused frame again
    assert src.step() == 2 and src.read().index == 2
    assert src.step(-1) == 1 and src.read().index == 1
    assert _same(src.read(), frames[1])
    src.step(-2)  # wraps with loop on
    assert src.position == 4 and src.read().index == 4
    src.set_loop(False)
    src.seek(0)
    src.step(-1)  # stops at the first frame with loop off
    assert src.read().index == 0
    src.seek(99)
    assert src.position == 4 and src.read().index == 4
    src.set_loop(True)
    src.resume()  # plays on after the frame shown
    assert [src.read().index for _ in range(3)] == [0, 1, 2]
    src.pause()
    src.seek(3)  # a seek while paused: the target is shown, and playing starts there
    src.resume()
    assert [src.read().index for _ in range(2)] == [3, 4]
    src.step()  # stepping while playing pauses on the next frame
    assert src.paused and src.read().index == 0  # the frame after 4, with loop on


def test_plain_folder_of_pairs(tmp_path):
    frames = _frames(3)
    for k, f in enumerate(frames, start=1):
        cv2.imwrite(str(tmp_path / f"chessboard-L{k}.png"), f.left)
        cv2.imwrite(str(tmp_path / f"chessboard-R{k}.png"), f.right)
    src = PlaybackSource(tmp_path, paced=False, fps=12.0)
    assert src.frame_count == 3 and src.nominal_fps == 12.0
    for k in range(3):
        g = src.read()
        assert np.array_equal(g.left, frames[k].left) and np.array_equal(g.right, frames[k].right)
        assert g.t_left == pytest.approx(k / 12.0)


def test_pair_of_different_image_sizes_is_refused(tmp_path):
    """A folder whose right image is half the size of the left must not play as if it were a
    stereo pair (the capture tab then said the right camera does not see the board)."""
    f = _frames(1)[0]
    cv2.imwrite(str(tmp_path / "left1.png"), f.left)
    cv2.imwrite(str(tmp_path / "right1.png"), cv2.resize(f.right, None, fx=0.5, fy=0.5))
    with pytest.raises(SourceError, match=r"left1.png is \d+x\d+ but right1.png is \d+x\d+"):
        src = PlaybackSource(tmp_path, paced=False)
        src.read()


def test_a_header_size_that_is_not_the_pictures_is_said(recorded):
    """recording.json's size edited to another size: the recording plays its pictures and says
    the header disagrees (it was accepted without a word)."""
    import json

    folder, frames = recorded
    header = json.loads((folder / "recording.json").read_text())
    assert header["size"] == [W, H]
    header["size"] = [640, 480]
    (folder / "recording.json").write_text(json.dumps(header))
    src = PlaybackSource(folder, paced=False)
    try:
        assert any(f"header says 640x480 px but the pictures are {W}x{H} px" in w
                   for w in src.warnings)
        assert _same(src.read(), frames[0])
    finally:
        src.close()
    header["size"] = [W, H]  # the size it has: nothing to say
    (folder / "recording.json").write_text(json.dumps(header))
    src = PlaybackSource(folder, paced=False)
    assert not any("header says" in w for w in src.warnings)
    src.close()


def test_side_by_side_video_file(tmp_path):
    frames = _frames(4)
    path = tmp_path / "sbs.avi"
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), 20.0, (2 * W, H))
    for f in frames:
        vw.write(np.hstack([f.left, f.right]))
    vw.release()
    src = PlaybackSource(path, paced=False)
    assert src.frame_count == 4 and src.nominal_fps == pytest.approx(20.0)
    got = [src.read() for _ in range(4)]
    for f, g in zip(frames, got, strict=True):
        assert np.array_equal(g.left, f.left) and np.array_equal(g.right, f.right)
    src.pause()
    src.step(-2)  # seeking backwards in the video
    assert np.array_equal(src.read().left, frames[1].left)
    src.close()


def test_recording_with_only_a_video_uses_its_timestamps(tmp_path):
    frames = _frames(3)
    folder = _record(tmp_path / "rec", frames, images=False, video="FFV1")
    src = PlaybackSource(folder, paced=False)
    got = [src.read() for _ in range(3)]
    assert all(_same(g, f) for g, f in zip(got, frames, strict=True))


def test_paced_playback_follows_recorded_times_and_wakes_on_control(tmp_path):
    # frames 1000 s apart: a paced read of the second frame waits; step/close must end the wait
    frames = _frames(3, dt=1000.0)
    src = PlaybackSource(_record(tmp_path / "rec", frames), paced=True)
    assert src.read().index == 0
    result: dict = {}

    def reader():
        try:
            result["frame"] = src.read()
        except StereoGuiError as exc:
            result["error"] = exc

    t = threading.Thread(target=reader)
    t.start()
    src.step(1)  # paused on frame 1: delivered at once
    t.join(10)
    assert not t.is_alive() and result["frame"].index == 1

    src.resume()  # playing again starts at once with the next frame ...
    assert src.read().index == 2
    result.clear()  # ... and the one after (frame 0, looped) is due 1000 s later
    t = threading.Thread(target=reader)
    t.start()
    src.close()
    t.join(10)
    assert not t.is_alive() and isinstance(result["error"], SourceError)


def test_controls_from_another_thread_while_reading(recorded):
    folder, frames = recorded
    src = PlaybackSource(folder, paced=False)
    seen: list[int] = []
    errors: list[BaseException] = []
    stop = threading.Event()

    def reader():
        try:
            while not stop.is_set():
                f = src.read()
                assert _same(f, frames[f.index])
                seen.append(f.index)
        except SourceError:
            pass
        except BaseException as exc:  # noqa: BLE001
            errors.append(exc)

    t = threading.Thread(target=reader)
    t.start()
    for k in range(200):
        [src.pause, src.resume, lambda: src.step(-1), lambda: src.seek(k % 7), src.resume][k % 5]()
    stop.set()
    src.close()
    t.join(10)
    assert not t.is_alive() and not errors and seen
    assert all(0 <= i < 5 for i in seen)


def test_missing_or_empty_sources(tmp_path):
    with pytest.raises(SourceError, match="no such"):
        PlaybackSource(tmp_path / "nothing")
    with pytest.raises(StereoGuiError):
        PlaybackSource(tmp_path)  # an empty folder: no pairs
    (tmp_path / "bad.avi").write_bytes(b"not a video")
    with pytest.raises(SourceError):
        PlaybackSource(tmp_path / "bad.avi")
    with pytest.raises(SourceError, match="positive"):
        PlaybackSource(tmp_path, fps=0)


def test_a_recorded_sequence_gives_the_same_distances_as_live(tmp_path):
    """Record the simulated rig, play it back: the pipeline measures exactly the same distances."""
    from stereo_gui.core.matching import StereoPipeline
    from stereo_gui.core.measure import measure_point
    from stereo_gui.files.presets import load_preset
    from stereo_gui.sources.sim import SimRig, SimSource

    rig = SimRig(seed=7)
    live = SimSource(rig, mode="scene", paced=False, seed=3)
    calib = rig.true_calibration(alpha=0.0)
    points = ((320, 240), (200, 150), (450, 330), (100, 400))

    def distances(pipe, frame):
        result = pipe.process(frame.left, frame.right)
        return [measure_point(result, x, y) for x, y in points]

    with StereoPipeline(calib, load_preset("live")) as pipe, \
            RecordingWriter(tmp_path / "rec", source_name=live.name, fps=live.nominal_fps) as w:
        live_frames = [live.read() for _ in range(2)]
        live_m = []
        for f in live_frames:
            w.write(f)
            live_m.append(distances(pipe, f))
    live.close()

    src = PlaybackSource(tmp_path / "rec", paced=False)
    with StereoPipeline(calib, load_preset("live")) as pipe:
        played_m = [distances(pipe, src.read()) for _ in live_frames]
    src.close()
    assert sum(m.valid for row in live_m for m in row) >= 4
    for a_row, b_row in zip(live_m, played_m, strict=True):
        for a, b in zip(a_row, b_row, strict=True):
            assert a.valid == b.valid and a.reason == b.reason
            if a.valid:
                assert b.Z_mm == a.Z_mm and b.range_mm == a.range_mm
                assert b.disparity_px == a.disparity_px


def test_speed_is_checked(recorded):
    folder, _frames_ = recorded
    src = PlaybackSource(folder, paced=False)
    for bad in (0, -1, float("nan"), float("inf")):
        with pytest.raises(SourceError, match="speed"):
            src.set_speed(bad)
    src.set_speed(0.5)
    assert src.speed == 0.5 and src.time_s(0) == 0.0
    src.close()
