"""The Live tab on the simulated rig: views update, clicks measure known distances, parameters
apply, no-calibration page, snapshot, ruler."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from PySide6.QtCore import Qt

from stereo_gui.pipeline.readout import format_distance
from stereo_gui.qt.tabs.live import TRUE_CALIBRATION_NOTE


def double_click(qtbot, widget, pos):
    """What a platform sends for a double-click: press, release, double-click, release
    (QTest.mouseDClick alone sends only the double-click event)."""
    left = Qt.MouseButton.LeftButton
    qtbot.mousePress(widget, left, pos=pos)
    qtbot.mouseRelease(widget, left, pos=pos)
    qtbot.mouseDClick(widget, left, pos=pos)
    qtbot.mouseRelease(widget, left, pos=pos)


# the region line of a box in the left strip the right camera does not see (no depth there)
LEFT_EDGE_REGION_LINE = "Region: too little depth in the region"


def region_median_mm(live) -> float:
    """The median distance the region line shows, mm (NaN when it shows none)."""
    found = re.search(r"median ([0-9.]+) m", live.region_label.text())
    return 1000.0 * float(found.group(1)) if found else math.nan


def _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source):
    scene, left, right = wall_pair
    calib = sim_rig.true_calibration()
    ctx.calibration_model.set(calib, None, note=TRUE_CALIBRATION_NOTE)
    ctx.frames.set_source(array_source(left, right, fps=30))
    with qtbot.waitSignal(live.frameShown, timeout=30000):
        pass
    return scene, calib


@pytest.mark.slow
def test_live_view_updates_on_the_sim_rig(qtbot, ctx, live, sim_rig):
    from stereo_gui.sources.sim import SimSource

    ctx.calibration_model.set(sim_rig.true_calibration())
    assert live.stack.currentIndex() == 1
    ctx.frames.set_source(SimSource(rig=sim_rig, mode="scene", fps=30))
    qtbot.waitUntil(lambda: live.frames_shown >= 2, timeout=60000)
    for key in live.visible_views():
        img = live.panels[key].item.image
        assert img is not None and img.dtype == np.uint8
        assert img.shape[:2] == (480, 640)
    # the demo scene lies within the colour bar's range, so the bar carries distance ticks
    ticks = live.panels["wls"].color_bar.ticks
    assert ticks and any(label.endswith("m") for _pos, label in ticks)
    # the live preset's colours follow the view, and the line under the views says so
    caption = live.panels["depth"].color_bar.caption
    assert caption.startswith("colours follow the view: ") and caption.endswith(" m")
    assert caption in live.legend.text()


def test_double_click_reports_a_known_distance_within_1_percent(
        qtbot, ctx, live, sim_rig, wall_pair, array_source):
    scene, calib = _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    x, y = 300.0, 250.0
    panel = live.panels["wls"]
    pos = panel.widget_pos_of_pixel(x, y)
    with qtbot.waitSignal(live.measured, timeout=30000) as sig:
        double_click(qtbot, panel.viewport(), pos)
    m = sig.args[0]
    assert m.valid, m.reason
    assert abs(m.x - x) < 1.5 and abs(m.y - y) < 1.5  # the click landed where it was aimed
    truth = sim_rig.true_point_rectified(calib, scene, m.x, m.y)
    assert truth is not None
    assert m.Z_mm == pytest.approx(truth[2], rel=0.01)
    # logged for the Measurements tab, a marker on every view that shares the left's pixels
    assert len(ctx.measurement_log.records) == 1
    rec = ctx.measurement_log.records[0]
    assert rec.Z_mm == pytest.approx(m.Z_mm) and rec.valid
    assert rec.calibration_file == TRUE_CALIBRATION_NOTE
    assert panel.marker_count() == 1 and live.panels["raw"].marker_count() == 1
    live.clear_markers()
    assert panel.marker_count() == 0


def test_invalid_point_says_why(qtbot, ctx, live, sim_rig, wall_pair, array_source):
    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    with qtbot.waitSignal(live.measured, timeout=30000) as sig:
        live.measure_at(-5.0, 10.0)
    m = sig.args[0]
    assert not m.valid and m.reason == "outside the image"
    last = ctx.measurement_log.records[-1]
    assert not last.valid and last.reason == "outside the image"


def test_ruler_measures_3d_distance_between_two_points(
        qtbot, ctx, live, sim_rig, wall_pair, array_source):
    scene, calib = _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    live.ruler_button.setChecked(True)
    a, b = (200.0, 240.0), (440.0, 240.0)
    for x, y in (a, b):
        with qtbot.waitSignal(live.measured, timeout=30000):
            live.measure_at(x, y)
    ta = sim_rig.true_point_rectified(calib, scene, *a)
    tb = sim_rig.true_point_rectified(calib, scene, *b)
    assert live.last_ruler_mm == pytest.approx(float(np.linalg.norm(ta - tb)), rel=0.02)
    # both points and the distance between them are in the log
    assert len(ctx.measurement_log.records) == 3
    rec = ctx.measurement_log.records[-1]
    assert rec.method.startswith("ruler A–B") and rec.valid
    assert rec.range_mm == pytest.approx(live.last_ruler_mm)
    assert rec.expected_error_mm > 0 and math.isnan(rec.disparity_px)  # not a regression sample


def test_ruler_says_when_a_point_has_no_distance(qtbot, ctx, live, sim_rig, wall_pair,
                                                 array_source):
    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    live.ruler_button.setChecked(True)
    statuses = []
    ctx.statusMessage.connect(statuses.append)
    with qtbot.waitSignal(live.measured, timeout=30000):
        live.measure_at(-5.0, 10.0)  # outside the image: no first point
    assert "first point has no distance (outside the image)" in statuses[-1]
    assert "another first point" in statuses[-1]
    with qtbot.waitSignal(live.measured, timeout=30000):
        live.measure_at(200.0, 240.0)  # A
    assert "double-click the second point" in statuses[-1]
    with qtbot.waitSignal(live.measured, timeout=30000):
        live.measure_at(700.0, 240.0)  # no B: A stays
    assert "second point has no distance" in statuses[-1]
    with qtbot.waitSignal(live.measured, timeout=30000):
        live.measure_at(440.0, 240.0)
    assert "A–B" in statuses[-1] and "logged" in statuses[-1]
    assert ctx.measurement_log.records[-1].method.startswith("ruler A–B")
    assert ctx.measurement_log.records[-1].x_px == pytest.approx(440.0)


def _hover(qtbot, live, key, x, y):
    """Point at (x, y) of view `key` and wait for the readout of that position."""
    with qtbot.waitSignal(live.hoverRead, timeout=30000,
                          check_params_cb=lambda r: (r.x, r.y) == (x, y)) as sig:
        live.panels[key].hovered.emit(key, x, y)
    return sig.args[0]


def test_hover_reads_what_a_double_click_gives_at_that_pixel(qtbot, ctx, live, sim_rig,
                                                             wall_pair, array_source):
    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    live.set_paused(True)  # one frame for both
    for key, (x, y) in (("wls", (320.0, 240.0)), ("raw", (101.0, 377.0)),
                        ("left", (610.0, 30.0)), ("wls", (3.0, 200.0))):
        reading = _hover(qtbot, live, key, x, y)
        with qtbot.waitSignal(live.measured, timeout=30000) as sig:
            live.measure_at(x, y, key)
        click = sig.args[0]
        hover = reading.measurement
        assert hover.valid == click.valid and hover.reason == click.reason
        if click.valid:
            assert hover.Z_mm == click.Z_mm
            assert hover.expected_error_mm == click.expected_error_mm
            assert format_distance(click.Z_mm) in live.readout.text()
            assert f"± {click.expected_error_mm:.1f} mm" in live.readout.text()
        else:  # the click's reason, e.g. "not seen by the right camera" at the left edge
            assert click.reason in live.readout.text()
    assert "right image" in _hover(qtbot, live, "right", 320.0, 240.0).note
    assert "outside" in _hover(qtbot, live, "wls", 5000.0, 10.0).note
    live.panels["wls"].hovered.emit("wls", math.nan, math.nan)  # the pointer leaves
    assert "double-click" in live.readout.text()
    # and comes back to the pixel it read last: read again, not left saying "Point at a view"
    _hover(qtbot, live, "wls", 5000.0, 10.0)
    assert "outside" in live.readout.text()


def test_fast_pointer_moves_do_not_queue_readings(qtbot, ctx, live, sim_rig, wall_pair,
                                                  array_source):
    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    live.set_paused(True)
    before = live.hover_jobs_submitted
    panel = live.panels["wls"]
    for i in range(60):  # faster than any reading: no event is processed in between
        panel.hovered.emit("wls", 200.0 + i, 240.0)
    assert live.hover_jobs_submitted - before == 1  # one runs, the newest position waits
    reading = None
    while reading is None or reading.x != 259.0:
        with qtbot.waitSignal(live.hoverRead, timeout=30000) as sig:
            pass
        reading = sig.args[0]
    assert live.hover_jobs_submitted - before == 2  # the first and the newest, nothing between
    assert "x  259" in live.readout.text()
    assert not ctx.jobs.is_busy()


def test_hover_on_the_simulated_rig_shows_the_true_distance_labelled(
        qtbot, ctx, live, sim_rig, wall_pair, array_source):
    from stereo_gui.sources.sim.rig import SimFrameTruth

    scene, left, right = wall_pair
    calib = sim_rig.true_calibration()
    ctx.calibration_model.set(calib, None, note=TRUE_CALIBRATION_NOTE)
    ctx.frames.set_source(array_source(left, right, fps=30,
                                       truth=SimFrameTruth(None, scene, sim_rig.truth)))
    with qtbot.waitSignal(live.frameShown, timeout=30000):
        pass
    live.set_paused(True)
    reading = _hover(qtbot, live, "wls", 320.0, 240.0)
    truth = sim_rig.true_point_rectified(calib, scene, 320.0, 240.0)
    assert reading.true_z_mm == pytest.approx(truth[2])
    assert f"TRUE (simulated scene): Z {format_distance(truth[2])}" in live.readout.text()
    assert reading.measurement.Z_mm == pytest.approx(truth[2], rel=0.01)


def test_parameter_change_applies_to_next_frame(qtbot, ctx, live, sim_rig, wall_pair,
                                                array_source):
    shown = []
    live.frameShown.connect(shown.append)
    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    before = shown[-1].result.params.closing_kernel
    new = 5 if before != 5 else 7
    live.params_panel.editors["closing_kernel"].setValue(new)
    qtbot.waitUntil(lambda: shown[-1].result.params.closing_kernel == new, timeout=30000)
    # and switching the WLS filter off leaves its view showing the depth, and saying so
    live.params_panel.editors["wls"].setChecked(False)
    qtbot.waitUntil(lambda: shown[-1].result.wls_px is None, timeout=30000)
    assert "No WLS" in live.panels["wls"].title.text


def test_preset_chooser_and_save_as(qtbot, ctx, live):
    panel = live.params_panel
    assert {"seed", "live", "quality"} <= {panel.preset.itemText(i)
                                           for i in range(panel.preset.count())}
    got = []
    panel.paramsChanged.connect(got.append)
    assert panel.apply_preset("seed")
    seed = got[-1].matcher
    assert seed.block_size == 3 and seed.num_disparities == 128 and seed.wls_lambda == 80000
    assert panel.editors["block_size"].value() == 3
    assert panel.save_as("my bench")
    assert panel.preset.findText("my bench") >= 0
    assert not panel.save_as("live")  # built-in names are refused with a message
    assert panel.error_label.isVisibleTo(panel)


def test_without_calibration_the_tab_says_so_and_offers_the_true_one(
        qtbot, ctx, live, sim_rig):
    from stereo_gui.sources.sim import SimSource

    assert live.stack.currentIndex() == 0
    assert not live.no_calib.use_true.isVisibleTo(live)  # no simulated rig yet
    calibrate = []
    live.calibrateRequested.connect(lambda: calibrate.append(1))
    qtbot.mouseClick(live.no_calib.calibrate, Qt.MouseButton.LeftButton)
    assert calibrate
    ctx.frames.set_source(SimSource(rig=sim_rig, mode="scene", fps=30))
    assert live.no_calib.use_true.isVisibleTo(live)
    qtbot.mouseClick(live.no_calib.use_true, Qt.MouseButton.LeftButton)
    assert ctx.calibration is not None and ctx.calibration_note == TRUE_CALIBRATION_NOTE
    assert live.stack.currentIndex() == 1 and live.calib_note.isVisibleTo(live)


def test_snapshot_writes_each_shown_view_as_png(qtbot, ctx, live, sim_rig, wall_pair,
                                                array_source, tmp_path):
    import cv2

    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    live.set_visible_views(("left", "wls"))
    with qtbot.waitSignal(ctx.jobs.finished, timeout=30000):
        live.snapshot(tmp_path)
    files = sorted(p.name for p in tmp_path.iterdir())
    assert len(files) == 2 and files[0].endswith("-left.png") and files[1].endswith("-wls.png")
    img = cv2.imread(str(tmp_path / files[1]))
    assert img.shape == (480, 640, 3)


@pytest.mark.slow
def test_pause_freezes_and_resume_continues(qtbot, ctx, live, sim_rig, wall_pair, array_source):
    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    live.set_paused(True)
    assert ctx.frames.paused and live.pause_button.text() == "Resume"
    live.set_paused(False)
    n = live.frames_shown
    qtbot.waitUntil(lambda: live.frames_shown > n, timeout=30000)


def test_readings_use_the_active_fit(qtbot, ctx, live, sim_rig, wall_pair, array_source):
    from stereo_gui.core.regression import fit_inverse

    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    calib = ctx.calibration
    fb = calib.focal_px * calib.rectified_baseline_mm
    # a deliberately wrong model (every distance 10 % longer) shows that readings follow it
    d = np.array([20.0, 40.0, 60.0, 80.0, 100.0])
    fit = fit_inverse(list(zip(d, 1.1 * fb / d)))
    ctx.measurement_log.set_active_fit(fit)
    with qtbot.waitSignal(live.measured, timeout=30000) as sig:
        live.measure_at(320.0, 240.0)
    m = sig.args[0]
    assert m.valid and m.method == fit.model
    assert m.Z_mm == pytest.approx(1.1 * 1500.0, rel=0.02)
    assert ctx.measurement_log.records[-1].method == fit.model
    live.set_paused(True)
    reading = _hover(qtbot, live, "wls", 320.0, 240.0)
    assert reading.measurement.method == fit.model and "fit" in live.readout.text()


@pytest.mark.slow
def test_every_view_shows_the_whole_image_filling_its_panel(
        qtbot, ctx, live, sim_rig, wall_pair, array_source):
    """The views (the colour one narrower, beside its colour bar) each fit the image after the
    layout changes, and Fit brings a zoomed view back."""
    live.resize(1100, 800)
    live.show()
    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    live.view_checks["right"].setChecked(True)
    live.view_checks["closed"].setChecked(False)
    live.resize(1200, 700)
    qtbot.waitUntil(lambda: live.frames_shown >= 3, timeout=30000)

    def fitted(panel) -> bool:
        (x0, x1), (y0, y1) = panel.view.viewRange()
        whole = x0 <= 0.5 and x1 >= 639.5 and y0 <= 0.5 and y1 >= 479.5
        return whole and min((x1 - x0) / 640, (y1 - y0) / 480) < 1.02

    for key in live.visible_views():
        qtbot.waitUntil(lambda k=key: fitted(live.panels[k]), timeout=30000)
    live.panels["wls"].view.scaleBy((0.5, 0.5))  # the mouse wheel
    assert not fitted(live.panels["wls"])
    assert fitted(live.panels["left"])  # zooming one view leaves the others alone
    live.fit_button.click()
    assert all(fitted(live.panels[k]) for k in live.visible_views())


def test_region_box_watches_the_nearest_distance_and_alarms(qtbot, ctx, live, sim_rig,
                                                            wall_pair, array_source):
    from stereo_gui.qt.widgets.image_view import REGION_ALARM

    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    statuses = []
    ctx.statusMessage.connect(statuses.append)
    live.set_region((250, 180, 400, 300), alarm_m=1.0)  # the wall is at 1.5 m: no alarm
    assert live.panels["depth"].region() == (250, 180, 400, 300)
    qtbot.waitUntil(lambda: "nearest" in live.region_label.text(), timeout=30000)
    assert region_median_mm(live) == pytest.approx(1500.0, rel=0.03)
    assert "ALARM" not in live.region_label.text()
    live.alarm_spin.setValue(2.0)  # now anything nearer than 2 m: the wall
    qtbot.waitUntil(lambda: "ALARM" in live.region_label.text(), timeout=30000)
    assert any(s.startswith("ALARM") for s in statuses)
    assert live.panels["depth"].region_box.pen.color().name() == REGION_ALARM
    # dragged elsewhere (what the box reports when the user lets go)
    live.panels["depth"].show_region((10, 10, 40, 40))
    live.panels["depth"].regionChanged.emit((10, 10, 40, 40))
    qtbot.waitUntil(lambda: live.region_label.text() == LEFT_EDGE_REGION_LINE, timeout=30000)
    live.set_region(None)
    assert live.panels["depth"].region_box is None and not live.region_label.isVisibleTo(live)


def test_hidden_views_belong_to_the_window_too(qtbot, ctx):
    """A view not shown is still a child of the views' grid (deleted with the window, never a
    top-level widget left to the interpreter's exit)."""
    from stereo_gui.qt.tabs.live import LiveTab

    ctx.settings_model.update(visible_views=("left",))
    tab = LiveTab(ctx)
    qtbot.addWidget(tab)
    tab.show()
    assert tab.visible_views() == ["left"]
    for key, panel in tab.panels.items():
        assert panel.parent() is tab.views, key
        assert panel.isVisibleTo(tab.views) == (key == "left"), key
        assert panel.isWindow() is False
    tab.set_visible_views(["left", "wls"])
    assert [k for k, p in tab.panels.items() if p.isVisibleTo(tab.views)] == ["left", "wls"]


