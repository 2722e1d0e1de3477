"""files.ros2_bag: frames of arrays written as a ROS 2 bag, read back with rosbags; the target
folder replaced atomically or left as it was (full disk, a bag that does not read back, a
failed rename); files.stream_mcap: the stream's MCAP recordings read back, fuzzed."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from disk_faults import install

from stereo_gui.core.errors import InputError, StereoGuiError
from stereo_gui.files.ros2_bag import (
    BagFrame,
    RectifiedCamera,
    atomic_folder,
    check_bag_target,
    pack_points,
    unpack_rgb,
    write_ros2_bag,
)
from tests.ros2_bags import cloud, image, read_bag, stamp_ns

W, H = 32, 24
FX = 40.0
BASELINE_M = 0.11
T0_NS = 1_700_000_000_123_456_789


def _cameras() -> tuple[RectifiedCamera, RectifiedCamera]:
    k = (FX, 0.0, 16.0, 0.0, FX, 12.0, 0.0, 0.0, 1.0)
    p_left = (FX, 0.0, 16.0, 0.0, 0.0, FX, 12.0, 0.0, 0.0, 0.0, 1.0, 0.0)
    p_right = (FX, 0.0, 16.0, -FX * BASELINE_M, 0.0, FX, 12.0, 0.0, 0.0, 0.0, 1.0, 0.0)
    return (RectifiedCamera("stereo_left_optical", W, H, k, p_left),
            RectifiedCamera("stereo_right_optical", W, H, k, p_right))


def _frames(n: int, seed: int = 0, left: bool = True, points: bool = True,
            size: tuple[int, int] = (W, H)) -> list[BagFrame]:
    rng = np.random.default_rng(seed)
    w, h = size
    cams = _cameras()
    if size != (W, H):
        cams = tuple(RectifiedCamera(c.frame_id, w, h, c.K, c.P) for c in cams)
    out = []
    for i in range(n):
        depth = rng.integers(0, 65536, (h, w), dtype=np.uint16)
        depth[0, :5] = 0  # no value
        m = 200
        out.append(BagFrame(
            T0_NS + i * 33_333_333, depth, *cams,
            left_bgr=rng.integers(0, 256, (h, w, 3), dtype=np.uint8) if left else None,
            points_m=rng.normal(0, 2, (m, 3)).astype(np.float32) if points else None,
            points_rgb=rng.integers(0, 256, (m, 3), dtype=np.uint8) if points else None))
    return out


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def _leftovers(folder: Path, *keep: str) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


# ---- what the bag holds -----------------------------------------------------------------------
def test_the_bag_holds_every_topic_as_ros_reads_it(tmp_path):
    frames = _frames(3)
    out = tmp_path / "bag"
    summary = write_ros2_bag(out, frames)
    assert summary.frames == 3 and summary.size_bytes > 0
    assert sorted(p.name for p in out.iterdir()) == ["bag.mcap", "metadata.yaml"]
    bag = read_bag(out)
    assert bag.types == {
        "/stereo/depth": "sensor_msgs/msg/Image",
        "/stereo/left/image_rect": "sensor_msgs/msg/Image",
        "/stereo/left/camera_info": "sensor_msgs/msg/CameraInfo",
        "/stereo/right/camera_info": "sensor_msgs/msg/CameraInfo",
        "/stereo/points": "sensor_msgs/msg/PointCloud2",
    }
    assert all(bag.count(t) == 3 for t in bag.types) and set(bag.listed.values()) == {3}
    for f, depth in zip(frames, bag.msgs("/stereo/depth")):
        assert (depth.encoding, depth.step, depth.header.frame_id) == ("16UC1", 2 * W,
                                                                       "stereo_left_optical")
        assert np.array_equal(image(depth), f.depth_mm)
    for f, left in zip(frames, bag.msgs("/stereo/left/image_rect")):
        assert left.encoding == "bgr8" and np.array_equal(image(left), f.left_bgr)
    right = bag.msgs("/stereo/right/camera_info")[0]
    assert right.p[3] < 0 and right.p[3] == pytest.approx(-right.p[0] * BASELINE_M)
    assert right.distortion_model == "plumb_bob" and list(right.d) == [0.0] * 5
    assert list(right.r) == [1, 0, 0, 0, 1, 0, 0, 0, 1] and list(right.k) == list(_cameras()[1].K)
    assert (right.width, right.height, right.header.frame_id) == (W, H, "stereo_right_optical")
    for f, pc in zip(frames, bag.msgs("/stereo/points")):
        xyz, rgb = cloud(pc)
        assert (pc.height, pc.width, pc.point_step, pc.row_step) == (1, 200, 16, 3200)
        assert pc.is_dense and pc.header.frame_id == "stereo_left_optical"
        assert np.array_equal(xyz, f.points_m) and np.array_equal(rgb, f.points_rgb)


def test_every_message_of_a_frame_carries_its_stamp(tmp_path):
    frames = _frames(4)
    write_ros2_bag(tmp_path / "bag", frames)
    bag = read_bag(tmp_path / "bag")
    want = [f.stamp_ns for f in frames]
    for topic, msgs in bag.messages.items():
        assert [t for t, _ in msgs] == want, topic  # the bag's own time
        assert [stamp_ns(m) for _, m in msgs] == want, topic  # the header's


def test_a_frame_without_picture_or_points_writes_the_rest(tmp_path):
    frames = _frames(2) + _frames(1, seed=1, left=False, points=False)
    write_ros2_bag(tmp_path / "bag", frames)
    bag = read_bag(tmp_path / "bag")
    assert bag.count("/stereo/depth") == 3 and bag.count("/stereo/right/camera_info") == 3
    assert bag.count("/stereo/left/image_rect") == 2 and bag.count("/stereo/points") == 2


def test_rgb_is_packed_the_ros_way():
    rgb = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [18, 52, 86]], np.uint8)
    data = pack_points(np.zeros((4, 3), np.float32), rgb)
    bits = np.frombuffer(data, dtype=[("xyz", "<f4", 3), ("rgb", "<u4")])["rgb"]
    assert bits.tolist() == [0xFF0000, 0x00FF00, 0x0000FF, 0x123456]
    as_float = np.frombuffer(data, dtype=[("xyz", "<f4", 3), ("rgb", "<f4")])["rgb"]
    assert np.array_equal(unpack_rgb(as_float), rgb)


@pytest.mark.parametrize("change, words", [
    ({"depth_mm": np.zeros((H, W), np.float32)}, "uint16"),
    ({"left_bgr": np.zeros((H, W), np.uint8)}, "left picture"),
    ({"depth_mm": np.zeros((H + 1, W), np.uint16)}, "depth image"),
    ({"points_rgb": np.zeros((3, 3), np.uint8)}, "colours"),
])
def test_frames_that_do_not_hold_together_are_refused_and_nothing_is_written(tmp_path, change,
                                                                              words):
    from dataclasses import replace

    bad = replace(_frames(1)[0], **change)
    with pytest.raises(InputError, match=words):
        write_ros2_bag(tmp_path / "bag", _frames(2) + [bad])
    assert _leftovers(tmp_path) == []


def test_no_frames_is_an_error_and_nothing_is_written(tmp_path):
    with pytest.raises(InputError, match="no frame"):
        write_ros2_bag(tmp_path / "bag", [])
    assert _leftovers(tmp_path) == []


def test_a_camera_needs_its_matrices_whole():
    with pytest.raises(InputError, match="9, 9 and 12"):
        RectifiedCamera("c", W, H, (1.0,) * 9, (1.0,) * 11)


# ---- the target folder ------------------------------------------------------------------------
def test_an_existing_target_is_refused_unless_replacing_a_bag(tmp_path):
    write_ros2_bag(tmp_path / "bag", _frames(1))
    with pytest.raises(InputError, match="exists already"):
        write_ros2_bag(tmp_path / "bag", _frames(2))
    assert read_bag(tmp_path / "bag").count("/stereo/depth") == 1
    write_ros2_bag(tmp_path / "bag", _frames(2), replace=True)
    assert read_bag(tmp_path / "bag").count("/stereo/depth") == 2
    assert _leftovers(tmp_path, "bag") == []


@pytest.mark.parametrize("make, words", [
    (lambda p: (p.mkdir(), (p / "thesis.tex").write_text("x")), "not a ROS 2 bag"),
    (lambda p: p.write_text("x"), "not a folder"),
])
def test_replacing_never_takes_what_is_not_a_bag(tmp_path, make, words):
    target = tmp_path / "out"
    make(target)
    before = _snapshot(tmp_path)
    with pytest.raises(InputError, match=words):
        write_ros2_bag(target, _frames(1), replace=True)
    assert _snapshot(tmp_path) == before


def test_an_empty_folder_may_be_replaced_and_a_missing_parent_is_named(tmp_path):
    (tmp_path / "empty").mkdir()
    assert check_bag_target(tmp_path / "empty", replace=True) is True
    write_ros2_bag(tmp_path / "empty", _frames(1), replace=True)
    assert read_bag(tmp_path / "empty").count("/stereo/depth") == 1
    with pytest.raises(InputError, match="does not exist"):
        check_bag_target(tmp_path / "nope" / "bag")
    with pytest.raises(InputError, match="name a new folder"):
        check_bag_target(Path("."), replace=True)


def _fail_mcap_write_after(monkeypatch, n: int) -> None:
    from rosbags.rosbag2 import storage_mcap

    original = storage_mcap.McapWriter.write
    calls = {"n": 0}

    def write(self, connection, timestamp, data):
        calls["n"] += 1
        if calls["n"] > n:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return original(self, connection, timestamp, data)

    monkeypatch.setattr(storage_mcap.McapWriter, "write", write)


@pytest.mark.parametrize("earlier", [False, True])
def test_a_full_disk_leaves_no_bag_and_the_earlier_one_as_it_was(tmp_path, monkeypatch, earlier):
    target = tmp_path / "bag"
    if earlier:
        write_ros2_bag(target, _frames(1, seed=5))
    before = _snapshot(tmp_path)
    _fail_mcap_write_after(monkeypatch, 7)
    with pytest.raises(InputError) as err:
        write_ros2_bag(target, _frames(3), replace=True)
    text = str(err.value)
    assert "disk is full" in text and str(target) in text
    assert ("was left as it was" if earlier else "nothing was written") in text
    assert _snapshot(tmp_path) == before
    assert _leftovers(tmp_path, "bag") == []


def test_a_bag_that_does_not_read_back_is_not_put_in_place(tmp_path, monkeypatch):
    from rosbags.rosbag2 import storage_mcap

    original = storage_mcap.McapWriter.close

    def close_cut(self, version, metadata):
        original(self, version, metadata)
        with open(self.path, "r+b") as f:  # the end of the file never reached the disk
            f.truncate(self.path.stat().st_size // 2)

    monkeypatch.setattr(storage_mcap.McapWriter, "close", close_cut)
    with pytest.raises(InputError, match="does not read back"):
        write_ros2_bag(tmp_path / "bag", _frames(2))
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("rename", [1, 2])
def test_a_failed_rename_puts_the_earlier_bag_back(tmp_path, monkeypatch, rename):
    target = tmp_path / "bag"
    write_ros2_bag(target, _frames(1, seed=5))
    before = _snapshot(tmp_path)
    install(monkeypatch, "replace", rename=rename)  # 1: moving it aside, 2: the new one in
    with pytest.raises(InputError, match="left as it was"):
        write_ros2_bag(target, _frames(2), replace=True)
    assert _snapshot(tmp_path) == before
    assert _leftovers(tmp_path, "bag") == []


def test_an_interrupted_write_leaves_nothing(tmp_path):
    def frames():
        yield from _frames(2)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_ros2_bag(tmp_path / "bag", frames())
    assert _leftovers(tmp_path) == []


def test_atomic_folder_names_the_target_when_nothing_was_made(tmp_path):
    with pytest.raises(InputError, match="nothing reached the disk"), \
            atomic_folder(tmp_path / "x"):
        pass
    assert _leftovers(tmp_path) == []


# ---- a real full disk -------------------------------------------------------------------------
@pytest.fixture
def small_disk(tmp_path):
    """A 1 MiB tmpfs (needs root and a sandbox that allows `mount`; skipped elsewhere)."""
    if not (sys.platform.startswith("linux") and os.geteuid() == 0):
        pytest.skip("a real full disk needs root to mount a small tmpfs")
    point = tmp_path / "disk"
    point.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1024k", "tmpfs", str(point)],
                          check=False, capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")
    try:
        yield point
    finally:
        subprocess.run(["umount", "-l", str(point)], check=False)


def test_on_a_real_full_disk_the_earlier_bag_stays_byte_for_byte(small_disk):
    target = small_disk / "bag"
    write_ros2_bag(target, _frames(1, seed=5))
    before = _snapshot(small_disk)
    # random pictures do not compress: 12 frames of 320x240 are about 4 MB
    with pytest.raises(InputError, match="disk is full|does not read back"):
        write_ros2_bag(target, _frames(12, size=(320, 240)), replace=True)
    assert _snapshot(small_disk) == before
    assert _leftovers(small_disk, "bag") == []
    assert read_bag(target).count("/stereo/depth") == 1


# ---- the stream's MCAP recordings -------------------------------------------------------------
def test_the_reader_takes_the_streams_topics():
    pytest.importorskip("foxglove")
    from stereo_gui.files.stream_mcap import STREAM_TOPICS
    from stereo_gui.pipeline.stream import TOPICS

    assert all(TOPICS[k] == t for k, t in STREAM_TOPICS.items())


@pytest.fixture(scope="module")
def small_recording(tmp_path_factory):
    """An MCAP file of `serve --mcap` of two 160x120 frames of the simulated scene."""
    pytest.importorskip("foxglove")
    pytest.importorskip("mcap_protobuf")
    from stereo_gui.pipeline.rig import open_rig
    from stereo_gui.pipeline.stream import DepthStream

    path = tmp_path_factory.mktemp("mcap") / "run.mcap"
    with open_rig("sim:scene", None, "live", size=(160, 120)) as rig, DepthStream() as stream:
        stream.record(path)
        for i, frame in enumerate(rig.frames(2)):
            stream.publish(frame.result, 1000.0 + i)
    return path


def test_a_recording_reads_back_frame_by_frame(small_recording):
    from stereo_gui.files.stream_mcap import StreamRecording

    rec = StreamRecording(small_recording)
    frames = list(rec.frames())
    assert rec.frame_count == 2 and len(frames) == 2
    assert frames[1].stamp_ns - frames[0].stamp_ns == 1_000_000_000
    f = frames[0]
    assert f.depth_mm.shape == (120, 160) and f.left_bgr.shape == (120, 160, 3)
    assert f.right_camera.P[3] < 0 and len(f.points_m) == len(f.points_rgb) > 1000
    assert len(list(rec.frames(limit=1))) == 1


def test_damaged_recordings_give_our_error_or_whole_frames(small_recording, tmp_path):
    from hypothesis import HealthCheck, given, settings
    from mutations import damaged_bytes

    from stereo_gui.files.stream_mcap import StreamRecording

    valid = small_recording.read_bytes()
    path = tmp_path / "damaged.mcap"
    loaded = []

    @settings(max_examples=int(os.environ.get("STEREO_GUI_FUZZ_EXAMPLES", "60")),
              derandomize=True, database=None, deadline=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(data=damaged_bytes(valid))
    def refused_or_whole(data: bytes) -> None:
        path.write_bytes(data)
        try:
            frames = list(StreamRecording(path).frames())
        except StereoGuiError:
            loaded.append(False)
            return
        for f in frames:
            assert f.depth_mm.dtype == np.uint16 and f.depth_mm.ndim == 2
            assert len(f.left_camera.P) == 12
        loaded.append(True)

    refused_or_whole()
    assert False in loaded
