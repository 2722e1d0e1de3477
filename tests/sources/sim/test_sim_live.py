"""The simulated rig as a live source: frames, modes, pacing."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.errors import InputError, SourceError
from stereo_gui.sources.sim import (
    RigConfig,
    SimFrameTruth,
    SimRig,
    SimSource,
)


def test_sim_source_frames():
    src = SimSource(SimRig(RigConfig(supersample=2)), mode="mixed", paced=False, seed=1)
    # the capabilities it has and has not: its rig and the rig's cameras, no playback
    assert src.simulated_rig() is src.rig and src.camera_controls() is not None
    assert src.playback() is None
    assert src.name == "Simulated rig" and src.nominal_fps == 30.0
    frames = [src.read() for _ in range(4)]
    assert [f.index for f in frames] == [0, 1, 2, 3]
    f = frames[-1]
    assert f.left.shape == (480, 640, 3) and f.right.shape == (480, 640, 3)
    assert isinstance(f.truth, SimFrameTruth) and f.truth.pose is not None
    assert f.truth.scene is not None and f.truth.truth.baseline_mm == pytest.approx(110.0)
    # the board moves smoothly: consecutive poses differ by little
    step = np.linalg.norm(frames[2].truth.pose.t - frames[1].truth.pose.t)
    assert 0 < step < 60
    src.close()
    src.close()
    with pytest.raises(SourceError):
        src.read()


def test_sim_source_modes_and_bad_arguments():
    rig = SimRig(RigConfig(supersample=1))
    scene_only = SimSource(rig, mode="scene", paced=False).read()
    assert scene_only.truth.pose is None and scene_only.truth.scene is not None
    board_only = SimSource(rig, mode="board", paced=False).read()
    assert board_only.truth.scene is None and board_only.truth.pose is not None
    with pytest.raises(InputError):
        SimSource(rig, mode="cinema")
    with pytest.raises(InputError):
        SimSource(rig, fps=0)


def test_sim_source_paces_frames(monkeypatch):
    """paced=True waits for the next frame time (a fake clock: tests never sleep)."""
    import stereo_gui.sources.sim.live as live

    clock = {"t": 100.0}
    slept = []
    monkeypatch.setattr(live.time, "monotonic", lambda: clock["t"])

    def fake_sleep(dt):
        slept.append(dt)
        clock["t"] += dt

    monkeypatch.setattr(live.time, "sleep", fake_sleep)
    src = SimSource(SimRig(RigConfig(supersample=1)), mode="scene", fps=10.0, paced=True)
    times = [src.read().t_left for _ in range(3)]
    assert times == pytest.approx([100.0, 100.1, 100.2])
    assert sum(slept) == pytest.approx(0.2)


@pytest.mark.parametrize("mode", ["mixed", "board"])
def test_the_live_rigs_resting_poses_make_a_set_ready_to_calibrate(mode):
    """Where the live board rests (every second frame with two frames a move), both cameras see
    it whole, in front of the scene's objects, and three rounds of its places satisfy the Capture
    tab's own readiness rule (random poses left image corners empty after 50 pairs)."""
    from stereo_gui.core.board import BoardSpec
    from stereo_gui.core.coverage import readiness
    from stereo_gui.core.detect import detect_pair

    rig = SimRig(RigConfig(supersample=2))
    src = SimSource(rig, mode=mode, paced=False, seed=0, frames_per_move=2)
    board = BoardSpec()
    kept = []
    for i in range(2 * len(SimRig.PLACES) * 3):
        f = src.read()
        if i % 2 == 0:
            det = detect_pair(f"rest {i}", f.left, f.right, board)
            assert det.found, f"frame {i}: {det.reason}"
            kept.append(det)
    src.close()
    r = readiness(kept, board, rig.config.image_size)
    assert r.ready, r.summary()
