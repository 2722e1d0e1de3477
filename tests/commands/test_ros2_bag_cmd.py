"""`stereo-gui ros2-bag`: the depth as a ROS 2 bag, from the simulated rig, from a recording of
ours and from an MCAP file of `serve --mcap`, read back with rosbags as a ROS 2 user's program
reads it (the `ros2` command line is not needed: rosbags writes the standard metadata.yaml that
`ros2 bag info` reads)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("rosbags")
pytest.importorskip("foxglove")
pytest.importorskip("mcap_protobuf")

import stereo_gui.cli
from stereo_gui.commands import ros2_bag as cmd
from stereo_gui.pipeline.stream import LEFT_FRAME, RIGHT_FRAME, cloud_packed, depth_image_mm
from tests.cli_output import one_line, stop_with_signal
from tests.ros2_bags import cloud, image, read_bag, stamp_ns

ENTRY = ("stereo_gui.commands.ros2_bag",
         "write the depth as a ROS 2 bag (rosbag2, MCAP storage)")
TOPICS = {
    "/stereo/depth": "sensor_msgs/msg/Image",
    "/stereo/left/image_rect": "sensor_msgs/msg/Image",
    "/stereo/left/camera_info": "sensor_msgs/msg/CameraInfo",
    "/stereo/right/camera_info": "sensor_msgs/msg/CameraInfo",
    "/stereo/points": "sensor_msgs/msg/PointCloud2",
}
WALL_M = 1.2


def run_cli(*argv) -> int:
    """`stereo-gui ros2-bag ...` as the command line runs it (the subcommand registered for the
    call: cli.py lists it once it is added there)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(stereo_gui.cli.SUBCOMMANDS, "ros2-bag", ENTRY)
        try:
            return stereo_gui.cli.main(["ros2-bag", *map(str, argv)])
        except SystemExit as exc:  # argparse's own refusals
            return int(exc.code)


class _Spy:
    """The rig's frames the command turns into bag frames, with the stamps it gave them."""

    def __init__(self, mp) -> None:
        self.frames: list = []
        self.stamps: list[int] = []
        original = cmd._bag_frame

        def spy(frame, stamps):
            out = original(frame, stamps)
            self.frames.append(frame)
            self.stamps.append(out.stamp_ns)
            return out

        mp.setattr(cmd, "_bag_frame", spy)


def _leftovers(folder: Path, *keep: str) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


def _check_frames(bag, n: int, points: int | None = None) -> list[int]:
    """Every topic with its type and n messages (`points` clouds: an MCAP file of the stream
    holds a cloud at most every CLOUD_EVERY_S); every message with its frame's stamp (the
    header's and the bag's); the frames' stamps, in order."""
    assert bag.types == TOPICS
    want = {t: n for t in TOPICS} | {"/stereo/points": n if points is None else points}
    assert {t: bag.count(t) for t in TOPICS} == want == bag.listed
    stamps = [t for t, _ in bag.messages["/stereo/depth"]]
    assert len(set(stamps)) == n and stamps == sorted(stamps)
    for topic, msgs in bag.messages.items():
        times = [t for t, _ in msgs]
        assert times == (stamps if len(msgs) == n else sorted(set(times) & set(stamps))), topic
        assert [stamp_ns(m) for _, m in msgs] == times, topic
    return stamps


def _check_cameras(bag, calib) -> None:
    fx = calib.focal_px
    baseline_m = calib.rectified_baseline_mm / 1000.0
    left = bag.msgs("/stereo/left/camera_info")[0]
    right = bag.msgs("/stereo/right/camera_info")[0]
    assert (left.header.frame_id, right.header.frame_id) == (LEFT_FRAME, RIGHT_FRAME)
    assert left.p[3] == 0.0 and left.p[0] == pytest.approx(fx)
    assert right.p[3] < 0 and right.p[3] == pytest.approx(-fx * baseline_m, rel=1e-9)
    for info in (left, right):
        assert info.distortion_model == "plumb_bob" and list(info.d) == [0.0] * 5
        assert list(info.r) == [1, 0, 0, 0, 1, 0, 0, 0, 1]
        assert list(info.k) == [*info.p[0:3], *info.p[4:7], *info.p[8:11]]
        assert (info.width, info.height) == tuple(calib.image_size)


