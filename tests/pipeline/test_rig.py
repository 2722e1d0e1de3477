"""The Python API (`stereo_gui.open_rig`): the window's pipeline for a robot's program."""

from __future__ import annotations

import time

import numpy as np
import pytest

import stereo_gui
from stereo_gui.core.errors import InputError, SourceError, StereoGuiError
from stereo_gui.pipeline.rig import Frame, Reading, Rig, open_rig
from stereo_gui.sources.base import FrameSource, StereoFrame


def test_the_package_offers_the_api():
    assert stereo_gui.open_rig is open_rig and stereo_gui.Reading is Reading
    with pytest.raises(AttributeError):
        stereo_gui.no_such_thing  # noqa: B018


def test_frames_of_the_simulated_wall_read_its_distance():
    with open_rig("sim:wall:rig:1.5", None, "live") as rig:
        frames = list(rig.frames(3))
        assert "true calibration" in rig.description
    assert [isinstance(f, Frame) for f in frames] == [True] * 3
    f = frames[-1]
    assert f.depth_mm.dtype == np.uint16 and f.depth_mm.shape == (480, 640)
    r = f.measure(400, 240)
    assert r.valid and r.reason is None
    assert r.z_mm == pytest.approx(1500, rel=0.01) and 0 < r.pm_mm < 20
    assert "m +-" in str(r)
    near = f.nearest(region=(360, 200, 80, 80), alarm_mm=2000.0)
    assert near.nearest_mm == pytest.approx(1500, rel=0.02) and near.alarm
    assert not f.nearest(region=(360, 200, 80, 80)).alarm
    whole = f.nearest()
    assert whole.valid_share > 0.5
    off = f.measure(-5, 10)
    assert not off.valid and off.reason
    with pytest.raises(InputError, match="positive width"):
        f.nearest(region=(0, 0, 0, 10))


def test_a_watched_region_comes_with_every_frame():
    with open_rig("sim:wall:rig:1.0", None, "live") as rig:
        rig.watch((300, 200, 60, 60), alarm_mm=1200.0)
        f = next(iter(rig.frames(1)))
    assert f.output.region is not None and f.output.region.alarm


class _Slow(FrameSource):
    """A source of 8 numbered frames, quicker than its reader, then ended."""

    name = "numbers"
    nominal_fps = 100.0

    def __init__(self, frames):
        self._frames = list(frames)
        self.closed = False

    def read(self) -> StereoFrame:
        if not self._frames:
            raise StopIteration
        time.sleep(0.01)
        return self._frames.pop(0)

    def close(self) -> None:
        self.closed = True


class _Failing(FrameSource):
    name = "broken"
    nominal_fps = 30.0

    def read(self) -> StereoFrame:
        raise SourceError("camera 1 disappeared")

    def close(self) -> None:
        pass


def _numbered(n: int, sim_rig_pair_raw):
    left, right = sim_rig_pair_raw
    return [StereoFrame(left, right, float(i), float(i), i) for i in range(n)]


@pytest.fixture(scope="module")
def raw_pair(sim_rig):
    from stereo_gui.sources.sim import Scene

    return sim_rig.render_scene(Scene.wall(1200.0), np.random.default_rng(0))


def test_a_slow_program_gets_the_newest_frame_and_skips_the_rest(sim_rig, raw_pair):
    source = _Slow(_numbered(8, raw_pair))
    rig = Rig(source, sim_rig.true_calibration(), "live")
    seen = []
    with rig:
        for f in rig.frames():
            seen.append(f.index)
            time.sleep(0.05)  # five source frames' time
    assert seen == sorted(seen) and seen[-1] == 7
    assert len(seen) < 8 and rig.dropped_frames == 8 - len(seen)
    assert source.closed


def test_a_failing_source_raises_its_error(sim_rig):
    with (Rig(_Failing(), sim_rig.true_calibration(), "live") as rig,
          pytest.raises(SourceError, match="disappeared")):
        next(iter(rig.frames()))


def test_errors_are_the_command_lines(tmp_path):
    with pytest.raises(StereoGuiError, match="preset"):
        open_rig("sim", None, "no-such-preset")
    with pytest.raises(InputError):
        open_rig("cams:zz", None, "live")
    missing = tmp_path / "calib.yaml"
    with pytest.raises(StereoGuiError, match="calib.yaml"):
        open_rig("sim", str(missing), "live")
    (tmp_path / "pairs").mkdir()
    with pytest.raises(StereoGuiError):
        open_rig(str(tmp_path / "pairs"), None, "live")


def test_a_closed_rig_gives_no_frames(sim_rig, raw_pair):
    rig = Rig(_Slow(_numbered(2, raw_pair)), sim_rig.true_calibration(), "live")
    rig.close()
    rig.close()
    with pytest.raises(InputError, match="closed"):
        next(iter(rig.frames()))


def test_every_frame_of_a_source_in_turn_none_skipped(sim_rig, raw_pair):
    source = _Slow(_numbered(6, raw_pair))
    with Rig(source, sim_rig.true_calibration(), "live") as rig:
        seen = []
        for f in rig.frames(every=True):
            seen.append(f.index)
            time.sleep(0.03)  # slower than the source: nothing is skipped all the same
    assert seen == list(range(6)) and rig.dropped_frames == 0
