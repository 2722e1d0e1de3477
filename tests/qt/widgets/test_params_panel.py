"""The matcher parameter panel shows the values that run: an odd window, P1/P2 following it,
the disparity range working distances give, and a modified preset said so."""

from __future__ import annotations

import pytest

from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.qt.widgets.params_panel import MODIFIED, ParamsPanel, load_preset


@pytest.fixture
def panel(qtbot):
    p = ParamsPanel(load_preset("live").replace(name="live"))
    qtbot.addWidget(p)
    return p


def test_an_even_window_shows_the_odd_one_that_runs(panel):
    got = []
    panel.paramsChanged.connect(got.append)
    panel.editors["block_size"].setValue(12)
    assert panel.params().matcher.block_size == 13 and panel.editors["block_size"].value() == 13
    panel.editors["block_size"].setValue(12)  # again: nothing new runs, the box still shows 13
    assert panel.editors["block_size"].value() == 13
    assert all(p.matcher.block_size % 2 for p in got)


def test_p1_p2_follow_the_window_while_automatic(panel):
    panel.p_auto.setChecked(True)
    panel.editors["block_size"].setValue(7)
    shown = (panel.editors["p1"].value(), panel.editors["p2"].value())
    assert shown == (8 * 3 * 49, 32 * 3 * 49)
    assert shown == (panel.params().matcher.p1_value, panel.params().matcher.p2_value)


def test_range_from_working_distances_shows_the_range_it_gives(panel):
    calib = StereoCalibration.identity((640, 480), 700.0, 110.0)  # f*B = 77000 px*mm
    panel.set_calibration(calib)
    panel.range_from_z.setChecked(True)
    panel.editors["z_min_mm"].setValue(450.0)
    panel.editors["z_max_mm"].setValue(0.0)  # infinity
    lo, num = panel.params().matcher.disparity_range(calib)
    assert lo == 0 and num >= 77000 / 450  # about 0 .. 192, not the 2 / 128 of the seed
    shown = (panel.editors["min_disparity"].value(), panel.editors["num_disparities"].value())
    assert shown == (lo, num)
    assert "from the working distances" in panel.editors["num_disparities"].toolTip()


def test_an_edited_preset_says_modified_and_choosing_it_again_restores_it(panel):
    assert panel.preset.currentText() == "live"
    panel.editors["uniqueness_ratio"].setValue(panel.editors["uniqueness_ratio"].value() + 3)
    assert panel.preset.currentText() == "live" + MODIFIED
    assert panel.params().name == "live" + MODIFIED
    assert panel.apply_preset("live")
    assert panel.preset.currentText() == "live"
    assert panel.preset.findText("live" + MODIFIED) < 0  # the modified entry is gone
    assert panel.params() == load_preset("live").replace(name="live")


def test_each_editor_offers_its_declared_range_words_and_choices(panel):
    from PySide6.QtWidgets import QCheckBox, QComboBox

    from stereo_gui.core.preset import PRESET_PARAMS

    for key, editor in panel.editors.items():
        spec = PRESET_PARAMS[key]
        if key not in ("min_disparity", "num_disparities"):  # these say what the range gives
            assert editor.toolTip() == spec.help, key
        if isinstance(editor, QComboBox):
            assert [editor.itemText(i) for i in range(editor.count())] == list(spec.choices)
        elif not isinstance(editor, QCheckBox) and key != "num_disparities":
            lo, hi, _step = spec.panel
            assert (editor.minimum(), editor.maximum()) == (lo, hi), key


def test_an_edit_changes_only_its_part_and_keeps_what_the_panel_does_not_show(panel):
    before = panel.params()
    panel.editors["colormap"].setCurrentText("jet")
    after = panel.params()
    assert after.display.colormap == "jet" and after.matcher == before.matcher
    assert after.threads == before.threads
    assert after.matcher.check_block_size == before.matcher.check_block_size == 5


def test_the_panel_offers_the_colour_ranges(panel):
    """The live preset's colours follow the view; the panel offers fixed and min-max too, and
    near/far (the fixed range, and the view's while nothing is in view) only where they count."""
    got = []
    panel.paramsChanged.connect(got.append)
    near = panel.editors["color_z_near_mm"]
    assert panel.color_range.currentData() == "view" and near.isEnabled()
    assert panel.color_range.currentText() == "follows the view"
    panel.color_range.setCurrentIndex(panel.color_range.findData("fixed"))
    assert got[-1].display.color_range == "fixed" and near.isEnabled()
    panel.color_range.setCurrentIndex(panel.color_range.findData("minmax"))
    assert got[-1].display.color_range == "minmax" and not near.isEnabled()
    panel.apply_preset("seed")
    assert panel.color_range.currentData() == "minmax"
    panel.apply_preset("quality")
    assert panel.color_range.currentData() == "view"


def test_searching_only_what_the_scene_needs_is_a_choice_of_the_working_distances(panel):
    box = panel.editors["range_from_scene"]
    assert box.isChecked() and panel.params().matcher.range_from_scene  # the live preset's
    box.setChecked(False)
    assert not panel.params().matcher.range_from_scene
    panel.range_from_z.setChecked(False)  # min_disp/num_disp: the range is the person's own
    assert not box.isEnabled()
    panel.range_from_z.setChecked(True)
    assert box.isEnabled()


def test_a_large_camera_frame_says_the_scale_it_runs_at_and_why(panel):
    panel.set_calibration(StereoCalibration.identity((1280, 720), 1000.0, 60.0))
    # the note wraps: it does not ask the panel for the width of its whole line
    note = panel.scale_note
    assert note.minimumSizeHint().width() < note.fontMetrics().horizontalAdvance(note.text()) / 2
    assert panel.scale_note.text() == ("runs at 0.25: 1280x720 px frames are matched at most "
                                       "320 px wide")
    assert panel.apply_preset("quality")
    assert panel.scale_note.text() == ("runs at 0.5: 1280x720 px frames are matched on at most "
                                       "600,000 pixels")
    # both limits: each named where it lowers the scale
    panel.set_params(panel.params().replace(max_match_width=2000))
    panel.set_calibration(StereoCalibration.identity((3200, 1800), 1000.0, 60.0))
    assert panel.scale_note.text() == ("runs at 0.3125: 3200x1800 px frames are matched at most "
                                       "2000 px wide and on at most 600,000 pixels")
    panel.set_params(panel.params().replace(max_match_width=400))
    assert panel.scale_note.text() == ("runs at 0.125: 3200x1800 px frames are matched at most "
                                       "400 px wide")
    assert panel.apply_preset("quality")
    panel.set_calibration(StereoCalibration.identity((640, 480), 700.0, 110.0))
    assert panel.scale_note.text() == "" and not panel.scale_note.isVisibleTo(panel)