# ---- from the simulated rig -------------------------------------------------------------------
@pytest.fixture(scope="module")
def sim_bag(tmp_path_factory):
    """`ros2-bag sim:wall:rig:1.2 --frames 3`: (bag folder, the rig's frames, their stamps,
    stdout)."""
    folder = tmp_path_factory.mktemp("sim")
    out = folder / "bag"
    with pytest.MonkeyPatch.context() as mp:
        spy = _Spy(mp)
        code = run_cli(f"sim:wall:rig:{WALL_M}", "--frames", 3, "-o", out)
    assert code == 0
    return out, spy.frames, spy.stamps


def test_from_the_simulated_rig_every_topic_with_the_frames(sim_bag):
    out, frames, stamps = sim_bag
    bag = read_bag(out)
    assert _check_frames(bag, 3) == stamps
    # the capture times (monotonic s) on the wall clock, their spacing kept to the ns
    spacing = np.diff([f.t_capture for f in frames]) * 1e9
    assert np.abs(np.diff(stamps) - spacing).max() <= 1
    assert _leftovers(out.parent, "bag") == []
    meta = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == "mcap" and meta["message_count"] == 15
    assert meta["relative_file_paths"] == ["bag.mcap"]


def test_from_the_simulated_rig_depth_picture_and_cloud_are_the_frames(sim_bag):
    out, frames, _ = sim_bag
    bag = read_bag(out)
    for frame, depth, left, pc in zip(frames, bag.msgs("/stereo/depth"),
                                      bag.msgs("/stereo/left/image_rect"),
                                      bag.msgs("/stereo/points")):
        assert (depth.encoding, depth.header.frame_id) == ("16UC1", LEFT_FRAME)
        assert np.array_equal(image(depth), depth_image_mm(frame.result))
        assert left.encoding == "bgr8"
        assert np.array_equal(image(left), frame.result.rectified_left)
        data, n = cloud_packed(frame.result)
        want = np.frombuffer(data, dtype=[("xyz", "<f4", 3), ("rgba", "u1", 4)])
        xyz, rgb = cloud(pc)
        assert (pc.height, pc.width, pc.point_step, pc.header.frame_id) == (1, n, 16, LEFT_FRAME)
        assert np.array_equal(xyz, want["xyz"]) and np.array_equal(rgb, want["rgba"][:, :3])
        assert np.median(xyz[:, 2]) == pytest.approx(WALL_M, rel=0.02)
    # a whole-frame sanity check: the wall reads at its distance over most of the picture
    d = image(bag.msgs("/stereo/depth")[-1])
    assert (d > 0).mean() > 0.5
    assert np.median(d[d > 0]) == pytest.approx(WALL_M * 1000, rel=0.02)


def test_from_the_simulated_rig_the_cameras_are_the_rectified_ones(sim_bag):
    out, frames, _ = sim_bag
    _check_cameras(read_bag(out), frames[0].calibration)


# ---- from an MCAP file of `serve --mcap` ------------------------------------------------------
@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """An MCAP file of three frames of the wall (DepthStream, as `serve --mcap` records), the
    frames, and what the file holds by topic (decoded)."""
    from stereo_gui.pipeline.rig import open_rig
    from stereo_gui.pipeline.stream import DepthStream

    path = tmp_path_factory.mktemp("mcap") / "run.mcap"
    with open_rig(f"sim:wall:rig:{WALL_M}", None, "live") as rig, DepthStream() as stream:
        stream.record(path)
        frames = list(rig.frames(3))
        for i, frame in enumerate(frames):
            stream.publish(frame.result, 1000.0 + i)
    return path, frames, _decoded(path)


def _decoded(path) -> dict[str, list]:
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    out: dict[str, list] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, _, msg in reader.iter_decoded_messages(topics=[
                "/stereo/depth", "/stereo/left/image", "/stereo/right/camera_info",
                "/stereo/points"]):
            out.setdefault(channel.topic, []).append(msg)
    return out


