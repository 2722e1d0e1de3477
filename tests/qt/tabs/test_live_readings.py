"""The Live tab's marker labels: a few words for every reason a reading has no distance."""

from __future__ import annotations

import math

import pytest

from stereo_gui.core.measure import Measurement, Reason
from stereo_gui.qt.tabs.live_readings import (
    HOVER_HINT,
    LiveReadings,
    ReadingScreen,
    short_reason,
    status_text,
)


def test_every_reason_has_a_short_label():
    for reason in Reason:
        label = short_reason(reason)
        assert label and len(label) <= 16, reason
    assert short_reason(Reason.NOT_SEEN) == "not seen"
    assert short_reason(Reason.NO_VALID_PIXELS) == "no match"


def test_a_reason_read_back_as_text_gets_the_same_label():
    for reason in Reason:
        assert short_reason(str(reason)) == short_reason(reason)


def test_no_reason_and_unknown_texts():
    assert short_reason(None) == short_reason("") == "invalid"
    assert short_reason("lens cap on") == "lens cap on"
    assert short_reason("a reason of a newer version") == "a reason of a n…"


def test_the_status_line_puts_the_plus_minus_beside_the_z_it_bounds():
    """The ± bounds Z and stands right after it, early in the line, where a 1280 px window
    still shows it; a refusal says why."""
    m = Measurement(509, 295, True, disparity_px=27.43, Z_mm=3002.0, range_mm=3106.0,
                    valid_fraction=0.9, expected_error_mm=5.8)
    text = status_text(m)
    assert text.startswith("(509, 295): Z 3.002 m ± 5.8 mm, range 3.106 m")
    assert status_text(Measurement(3, 4, False, Reason.AMBIGUOUS)) == (
        "(3, 4): no distance: ambiguous match")


# ---- the readings on a screen of their own: what they read and draw is named, nothing more ----
class _Panel:
    """Stands in for a view: keeps the markers put on it."""

    def __init__(self) -> None:
        self.markers: list[tuple] = []

    def add_marker(self, x, y, label, color, line_to=None, line_text="") -> None:
        self.markers.append((x, y, label, line_to))


@pytest.fixture
def screen(qtbot):
    """(ReadingScreen, what it shows): a readout line, two marker views and a ruler switch over
    an output the test sets."""
    from PySide6.QtWidgets import QLabel

    shown = {"output": None, "frame": None, "ruler": False}
    readout = QLabel()
    qtbot.addWidget(readout)
    panels = {"left": _Panel(), "depth": _Panel()}
    return ReadingScreen(output=lambda: shown["output"], frame=lambda: shown["frame"],
                         readout=readout, markers=panels,
                         ruler_on=lambda: shown["ruler"]), shown


@pytest.fixture(scope="module")
def wall_output(sim_rig, wall_pair):
    """A processed frame of the 1.5 m wall (what the Live tab would be showing)."""
    from stereo_gui.core.preset import Preset
    from stereo_gui.pipeline.live import LiveProcessor
    from stereo_gui.sources.base import StereoFrame

    _scene, left, right = wall_pair
    processor = LiveProcessor(sim_rig.true_calibration(), Preset(name="seed"))
    try:
        return processor(StereoFrame(left, right, 0.0, 0.0, 1))
    finally:
        processor.close()


def test_the_readout_line_is_the_screens(ctx, screen):
    s, _shown = screen
    readings = LiveReadings(ctx, s)
    readings.hovered("depth", 12.0, 34.0)
    assert s.readout.text() == "x   12  y   34   no frame yet"
    readings.hovered("depth", math.nan, math.nan)  # the pointer left the views
    assert s.readout.text() == HOVER_HINT


def test_nothing_is_measured_before_the_screen_shows_a_frame(ctx, screen):
    s, _shown = screen
    errors = []
    ctx.errorOccurred.connect(errors.append)
    assert LiveReadings(ctx, s).measure_at(10.0, 10.0) is None
    assert errors == ["No frame to measure on yet."]
    assert all(p.markers == [] for p in s.markers.values())


def test_a_ruler_measures_on_the_output_shown_and_marks_every_view(
        qtbot, ctx, screen, wall_output, sim_rig):
    s, shown = screen
    shown["output"], shown["ruler"] = wall_output, True
    readings = LiveReadings(ctx, s)
    for x in (250.0, 390.0):
        with qtbot.waitSignal(readings.measured, timeout=30000):
            readings.measure_at(x, 240.0)
    for panel in s.markers.values():
        (_xa, _ya, a, _), (_xb, _yb, b, line_to) = panel.markers
        assert a.startswith("A: ") and b.startswith("B: ") and line_to is not None
    # 140 px apart on the wall 1.5 m away (the rectified focal length in px)
    f_px = float(wall_output.result.calibration.P1[0, 0])
    assert readings.last_ruler_mm == pytest.approx(140.0 * 1500.0 / f_px, rel=0.05)
    assert len(ctx.measurement_log.records) == 3  # A, B and the A-B distance
