"""Every writer on a real full filesystem: a clear error, and the old file byte for byte.

A small tmpfs is mounted for the module (this needs root and a sandbox that allows `mount`;
elsewhere the module is skipped, and tests/files/test_atomic.py still fails every step of a
write by injection). For each writer: a good old file is written with room to spare, the disk
is filled up to 0 or 4 KiB free, the writer runs again with other data, and it must raise our
error, leave no temporary file and leave the old file exactly as it was.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.stereo_calibration import StereoCalibration

from factories import make_calibration, make_records

SIZE_KIB = 512
FREE = (0, 4096)  # bytes left on the disk when the writer runs


def _can_mount() -> bool:
    return sys.platform.startswith("linux") and hasattr(os, "geteuid") and os.geteuid() == 0


@pytest.fixture(scope="module")
def mount_point(tmp_path_factory):
    if not _can_mount():
        pytest.skip("a real full disk needs root to mount a small tmpfs")
    point = tmp_path_factory.mktemp("fulldisk")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={SIZE_KIB}k", "tmpfs", str(point)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")
    try:
        yield point
    finally:
        subprocess.run(["umount", "-l", str(point)], check=False)


class Disk:
    def __init__(self, root: Path) -> None:
        self.root = root
        self._filler = root / ".filler"

    def clear(self) -> None:
        for p in self.root.iterdir():
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p)
            else:
                p.unlink()

    def fill(self, free: int) -> None:
        """Fill the filesystem, then give back `free` bytes."""
        fd = os.open(self._filler, os.O_WRONLY | os.O_CREAT | os.O_APPEND)
        block = b"\0" * 65536
        try:
            while True:
                try:
                    os.write(fd, block)
                except OSError:
                    if len(block) == 1:
                        break
                    block = block[: len(block) // 2]
        finally:
            os.close(fd)
        if free:
            os.truncate(self._filler, max(0, self._filler.stat().st_size - free))

    def unfill(self) -> None:
        self._filler.unlink(missing_ok=True)

    def snapshot(self) -> dict[str, bytes]:
        return {str(p.relative_to(self.root)): p.read_bytes()
                for p in sorted(self.root.rglob("*")) if p.is_file() and p != self._filler}


@pytest.fixture
def disk(mount_point):
    d = Disk(mount_point)
    d.clear()
    yield d
    d.unfill()
    d.clear()


# ---- the writers ----------------------------------------------------------------------------
def _noise(h, w, seed, channels=3):
    rng = np.random.default_rng(seed)
    shape = (h, w, channels) if channels > 1 else (h, w)
    return rng.integers(0, 256, shape, np.uint8)


def _disparity(seed):
    rng = np.random.default_rng(seed)
    d = rng.uniform(5, 60, (60, 80)).astype(np.float32)
    d[rng.random(d.shape) < 0.1] = np.nan
    return d


IDENTITY = StereoCalibration.identity((80, 60), 300.0, 100.0)


def _w_calibration(root, version):
    from stereo_gui.core.stereo_calibration import PairError
    from stereo_gui.files.calibration_file import save_calibration

    calib = make_calibration(0.0 if version == 0 else 0.7)
    if version:  # more than 4 KiB: it cannot fit
        calib = calib.with_updates(per_pair=tuple(PairError(f"chessboard-{i}", 0.1 + i / 997,
                                                            0.2 + i / 991) for i in range(80)))
    save_calibration(calib, root / "calib.yaml")


def _w_ros(root, version):
    from stereo_gui.files.calibration_file import export_ros

    export_ros(make_calibration(0.0 if version == 0 else 0.7), root)


def _w_preset(root, version):
    from stereo_gui.core.preset import MatcherParams, Preset
    from stereo_gui.files.presets import save_user_preset

    os.environ["STEREO_GUI_CONFIG_DIR"] = str(root / "config")
    save_user_preset(Preset("mine", "x" * 3000 * (1 + version),
                            MatcherParams(block_size=5 + 2 * version)))


def _w_fit(root, version):
    from stereo_gui.core.regression import fit_inverse
    from stereo_gui.files.fit_file import save_fit

    rng = np.random.default_rng(version)
    samples = [(d, 82500.0 / d + e) for d, e in zip(np.linspace(30, 90, 40 + 200 * version),
                                                     rng.normal(0, 3, 40 + 200 * version),
                                                     strict=True)]
    save_fit(fit_inverse(samples), root / "fit.json")


def _w_settings(root, version):
    from stereo_gui.files.settings import Settings, save_settings

    save_settings(Settings(preset="seed" if version == 0 else "live",
                           recent_files=tuple(f"/some/file/{i}-{'y' * 40}.yaml"
                                              for i in range(1 + 80 * version))),
                  root / "settings.json")


def _w_session(root, version):
    from stereo_gui.files.session import CaptureSession

    if version == 0:
        s = CaptureSession.create(root / "session", resolution=(64, 48))
    else:
        s = CaptureSession.open(root / "session")
    s.add_pair(_noise(48, 64, version), _noise(48, 64, version + 10))


def _w_session_exclude(root, version):
    from stereo_gui.files.session import CaptureSession

    if version == 0:
        s = CaptureSession.create(root / "session", resolution=(64, 48))
        s.add_pair(_noise(48, 64, 1), _noise(48, 64, 2))
    else:
        s = CaptureSession.open(root / "session")
        s.set_excluded(s.pairs[0].name, True)


def _controls(version):
    from stereo_gui.core.camera_settings import CameraSettings, PairSettings

    cam = CameraSettings("V4L2", focus_auto=False, focus=30.0 + 5 * version,
                         exposure_auto=False, exposure=156.0, gain=float(version))
    return PairSettings(cam, cam)


def _w_calibration_controls(root, version):
    from stereo_gui.core.stereo_calibration import PairError
    from stereo_gui.files.calibration_file import save_calibration

    calib = make_calibration(0.0).with_updates(camera_controls=_controls(version))
    if version:  # more than 4 KiB: it cannot fit
        calib = calib.with_updates(per_pair=tuple(PairError(f"chessboard-{i}", 0.1 + i / 997,
                                                            0.2 + i / 991) for i in range(80)))
    save_calibration(calib, root / "calib.yaml")


def _w_session_controls(root, version):
    from stereo_gui.files.session import CaptureSession

    if version == 0:
        s = CaptureSession.create(root / "session", resolution=(64, 48))
        s.add_pair(_noise(48, 64, 1), _noise(48, 64, 2))
        s.set_camera_controls(_controls(0))
    else:
        s = CaptureSession.open(root / "session")
        try:
            s.set_camera_controls(_controls(1))
        finally:  # the session in memory keeps what is on disk
            assert s.camera_controls == _controls(0)


def _w_xlsx(root, version):
    from stereo_gui.files.spreadsheet import write_workbook

    write_workbook(root / "log.xlsx", make_records(3 + 200 * version),
                   calibration=make_calibration())


def _w_xlsx_append(root, version):
    from stereo_gui.files.spreadsheet import append_measurements

    append_measurements(root / "log.xlsx", make_records(3 + 200 * version))


def _w_csv(root, version):
    from stereo_gui.files.spreadsheet import write_csv

    write_csv(root / "log.csv", make_records(3 + 200 * version))


def _w_png16(root, version):
    from stereo_gui.files.depth_export import write_disparity_png16

    write_disparity_png16(root / "d16.png", _disparity(version))


def _w_depth(root, version):
    from stereo_gui.files.depth_export import write_depth_png16

    write_depth_png16(root / "z16.png", _disparity(version), IDENTITY)


def _w_npy(root, version):
    from stereo_gui.files.depth_export import write_disparity_npy

    write_disparity_npy(root / "d.npy", _disparity(version))


def _w_ply(root, version):
    from stereo_gui.files.depth_export import write_ply

    write_ply(root / "c.ply", _disparity(version), _noise(60, 80, version), IDENTITY)


def _w_snapshot(root, version):
    from stereo_gui.files.atomic import write_image_atomic

    write_image_atomic(root / "snapshot.png", _noise(60, 80, version))


def _w_truth(root, version):
    from stereo_gui.files.atomic import write_json_atomic

    write_json_atomic(root / "truth.json", {"scenes": list(range(5 + 3000 * version))})


def _w_measurement_log(root, version):
    from stereo_gui.files.measurement_log import KeptLog, save_log
    from stereo_gui.files.spreadsheet import MeasurementRecord

    recs = tuple(MeasurementRecord(time="2026-12-01T10:00:00+00:00", x_px=float(i), y_px=2.0,
                                   disparity_px=40.0, X_mm=0.0, Y_mm=0.0, Z_mm=2000.0,
                                   range_mm=2000.0, valid=True)
                 for i in range(5 + 300 * version))
    save_log(KeptLog(recs), root / "measurement-log.json")


WRITERS = {
    "calibration": _w_calibration, "ros": _w_ros, "preset": _w_preset, "fit": _w_fit,
    "settings": _w_settings, "session-pair": _w_session, "session-exclude": _w_session_exclude,
    "xlsx": _w_xlsx, "xlsx-append": _w_xlsx_append, "csv": _w_csv, "png16": _w_png16,
    "depth-png16": _w_depth, "npy": _w_npy, "ply": _w_ply, "snapshot": _w_snapshot,
    "json": _w_truth, "measurement-log": _w_measurement_log,
    "calibration-controls": _w_calibration_controls, "session-controls": _w_session_controls,
}


@pytest.fixture
def _restore_config_env():
    old = os.environ.get("STEREO_GUI_CONFIG_DIR")
    yield
    if old is None:
        os.environ.pop("STEREO_GUI_CONFIG_DIR", None)
    else:
        os.environ["STEREO_GUI_CONFIG_DIR"] = old


# the new data of these is smaller than 4 KiB, so they are run with 0 bytes free only (a
# manifest that fits is rightly written); ROS writes two small files, which need two pages
SMALL = {"session-exclude", "session-controls"}
CASES = [(name, free) for name in sorted(WRITERS) for free in FREE
         if not (free and name in SMALL)]


@pytest.mark.parametrize(("name", "free"), CASES)
def test_every_writer_fails_cleanly_and_keeps_the_old_file(disk, name, free, capfd,
                                                            _restore_config_env):
    write = WRITERS[name]
    write(disk.root, 0)
    before = disk.snapshot()
    assert before
    disk.fill(free)
    with pytest.raises(StereoGuiError) as info:
        write(disk.root, 1)
    disk.unfill()
    message = str(info.value)
    assert "cannot write" in message or "cannot" in message, message
    after = disk.snapshot()
    assert after == before, f"{name}: the old files changed or a temporary file was left"
    leftovers = [p.name for p in disk.root.rglob(".*") if p.name != ".filler"]
    assert leftovers == []
    err = capfd.readouterr().err
    assert "Exception ignored" not in err and "Traceback" not in err, err


def test_a_recording_on_a_full_disk_stops_with_an_error_and_keeps_its_frames(disk):
    from stereo_gui.files.recording import RecordingWriter, open_recording
    from stereo_gui.sources.base import StereoFrame

    w = RecordingWriter(disk.root / "rec", fps=30.0, background=False)
    for i in range(3):
        w.write(StereoFrame(_noise(48, 64, i), _noise(48, 64, i + 50), i / 30, i / 30, i))
    disk.fill(0)
    with pytest.raises(StereoGuiError, match="No space left"):
        for i in range(3, 20):
            w.write(StereoFrame(_noise(48, 64, i), _noise(48, 64, i + 50), i / 30, i / 30, i))
    with pytest.raises(StereoGuiError):
        w.close()
    disk.unfill()
    back = open_recording(disk.root / "rec")
    assert [f.index for f in back.frames][:3] == [0, 1, 2]
    for f in back.frames:
        assert cv2.imread(str(f.left)) is not None and cv2.imread(str(f.right)) is not None


def test_a_recording_that_cannot_start_on_a_full_disk_says_so_and_leaves_nothing(disk):
    """Record with no space left: the disk is full, said in words (it was "unexpected error" and
    a traceback at the frame list's flush), and no empty rec-... folder is left behind; a folder
    the person chose stays, empty."""
    from stereo_gui.files.recording import RecordingWriter

    disk.fill(0)
    with pytest.raises(StereoGuiError, match="the disk is full"):
        RecordingWriter(disk.root / "rec", fps=30.0, background=False)
    assert not (disk.root / "rec").exists()
    disk.unfill()
    (disk.root / "chosen").mkdir()
    disk.fill(0)
    with pytest.raises(StereoGuiError, match="the disk is full"):
        RecordingWriter(disk.root / "chosen", fps=30.0, background=False)
    assert (disk.root / "chosen").is_dir() and not any((disk.root / "chosen").iterdir())


def _cli(*argv, cwd):
    env = dict(os.environ, PYTHONFAULTHANDLER="1")
    return subprocess.run([sys.executable, "-m", "stereo_gui", *map(str, argv)],
                          capture_output=True, text=True, cwd=cwd, env=env, timeout=300)


@pytest.mark.slow
def test_calibrate_on_a_full_disk_exits_2_and_keeps_the_old_calibration(disk, tmp_path):
    """`calibrate -o calib.yaml` over a good file with 4 KiB free: exit 2, the old file kept."""
    from stereo_gui.sources.sim import write_calibration_set

    (tmp_path / "pairs").mkdir()
    pairs = write_calibration_set(tmp_path / "pairs", n_pairs=8, seed=5)
    target = disk.root / "calib.yaml"
    from stereo_gui.files.calibration_file import save_calibration

    save_calibration(make_calibration(), target)
    before = target.read_bytes()
    disk.fill(4096)
    done = _cli("calibrate", pairs, "--board", "9x6", "--square-mm", "25", "-o", target,
                cwd=tmp_path)
    disk.unfill()
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "No space left" in lines[0], done.stderr
    assert target.read_bytes() == before
    assert "wrote" not in done.stdout


def test_disparity_on_a_full_disk_exits_2_and_keeps_the_old_outputs(disk, tmp_path):
    left = _noise(60, 80, 1)
    right = np.roll(left, -8, axis=1)
    cv2.imwrite(str(tmp_path / "l.png"), left)
    cv2.imwrite(str(tmp_path / "r.png"), right)
    outs = [disk.root / "v.png", disk.root / "d.npy", disk.root / "c.ply"]
    for p in outs:
        p.write_bytes(b"old " + p.name.encode())
    disk.fill(0)
    done = _cli("disparity", "--calib", "rectified:300,100", tmp_path / "l.png",
                tmp_path / "r.png", "-o", outs[0], "--npy", outs[1], "--ply", outs[2],
                cwd=tmp_path)
    disk.unfill()
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    for p in outs:
        assert p.read_bytes() == b"old " + p.name.encode()


@pytest.fixture
def big_disk(tmp_path_factory):
    """A tmpfs of 8 MiB: a simulated set of 640x480 pairs does not fit in the small one."""
    if not _can_mount():
        pytest.skip("a real full disk needs root to mount a small tmpfs")
    point = tmp_path_factory.mktemp("bigdisk")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=8m", "tmpfs", str(point)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")
    try:
        yield Disk(point)
    finally:
        subprocess.run(["umount", "-l", str(point)], check=False)


def test_simulate_overwrite_on_a_filling_disk_keeps_the_earlier_set(big_disk, tmp_path):
    """With room for about half of the new set, the earlier one stays whole (not its images
    replaced while truth.json still describes the old set)."""
    disk = big_disk
    out = disk.root / "set"
    done = _cli("simulate", out, "--pairs", "3", "--seed", "1", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    before = disk.snapshot()
    size = sum(len(v) for v in before.values())
    disk.fill(size // 2)
    done = _cli("simulate", out, "--pairs", "3", "--seed", "2", "--overwrite", cwd=tmp_path)
    disk.unfill()
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "was not written" in lines[0], done.stderr
    assert disk.snapshot() == before
    assert [p.name for p in disk.root.rglob(".*") if p.name != ".filler"] == []
