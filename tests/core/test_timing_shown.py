"""The frames shown, their latency and the process's CPU share: the meters' arithmetic on made-up
times (no clock, no sleeping)."""

from __future__ import annotations

import math

import pytest

from stereo_gui.core.timing import (
    CpuMeter,
    ShownMeter,
    cpu_percent,
    intervals,
    latency_stats,
    usable_cores,
)


def test_latency_statistics_are_the_median_and_the_95th_percentile():
    st = latency_stats([*range(1, 101), math.nan])  # 1..100 ms, an unknown one left out
    assert st.count == 100
    assert st.median_ms == pytest.approx(50.5)
    assert st.p95_ms == pytest.approx(95.05)
    none = latency_stats([])
    assert none.count == 0 and math.isnan(none.median_ms) and math.isnan(none.p95_ms)


def test_a_steady_stream_gives_its_rate_and_latency():
    m = ShownMeter(window_s=2.0)
    for i in range(90):  # three seconds at 30 fps, each frame drawn 40 ms after it was read
        t = 100.0 + i / 30
        m.add(t, t - 0.040)
    st = m.stats(now=100.0 + 89 / 30 + 0.01)
    assert st.fps == pytest.approx(30.0)
    assert 59 <= st.frames <= 61  # the last two seconds only
    assert st.latency.median_ms == pytest.approx(40.0)
    assert st.latency.p95_ms == pytest.approx(40.0)
    assert st.showing
    assert st.latency_intervals(30.0) == pytest.approx(1.2)


def test_the_95th_percentile_sees_the_late_frames():
    m = ShownMeter()
    for i in range(40):  # one frame in ten drawn 100 ms late, the others 30 ms
        t = 10.0 + i / 20
        m.add(t, t - (0.100 if i % 10 == 0 else 0.030))
    st = m.stats(now=10.0 + 39 / 20)
    assert st.latency.median_ms == pytest.approx(30.0)
    assert st.latency.p95_ms > 90.0


def test_a_view_that_stops_falls_to_no_rate():
    m = ShownMeter(window_s=2.0, stale_s=1.0)
    for i in range(30):
        m.add(i / 30, None)  # no read time: a rate but no latency
    last = 29 / 30
    st = m.stats(now=last + 0.2)  # waiting longer than an interval lowers the rate
    assert st.fps == pytest.approx(5.0)
    assert st.latency.count == 0 and math.isnan(st.latency.median_ms)
    gone = m.stats(now=last + 1.5)  # nothing drawn for longer than a second: no rate at all
    assert gone.fps == 0.0 and gone.frames == 0 and not gone.showing


def test_one_frame_is_no_rate_and_a_clock_going_back_starts_again():
    m = ShownMeter()
    m.add(5.0, 4.99)
    assert m.stats(now=5.01).fps == 0.0 and not m.stats(now=5.01).showing
    m.add(5.1, 5.05)
    assert m.stats(now=5.1).fps == pytest.approx(10.0)
    m.add(1.0, 0.99)  # another clock
    assert m.stats(now=1.0).frames == 1
    m.add(2.0, 2.5)  # read after it was drawn: no latency of it
    assert m.stats(now=2.0).latency.count == 1
    m.reset()
    assert m.stats(now=2.0).frames == 0


def test_latency_in_frame_intervals():
    assert intervals(66.7, 30.0) == pytest.approx(2.0, abs=0.01)
    assert math.isnan(intervals(40.0, 0.0)) and math.isnan(intervals(math.nan, 30.0))


def test_cpu_share_is_of_all_the_cores():
    assert cpu_percent(1.0, 1.0, 2) == pytest.approx(50.0)  # one core busy of two
    assert cpu_percent(2.0, 1.0, 2) == pytest.approx(100.0)
    assert math.isnan(cpu_percent(1.0, 0.0, 2))
    assert usable_cores() >= 1


def test_the_cpu_meter_covers_the_last_window():
    m = CpuMeter(cores=2, window_s=2.0)
    assert math.isnan(m.sample(now=0.0, cpu=0.0))  # nothing to compare with yet
    assert m.sample(now=0.5, cpu=0.5) == pytest.approx(50.0)
    for k in range(2, 9):  # 0.5 s apart: one core busy until 2 s, then both
        t = 0.5 * k
        cpu = t if t <= 2.0 else 2.0 + 2.0 * (t - 2.0)
        share = m.sample(now=t, cpu=cpu)
    # at 4 s the window reaches back to 2 s, when both cores were busy since
    assert share == pytest.approx(100.0)


def test_the_cpu_meter_starts_again_when_a_clock_goes_back():
    m = CpuMeter(cores=1)
    m.sample(now=10.0, cpu=5.0)
    assert math.isnan(m.sample(now=9.0, cpu=5.0))
    assert m.sample(now=10.0, cpu=5.25) == pytest.approx(25.0)