def test_from_an_mcap_file_the_bag_holds_its_frames(recorded, tmp_path, capsys):
    import cv2

    path, frames, got = recorded
    out = tmp_path / "bag"
    assert run_cli(path, "-o", out) == 0
    assert "wrote 3 frames" in capsys.readouterr().out
    bag = read_bag(out)
    stamps = _check_frames(bag, 3, points=len(got["/stereo/points"]))
    assert stamps == [m.timestamp.ToNanoseconds() for m in got["/stereo/depth"]]
    assert [t for t, _ in bag.messages["/stereo/points"]] == [
        m.timestamp.ToNanoseconds() for m in got["/stereo/points"]]
    for frame, src, depth in zip(frames, got["/stereo/depth"], bag.msgs("/stereo/depth")):
        mcap_depth = np.frombuffer(src.data, np.uint16).reshape(src.height, src.width)
        assert np.array_equal(image(depth), mcap_depth)
        assert np.array_equal(image(depth), depth_image_mm(frame.result))
    for src, left in zip(got["/stereo/left/image"], bag.msgs("/stereo/left/image_rect")):
        jpeg = cv2.imdecode(np.frombuffer(src.data, np.uint8), cv2.IMREAD_COLOR)
        assert np.array_equal(image(left), jpeg)
    for src, pc in zip(got["/stereo/points"], bag.msgs("/stereo/points")):
        pts = np.frombuffer(src.data, dtype=[("xyz", "<f4", 3), ("rgba", "u1", 4)])
        xyz, rgb = cloud(pc)
        assert pc.width == len(pts) > 1000
        assert np.array_equal(xyz, pts["xyz"]) and np.array_equal(rgb, pts["rgba"][:, :3])
    for src, info in zip(got["/stereo/right/camera_info"], bag.msgs("/stereo/right/camera_info")):
        assert list(info.p) == list(src.P) and list(info.k) == list(src.K)
    _check_cameras(bag, frames[0].calibration)
    assert _leftovers(tmp_path, "bag") == []


def test_from_an_mcap_file_at_most_n_frames_and_force_replaces(recorded, tmp_path, capsys):
    path, _, got = recorded
    out = tmp_path / "bag"
    assert run_cli(path, "-o", out, "--frames", 1) == 0
    assert read_bag(out).count("/stereo/depth") == 1
    assert run_cli(path, "-o", out, "--frames", 2, "--force") == 0
    two = {m.timestamp.ToNanoseconds() for m in got["/stereo/depth"][:2]}
    clouds = sum(m.timestamp.ToNanoseconds() in two for m in got["/stereo/points"])
    _check_frames(read_bag(out), 2, points=clouds)
    assert _leftovers(tmp_path, "bag") == []


# ---- from a recording folder ------------------------------------------------------------------
@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A recording folder of five frames of the simulated wall (times 1/30 s apart) and the
    rig's true calibration as a file: (folder, calibration file, recorded times)."""
    from stereo_gui.files.calibration_file import save_calibration
    from stereo_gui.files.recording import RecordingWriter
    from stereo_gui.sources.base import StereoFrame
    from stereo_gui.sources.sim import Scene, SimRig

    root = tmp_path_factory.mktemp("rec")
    rig = SimRig(seed=3)
    times = [500.0 + i / 30.0 for i in range(5)]
    with RecordingWriter(root / "rec", fps=30.0, background=False) as w:
        for i, t in enumerate(times):
            left, right = rig.render_scene(Scene.wall(1500.0), np.random.default_rng(i))
            w.write(StereoFrame(left, right, t, t, i))
    calib = save_calibration(rig.true_calibration(), root / "calib.yaml")
    return root / "rec", calib, times


def test_from_a_recording_every_frame_once_on_its_clock(recording, tmp_path, capsys):
    from datetime import datetime

    folder, calib, times = recording
    out = tmp_path / "bag"
    with pytest.MonkeyPatch.context() as mp:
        spy = _Spy(mp)
        assert run_cli(folder, "--calib", calib, "-o", out) == 0
    text = capsys.readouterr().out
    assert "wrote 5 frames" in text and "skipped" not in text
    assert [f.index for f in spy.frames] == [0, 1, 2, 3, 4]  # none skipped, none twice
    stamps = _check_frames(read_bag(out), 5)
    # counted from when the recording was made, spaced as recorded
    created = json.loads((folder / "recording.json").read_text())["created"]
    assert stamps[0] == round(datetime.fromisoformat(created).timestamp() * 1e9)
    assert np.abs(np.diff(stamps) - np.diff(times) * 1e9).max() <= 1
    depth = image(read_bag(out).msgs("/stereo/depth")[2])
    assert np.array_equal(depth, depth_image_mm(spy.frames[2].result))


