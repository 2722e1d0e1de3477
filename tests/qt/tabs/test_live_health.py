"""The Live tab's calibration health on the simulated rig: the right camera turned by 0.3 degree
is reported live, and Refine rectification from the scene saves a new calibration that brings
the figure back under 0.2 px and says where it came from."""

from __future__ import annotations

import pytest

from stereo_gui.files.calibration_file import load_calibration
from stereo_gui.sources.sim import SimRig, SimSource


@pytest.mark.slow
def test_drift_is_shown_live_and_refined_away(qtbot, ctx, live, tmp_path):
    rig = SimRig(seed=29)  # its own rig: the test turns its right camera
    calib = rig.true_calibration()
    ctx.calibration_model.set(calib)
    ctx.frames.set_source(SimSource(rig=rig, mode="scene", fps=15))
    panel = live.health
    qtbot.waitUntil(lambda: panel.health is not None, timeout=60000)
    assert not panel.health.drifted and "OK" in panel.label.text()
    assert panel.sim_row.isVisibleTo(live)
    panel.angle_spin.setValue(0.3)
    panel.axis_combo.setCurrentIndex(panel.axis_combo.findData("tilt"))
    panel.turn_button.click()
    assert rig.turned_deg > 0.29 and "turned 0.30" in panel.turned_label.text()
    qtbot.waitUntil(lambda: panel.health is not None and panel.health.drifted, timeout=60000)
    assert "moved since calibration" in panel.label.text()
    assert panel.refine_button.isEnabled()
    panel.save_to = tmp_path / "refined.yaml"
    with qtbot.waitSignal(panel.refined, timeout=60000) as sig:
        assert panel.refine()
    ref = sig.args[0]
    assert ref.after_px < 0.2
    saved = load_calibration(tmp_path / "refined.yaml")
    assert "refined from the scene" in saved.origin
    assert ctx.calibration is not calib and ctx.calibration_path == tmp_path / "refined.yaml"
    assert abs(saved.baseline_mm - calib.baseline_mm) < 1e-9
    # the figure comes back with the refined calibration
    qtbot.waitUntil(lambda: panel.health is not None and panel.health.measured, timeout=60000)
    assert panel.health.vertical_px < 0.2, panel.label.text()
    qtbot.waitUntil(lambda: not panel.is_refining(), timeout=10000)
