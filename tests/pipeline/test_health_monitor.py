"""The calibration-health monitor: off the frame path, at most one check at a time and every
`interval_s`; the Live processor's output carries the newest figure."""

from __future__ import annotations

import threading

import numpy as np

from stereo_gui.core.preset import MatcherParams
from stereo_gui.pipeline.health import HealthMonitor
from stereo_gui.pipeline.live import LiveProcessor
from stereo_gui.sources.sim import Scene


def test_checks_run_in_a_thread_of_their_own_and_not_too_often(sim_rig_pair):
    left, right = sim_rig_pair
    mon = HealthMonitor(interval_s=1.0)
    try:
        assert mon.offer(left, right, now=100.0)
        assert not mon.offer(left, right, now=100.5)  # one running, and too soon
        h = mon.wait(60)
        assert h is not None and h.measured
        assert not mon.offer(left, right, now=100.9)  # less than a second after the last
        assert mon.offer(left, right, now=101.2)
        mon.wait(60)
        names = {t.name for t in threading.enumerate()}
        assert any(n.startswith("health") for n in names)
    finally:
        mon.close()


def test_live_output_carries_the_figure(sim_rig):
    calib = sim_rig.true_calibration()
    left, right = sim_rig.render_scene(Scene.demo(), np.random.default_rng(0))
    proc = LiveProcessor(calib, MatcherParams(num_disparities=32, block_size=5))
    try:
        from stereo_gui.sources.base import StereoFrame

        out = proc(StereoFrame(left, right, 0.0, 0.0, 0))
        assert out.health is None  # the first check has only started
        proc.health.wait(60)
        out = proc(StereoFrame(left, right, 0.0, 0.0, 1))
        assert out.health is not None and out.health.measured and not out.health.drifted
    finally:
        proc.close()


def test_a_check_cancelled_by_closing_is_no_failure(caplog):
    """Closing with a check still queued cancels it: no "calibration health check failed: "
    warning with an empty reason at every quit."""
    from concurrent.futures import Future

    from stereo_gui.pipeline.health import HealthMonitor

    monitor = HealthMonitor()
    cancelled: Future = Future()
    cancelled.cancel()
    # what close() leaves of a check queued but not begun (a race no public call can time)
    monitor._pending = cancelled
    with caplog.at_level("WARNING"):
        assert monitor.latest() is None
    assert "failed" not in caplog.text
    monitor.close()