# ---- refusals ---------------------------------------------------------------------------------
def _other_mcap(path: Path) -> None:
    from mcap.writer import Writer

    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("x", "jsonschema", b"{}")
        cid = w.register_channel("/chatter", "json", sid)
        w.add_message(cid, log_time=1, publish_time=1, data=b"{}")
        w.finish()


@pytest.mark.parametrize("make_input, extra, words", [
    (None, ["nope.mcap"], ["nope.mcap", "no such MCAP file"]),
    (None, ["nope"], ["nope", "no such file or folder"]),
    (lambda d: (d / "notes.mcap").write_text("hello"), ["notes.mcap"], ["not an MCAP file"]),
    (lambda d: _other_mcap(d / "other.mcap"), ["other.mcap"],
     ["other.mcap", "not a depth recording", "/stereo/depth"]),
    (None, ["sim"], ["sim", "--frames"]),
    (None, ["sim", "--frames", "0"], ["--frames"]),
    (None, ["sim", "--frames", "1", "--preset", "nonesuch"], ["nonesuch"]),
    (None, ["sim", "--frames", "1", "--calib", "none.yaml"], ["none.yaml"]),
])
def test_bad_input_is_one_line_and_nothing_is_written(make_input, extra, words, tmp_path,
                                                      monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    if make_input is not None:
        make_input(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    code = run_cli(*extra, "-o", "bag")
    one_line(capsys.readouterr().err, code, *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_recording_without_calibration_is_one_line(recording, tmp_path, capsys):
    folder, _, _ = recording
    code = run_cli(folder, "-o", tmp_path / "bag")
    one_line(capsys.readouterr().err, code, "--calib")
    assert _leftovers(tmp_path) == []


def test_an_mcap_file_takes_no_calibration(recorded, tmp_path, capsys):
    path, _, _ = recorded
    code = run_cli(path, "--calib", "c.yaml", "-o", tmp_path / "bag")
    one_line(capsys.readouterr().err, code, "--calib", "MCAP")


def test_an_existing_output_is_refused_unless_forced(recorded, tmp_path, capsys):
    path, _, _ = recorded
    out = tmp_path / "bag"
    out.mkdir()
    (out / "metadata.yaml").write_text("kept\n")
    code = run_cli(path, "-o", out)
    one_line(capsys.readouterr().err, code, str(out), "exists", "--force")
    assert (out / "metadata.yaml").read_text() == "kept\n"
    other = tmp_path / "thesis"
    other.mkdir()
    (other / "chapter1.tex").write_text("x")
    code = run_cli(path, "-o", other, "--force")
    one_line(capsys.readouterr().err, code, "not a ROS 2 bag")
    assert sorted(p.name for p in other.iterdir()) == ["chapter1.tex"]


def test_a_full_disk_is_one_line_and_the_earlier_bag_stays(recorded, tmp_path, monkeypatch,
                                                            capsys):
    import errno
    import os

    from rosbags.rosbag2 import storage_mcap

    path, _, _ = recorded
    out = tmp_path / "bag"
    assert run_cli(path, "-o", out, "--frames", 1) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()

    def full(self, connection, timestamp, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(storage_mcap.McapWriter, "write", full)
    code = run_cli(path, "-o", out, "--force")
    one_line(capsys.readouterr().err, code, "disk is full", "left as it was")
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert _leftovers(tmp_path, "bag") == []


def test_sigterm_leaves_no_temporary_bag(tmp_path):
    import sys

    # (the bag is being written once its temporary folder holds its MCAP file)
    code, _, err = stop_with_signal(
        [sys.executable, "-m", "stereo_gui", "ros2-bag", "sim", "--frames", "100000", "-o",
         str(tmp_path / "bag")],
        lambda _p: bool(list(tmp_path.glob(".bag.*.partial/bag/*.mcap"))), timeout=60)
    assert code == 130 and "interrupted" in err and "Traceback" not in err, err
    assert _leftovers(tmp_path) == []
