#!/usr/bin/env python
"""The guide's "Two real webcams" pictures, taken under Xvfb at 1366x768 on the simulated rig
set up as two webcams left to themselves: autofocus, auto exposure and auto white balance on,
and the right camera taking its picture 20 ms after the left.

    python scripts/screenshots_webcams.py [--out docs]

Writes guide-webcams-autofocus.png (the Capture tab's camera controls on fresh webcams: the
autofocus warning, the two exposures, the skew), guide-webcams-locked.png (focus locked and
exposure matched; the skew still asks for a still board) and guide-webcams-restore.png (the
Live tab on a calibration made at focus 30 with a camera since turned to 45). Without a display
it re-runs itself under `xvfb-run`, as scripts/screenshots.py does.
"""

from __future__ import annotations

import argparse
import logging
import os
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from screenshots import SCREEN, _capture, _pump, _wait  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
log = logging.getLogger("screenshots")


def _webcam_rig_source(**changes):
    from stereo_gui.sources.sim import RigConfig, SimRig, SimSource

    config = RigConfig(supersample=2, auto_modes=True, time_offset_s=0.020, **changes)
    return SimSource(SimRig(config), mode="mixed", fps=30.0, frames_per_move=120)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(REPO / "docs"), help="folder for the PNG files")
    args = ap.parse_args(argv)
    if not os.environ.get("DISPLAY"):
        return _rerun(argv)

    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="stereo-gui-webcam-shots-"))
    os.environ["STEREO_GUI_CONFIG_DIR"] = str(work / "config")
    os.environ["STEREO_GUI_DATA_DIR"] = str(work / "data")

    from PySide6.QtWidgets import QApplication

    from stereo_gui.core.camera_settings import CameraSettings, PairSettings
    from stereo_gui.qt.app import build_window

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("Stereo GUI")
    ctx, window = build_window(source="sim")
    try:
        window.setGeometry(0, 0, *SCREEN)
        window.show()
        _wait(app, lambda: ctx.frames.source() is not None, 120, "the simulated rig")
        src = _webcam_rig_source()
        ctx.frames.set_source(src)
        capture = window.capture_tab
        window.show_tab("capture")
        panel = capture.camera_controls
        _wait(app, lambda: panel.model.report is not None, 120, "the cameras' controls")
        panel.set_unfolded(True)
        _pump(app, 4.0)  # the automatic modes settle; the skew figures fill the second
        panel.model.refresh()
        _wait(app, lambda: "Autofocus is on" in panel.warning.text(), 60, "the autofocus warning")
        _pump(app, 1.0)
        _capture(app, window, out / "guide-webcams-autofocus.png")

        panel.lock_warning_button.click()
        _wait(app, lambda: not panel.model.report.autofocus_on(), 60, "the focus locked")
        panel.match_button.click()
        _wait(app, lambda: not panel.model.matching, 120, "exposure matching")
        _pump(app, 2.0)
        _capture(app, window, out / "guide-webcams-locked.png")

        # Live: a calibration made at focus 30 (the rig's truth with the controls it holds),
        # and a camera whose focus was turned to 45 since
        held = PairSettings(
            CameraSettings("simulated", focus_auto=False, focus=30.0, exposure_auto=False,
                           exposure=150.0),
            CameraSettings("simulated", focus_auto=False, focus=30.0, exposure_auto=False,
                           exposure=150.0))
        src.camera_controls().left.write("focus", 45)
        ctx.calibration_model.set(src.rig.true_calibration().with_updates(camera_controls=held),
                                  None, note="")
        window.show_tab("live")
        live = window.live_tab
        live_panel = live.camera_controls
        _wait(app, lambda: live_panel.model.report is not None and
              live_panel.restore_button.isVisible(), 120, "the focus warning")
        shown = live.frames_shown
        _wait(app, lambda: live.frames_shown >= shown + 3, 120, "live frames")
        _pump(app, 2.0)
        _capture(app, window, out / "guide-webcams-restore.png")
    finally:
        window.close()
        shutil.rmtree(work, ignore_errors=True)
    return 0


def _rerun(argv: list[str]) -> int:
    """Run this script again under xvfb-run at the laptop screen's size."""
    import subprocess

    if not shutil.which("xvfb-run"):
        sys.stderr.write("screenshots: no display and no xvfb-run; install xvfb\n")
        return 2
    cmd = ["xvfb-run", "-a", "-s", f"-screen 0 {SCREEN[0]}x{SCREEN[1]}x24",
           sys.executable, str(Path(__file__).resolve()), *argv]
    return subprocess.call(cmd, env=dict(os.environ, QT_QPA_PLATFORM="xcb"))


if __name__ == "__main__":
    sys.exit(main())
