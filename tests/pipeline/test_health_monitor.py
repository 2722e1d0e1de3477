"""The calibration-health monitor: off the frame path, at most one check at a time and every
`interval_s`; the Live processor's output carries the newest figure."""

from __future__ import annotations

import os
import sys
import threading

import numpy as np
import pytest

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


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a thread's own niceness is Linux's")
def test_a_check_runs_below_the_frame_lanes_priority(monkeypatch, sim_rig_pair):
    """The check's thread takes only the CPU the lanes (niceness 10) leave: it runs at
    CHECK_NICE, and the thread that offered the pair keeps its own priority."""
    import stereo_gui.pipeline.health as health_module

    seen: list[int] = []

    def check(left, right, scale):
        seen.append(os.getpriority(os.PRIO_PROCESS, threading.get_native_id()))
        return real(left, right, scale)

    real = health_module.calibration_health
    monkeypatch.setattr(health_module, "calibration_health", check)
    mine = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    mon = HealthMonitor()
    try:
        assert mon.offer(*sim_rig_pair, now=0.0)
        assert mon.wait(60) is not None
    finally:
        mon.close()
    assert seen == [max(health_module.CHECK_NICE, mine)]
    from stereo_gui.qt.workers.threads import WORKER_NICE

    assert health_module.CHECK_NICE > WORKER_NICE  # below the lanes' priority
    assert os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == mine