def _event_loop_turns(qtbot, n: int) -> None:
    """Return after `n` turns of the event loop: a chain of n zero-time timers, each started by
    the one before, ends after every chain of that length started earlier."""
    from PySide6.QtCore import QTimer

    left = [n]

    def turn():
        left[0] -= 1
        if left[0] > 0:
            QTimer.singleShot(0, turn)

    QTimer.singleShot(0, turn)
    qtbot.waitUntil(lambda: left[0] == 0, timeout=10000)


def test_views_are_drawn_one_event_loop_turn_apart_and_the_newest_frame_wins(
        qtbot, ctx, live, sim_rig, wall_pair, array_source):
    """Each view gets its image in a turn of its own (each is painted on its own, the window
    answers in between); frameShown follows the last view; a frame that comes meanwhile is
    the one the remaining views show; a new calibration drops what was still to be drawn."""
    _wall_live(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    with qtbot.waitSignal(live.frameShown, timeout=30000) as sig:
        pass
    live.set_paused(True)  # no frame is shown any more
    first = sig.args[0]
    keys = [k for k in live.visible_views() if k in first.images]
    qtbot.waitUntil(lambda: all(np.array_equal(live.panels[k].item.image, first.images[k])
                                for k in keys), timeout=30000)
    assert len(keys) >= 2
    blank = {k: np.zeros_like(first.images[k]) for k in keys}
    newer = dataclasses.replace(first, images=blank)
    shown = live.frames_shown
    live.show_output(first)
    assert live.frames_shown == shown  # only the first view has its image yet
    assert np.array_equal(live.panels[keys[0]].item.image, first.images[keys[0]])
    assert first.images[keys[0]].any()  # (the newer frame's images are all black)
    live.show_output(newer)  # before the other views' turns came
    with qtbot.waitSignal(live.frameShown, timeout=2000):
        pass
    for k in keys[1:]:
        assert not live.panels[k].item.image.any()  # the newer frame's
    live.show_output(first)
    # a new calibration clears the views' frame: nothing to measure on
    ctx.calibration_model.set(ctx.calibration, ctx.calibration_path, ctx.calibration_note)
    with qtbot.waitSignal(ctx.errorOccurred, timeout=2000) as err:
        assert live.measure_at(320.0, 240.0) is None
    assert err.args[0] == "No frame to measure on yet."
    _event_loop_turns(qtbot, len(keys) + 1)  # the remaining turns draw nothing, raise nothing


@pytest.mark.slow
def test_a_new_calibration_closes_the_processor_it_replaces(qtbot, ctx, live, sim_rig):
    """Its pipelines and its health thread go; the frames go on with the new one, and the old
    one, closed while a frame may be in work, shows no error."""
    from stereo_gui.sources.sim import SimSource

    errors = []
    ctx.frames.errorOccurred.connect(errors.append)
    ctx.calibration_model.set(sim_rig.true_calibration())
    ctx.frames.set_source(SimSource(rig=sim_rig, mode="scene", fps=30))
    qtbot.waitUntil(lambda: live.frames_shown >= 2, timeout=60000)
    for _ in range(3):  # while frames are in work
        old = ctx.frames.processor()
        frame = live.shown_frame
        ctx.calibration_model.set(sim_rig.true_calibration())
        assert ctx.frames.processor() is not None and ctx.frames.processor() is not old
        with pytest.raises(RuntimeError, match="closed"):
            old(frame)
        assert not old.health.offer(frame.left, frame.right, now=1e12)
        shown = live.frames_shown
        qtbot.waitUntil(lambda: live.frames_shown >= shown + 2, timeout=60000)
    assert not errors


def test_views_share_the_width_evenly_whatever_they_are(qtbot):
    """Two views a row get half the width each, whichever are shown and in whatever order they
    were switched (the colour bar of the WLS view does not widen its column)."""
    from stereo_gui.qt.tabs.live_views import ViewGrid

    grid = ViewGrid(("left", "raw", "closed", "wls"))
    qtbot.addWidget(grid)
    grid.resize(1000, 500)
    grid.show()
    grid.lay_out()
    for panel in grid.panels.values():
        panel.set_image(np.zeros((480, 640, 3), np.uint8))

    def shown_as_checked() -> bool:
        keys = grid.visible()
        return all(p.isVisible() == (k in keys) for k, p in grid.panels.items())

    def even(keys) -> bool:
        widths = [grid.panels[k].width() for k in keys]
        return max(widths) - min(widths) <= 2

    qtbot.waitUntil(shown_as_checked, timeout=10000)
    grid.checks["right"].setChecked(True)  # as a person does it: Right on (five views), Raw off
    qtbot.waitUntil(shown_as_checked, timeout=10000)
    grid.checks["raw"].setChecked(False)
    qtbot.waitUntil(shown_as_checked, timeout=10000)
    for shown in (["left", "right", "closed", "wls"], ["left", "wls"], ["raw", "closed"]):
        if shown != grid.visible():
            grid.set_visible(shown)
        qtbot.waitUntil(lambda shown=shown: shown_as_checked() and even(shown), timeout=10000)
        widths = [grid.panels[k].width() for k in shown]
        assert max(widths) - min(widths) <= 2, (shown, widths)


def test_six_views_take_the_layout_that_gives_each_picture_the_most_room(qtbot):
    """Six views in the Live tab's space at 1366x768 (about 1010x425 px) were two by three,
    each picture about 115 px wide; three by two gives each twice the area, and a narrow grid
    goes back to two columns (three never keep the window from shrinking)."""
    from stereo_gui.qt.tabs.live_views import VIEWS, ViewGrid, best_columns

    assert best_columns(6, 1010, 425, color_views=2) == 3
    assert best_columns(6, 500, 700, color_views=2) == 2
    assert best_columns(4, 1010, 425, color_views=2) in (2, 4)
    assert best_columns(1, 1010, 425) == 1 and best_columns(2, 300, 900) == 1
    grid = ViewGrid(tuple(VIEWS))
    qtbot.addWidget(grid)
    grid.resize(1010, 425)
    grid.show()
    grid.lay_out()
    qtbot.waitUntil(lambda: grid.columns() == 3, timeout=10000)
    qtbot.waitUntil(lambda: all(p.isVisible() for p in grid.panels.values()), timeout=10000)
    heights = {p.height() for p in grid.panels.values()}
    widths = {p.width() for p in grid.panels.values()}
    assert max(heights) - min(heights) <= 2 and max(widths) - min(widths) <= 2  # rows equal
    assert min(widths) >= 320
    assert grid.minimumSizeHint().width() <= 2 * 200 + 4
    told = []
    grid.changed.connect(told.append)
    grid.resize(480, 700)
    qtbot.waitUntil(lambda: grid.columns() == 2, timeout=10000)
    assert told == []  # the same views in other columns: nothing for the tab to redo
