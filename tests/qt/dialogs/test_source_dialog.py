"""The source chooser's simulated rig: what it looks at, a wall's condition and distance."""

from __future__ import annotations

from stereo_gui.qt.dialogs.source_dialog import SIM_VIEWS, SourceChoice, SourceDialog, describe_spec
from stereo_gui.sources.open import parse_source_spec
from stereo_gui.sources.sim.conditions import CONDITIONS


def test_every_sim_view_is_a_spec_the_command_line_takes():
    assert {spec for _, spec in SIM_VIEWS} >= {f"sim:wall:{c}" for c in CONDITIONS}
    for _, spec in SIM_VIEWS:
        assert parse_source_spec(spec + (":2" if spec.startswith("sim:wall") else "")).kind == "sim"


def test_choosing_a_wall_under_a_condition(qtbot):
    dlg = SourceDialog(SourceChoice("sim"), cameras=[])
    qtbot.addWidget(dlg)
    assert dlg.sim.isChecked() and dlg.choice().spec == "sim"
    assert dlg.sim_view.isEnabled() and not dlg.wall_distance.isEnabled()
    dlg.sim_view.setCurrentIndex(dlg.sim_view.findData("sim:wall:webcams"))
    assert dlg.wall_distance.isEnabled()
    dlg.wall_distance.setValue(2.5)
    assert dlg.choice().spec == "sim:wall:webcams:2.5"
    dlg.cams.setChecked(True)  # the rig's choices wait while another source is chosen
    assert not dlg.sim_view.isEnabled() and not dlg.wall_distance.isEnabled()


def test_a_sim_spec_opens_the_dialog_where_it_was(qtbot):
    for spec in ("sim:board", "sim:scene", "sim:wall:weak:0.6", "sim:wall:mjpg:3"):
        dlg = SourceDialog(SourceChoice(spec), cameras=[])
        qtbot.addWidget(dlg)
        assert dlg.sim.isChecked() and dlg.choice().spec == spec


def test_describe_sim_specs():
    assert describe_spec("sim") == "Simulated rig"
    assert describe_spec("sim:board") == "Simulated rig: the chessboard"
    assert describe_spec("sim:wall:quarter:2") == "Simulated rig: a wall (quarter) at 2 m"
