"""The 3D point cloud view: made off the UI thread, drawn with pyqtgraph's OpenGL view; where
no OpenGL context can be made (the offscreen platform) it says so, and the drawing test skips."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.qt.tabs.live import TRUE_CALIBRATION_NOTE
from stereo_gui.qt.widgets.cloud_view import CloudView, opengl_problem


def test_without_opengl_the_view_says_why(qtbot, monkeypatch):
    import stereo_gui.qt.widgets.cloud_view as cv

    monkeypatch.setattr(cv, "opengl_problem", lambda: "no OpenGL context can be made")
    view = CloudView()
    qtbot.addWidget(view)
    assert view.gl is None and not view.colour_combo.isEnabled()
    assert view.problem == "no OpenGL context can be made"


def test_the_live_tab_draws_the_frames_cloud(qtbot, ctx, live, sim_rig, wall_pair,
                                             array_source):
    problem = opengl_problem()
    if problem:
        pytest.skip(problem)
    scene, left, right = wall_pair
    ctx.calibration_model.set(sim_rig.true_calibration(), None, note=TRUE_CALIBRATION_NOTE)
    ctx.frames.set_source(array_source(left, right, fps=30))
    with qtbot.waitSignal(live.frameShown, timeout=30000):
        pass
    with qtbot.waitSignal(live.cloudShown, timeout=30000) as sig:
        win = live.show_cloud()
    cloud = sig.args[0]
    assert win.isVisible() and cloud.count > 10000
    assert np.median(cloud.xyz_m[:, 1]) == pytest.approx(1.5, rel=0.03)  # the wall, 1.5 m ahead
    view = live.cloud_view
    assert view.scatter.pos is not None and len(view.scatter.pos) == cloud.count
    with qtbot.waitSignal(live.cloudShown, timeout=30000) as sig:
        view.colour_combo.setCurrentIndex(1)  # by distance: made again
    assert view.colouring == "distance" and sig.args[0].count == cloud.count
    image = view.gl.grabFramebuffer()
    assert image.width() > 0 and len({image.pixel(x, image.height() // 2)
                                      for x in range(0, image.width(), 7)}) > 3
    win.close()


@pytest.mark.slow
def test_a_context_too_old_for_pyqtgraph_is_refused(tmp_path):
    """Offscreen Qt with an X display present makes an OpenGL 2.0 context, which pyqtgraph's
    view refuses (it stayed black or crashed): the check says so instead. Needs xvfb-run."""
    import os
    import shutil
    import subprocess
    import sys

    if shutil.which("xvfb-run") is None:
        pytest.skip("xvfb-run is not installed")
    script = tmp_path / "check.py"
    script.write_text("from PySide6.QtWidgets import QApplication\napp = QApplication([])\n"
                      "from PySide6.QtGui import QOpenGLContext\n"
                      "c = QOpenGLContext()\n"
                      "v = c.format().version() if c.create() else (0, 0)\n"
                      "print('VERSION=%d.%d' % tuple(v))\n"
                      "from stereo_gui.qt.widgets.cloud_view import opengl_problem\n"
                      "print('PROBLEM=' + opengl_problem())\n")
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    done = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 640x480x24", sys.executable,
                           str(script)], env=env, capture_output=True, text=True, timeout=120)
    line = next((ln for ln in done.stdout.splitlines() if ln.startswith("PROBLEM=")), None)
    assert line is not None, done.stderr[-2000:]
    problem = line[len("PROBLEM="):]
    if problem.startswith("no OpenGL context"):
        pytest.skip(problem)
    version = next(ln for ln in done.stdout.splitlines() if ln.startswith("VERSION="))
    major, minor = map(int, version[len("VERSION="):].split("."))
    # a context below 2.1 must be refused; one at or above it accepted
    assert ("needs OpenGL 2.1" in problem) == ((major, minor) < (2, 1)), (version, problem)
