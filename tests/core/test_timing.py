"""The skew between the two cameras' frame times and its statistics over the last second."""

from __future__ import annotations

import pytest

from stereo_gui.core.timing import SkewMeter, skew_stats


def test_a_steady_offset_gives_its_median_and_worst():
    tl = [i / 30 for i in range(30)]
    st = skew_stats(tl, [t + 0.020 for t in tl])
    assert st.median_ms == pytest.approx(20.0) and st.worst_ms == pytest.approx(20.0)
    assert st.interval_ms == pytest.approx(33.333, abs=0.01)
    assert st.limit_ms == pytest.approx(11.111, abs=0.01) and st.too_large


def test_the_worst_is_the_largest_in_size_with_its_sign():
    st = skew_stats([0.0, 0.033, 0.066, 0.1], [0.001, 0.034, 0.036, 0.101])
    assert st.median_ms == pytest.approx(1.0)
    assert st.worst_ms == pytest.approx(-30.0)
    assert not st.too_large  # the typical skew is small; one pair across frames is not


def test_the_meter_keeps_the_last_second_only():
    m = SkewMeter(window_s=1.0)
    for i in range(60):  # two seconds at 30 fps: 5 ms apart first, then 1 ms
        t = i / 30
        m.add(t, t + (0.005 if i < 25 else 0.001))
    st = m.stats()
    assert st.frames <= 31 and st.worst_ms == pytest.approx(1.0)


def test_a_clock_that_goes_back_starts_again():
    m = SkewMeter()
    m.add(10.0, 10.02)
    m.add(0.0, 0.0)
    assert m.stats().frames == 1 and m.stats().worst_ms == 0.0


def test_no_frames_no_figures():
    st = SkewMeter().stats()
    assert st.frames == 0 and st.interval_ms is None and not st.too_large
    assert st.text() == "Skew: no frames"


def test_the_same_frame_again_is_not_counted_again():
    """A paused playback hands its frame over and over: the skew is of the frames that came,
    not "over the last second (547 frames)"."""
    from stereo_gui.core.timing import SkewMeter

    meter = SkewMeter(window_s=1.0)
    for i in range(10):
        meter.add(0.1 * i, 0.1 * i + 0.002)
    for _ in range(500):
        meter.add(0.9, 0.902)
    assert meter.stats().frames == 10
