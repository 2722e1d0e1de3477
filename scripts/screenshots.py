#!/usr/bin/env python
"""Screenshots of every tab, taken under Xvfb on the simulated rig: docs/screenshot-<tab>.png.

Walks through the real workflow: the Capture tab live on the simulated rig, a calibration of
simulated chessboard pairs in the Calibration tab, the Live tab on that calibration with a few
distances measured by double-click and a ruler, the Measurements tab with that log, and a short
recording of the live stream played back in the Live tab (paused, stepped, measured).

    python scripts/screenshots.py [--out docs]

Without a display it re-runs itself under `xvfb-run` (screen 1366x768x24) and captures the
screen with QScreen.grabWindow.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCREEN = (1366, 768)  # a laptop screen
log = logging.getLogger("screenshots")


def _rerun_under_xvfb(argv: list[str]) -> int:
    if not shutil.which("xvfb-run"):
        sys.stderr.write("screenshots: no display and no xvfb-run; install xvfb\n")
        return 2
    cmd = ["xvfb-run", "-a", "-s", f"-screen 0 {SCREEN[0]}x{SCREEN[1]}x24",
           sys.executable, str(Path(__file__).resolve()), *argv]
    env = dict(os.environ, QT_QPA_PLATFORM="xcb", STEREO_GUI_SCREENSHOT_CHILD="1")
    return subprocess.call(cmd, env=env)


def _pump(app, seconds: float) -> None:
    """Let the event loop run (this is a script: waiting on wall time is what we want)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        app.processEvents()
        time.sleep(0.01)


def _wait(app, cond, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise SystemExit(f"screenshots: timed out waiting for {what}")
        app.processEvents()
        time.sleep(0.02)


def _capture(app, window, path: Path) -> None:
    window.raise_()
    window.activateWindow()
    _pump(app, 0.8)
    # the X screen as a person sees it (Qt's own grab: ImageMagick's `import` is not everywhere)
    if not app.primaryScreen().grabWindow(0).save(str(path), "PNG"):
        raise SystemExit(f"screenshots: could not write {path}")
    log.warning("wrote %s", path)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(REPO / "docs"), help="folder for the PNG files")
    ap.add_argument("--pairs", type=int, default=14, help="simulated calibration pairs")
    args = ap.parse_args(argv)
    if not os.environ.get("DISPLAY"):
        return _rerun_under_xvfb(argv)

    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="stereo-gui-shots-"))
    os.environ["STEREO_GUI_CONFIG_DIR"] = str(work / "config")
    os.environ["STEREO_GUI_DATA_DIR"] = str(work / "data")  # no measurement log of the user's

    from stereo_gui.sources.sim import Scene, write_calibration_set

    pairs = work / "calibration-pairs"
    pairs.mkdir()
    write_calibration_set(pairs, n_pairs=args.pairs, seed=3)

    from PySide6.QtWidgets import QApplication

    from stereo_gui.qt.app import build_window
    from stereo_gui.qt.dialogs.source_dialog import SourceChoice

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("Stereo GUI")
    ctx, window = build_window(source="auto")  # no cameras here: the simulated rig, with banner
    try:
        window.setGeometry(0, 0, *SCREEN)
        window.show()
        _wait(app, lambda: ctx.frames.source() is not None, 120, "the simulated rig")

        # Capture: the board moving in front of the demo scene, corners drawn
        window.show_tab("capture")
        _pump(app, 6.0)
        _capture(app, window, out / "screenshot-capture.png")

        # Calibration: calibrate the simulated pairs
        cal = window.calibration_tab
        window.show_tab("calibration")
        cal.folder_edit.setText(str(pairs))
        if not cal.start_calibration():
            raise SystemExit("screenshots: calibration did not start")
        _wait(app, lambda: ctx.calibration is not None and not cal.is_running(), 600, "calibration")
        _pump(app, 1.0)
        _capture(app, window, out / "screenshot-calibration.png")

        # Live: the calibration just made, on the demo scene (no moving board in front of it);
        # distances measured by double-click on each object, and a ruler between two of them
        live = window.live_tab
        window.open_source(SourceChoice("sim:scene"))
        _wait(app, lambda: getattr(ctx.frames.source(), "mode", "") == "scene", 120, "scene source")
        window.show_tab("live")
        shown = live.frames_shown
        _wait(app, lambda: live.frames_shown >= shown + 3, 120, "live frames")
        _pump(app, 2.0)
        live.set_paused(True)
        calib = ctx.calibration
        scene = Scene.demo()
        # pixels on the panel (1.3 m, turned 20 degrees), the poster (2 m) and the wall (3 m)
        points = [(420, 215), (300, 345), (560, 70), (585, 420), (250, 90)]
        for x, y in points:
            live.measure_at(x, y)
        _wait(app, lambda: len(ctx.measurement_log.records) >= len(points), 60, "measurements")
        live.ruler_button.setChecked(True)
        for x, y in ((235, 392), (515, 128)):
            live.measure_at(x, y)
        _wait(app, lambda: len(ctx.measurement_log.records) >= len(points) + 3, 60, "ruler")
        live.ruler_button.setChecked(False)
        # the technician's tape-measure distances (here: the rig's truth) make regression samples
        rig = ctx.frames.source().rig
        for i, rec in enumerate(list(ctx.measurement_log.records)):
            truth = rig.true_point_rectified(calib, scene, rec.x_px, rec.y_px)
            if rec.valid and truth is not None:
                true = dataclasses.replace(rec, true_mm=round(float(truth[2]), 0))
                ctx.measurement_log.update(i, true)
        live.readings.hovered("wls", 455.0, 180.0)  # the readout line as if the pointer were on the panel
        _wait(app, lambda: live.last_reading is not None, 60, "the pointer's reading")
        _pump(app, 1.0)
        _capture(app, window, out / "screenshot-live.png")

        # Measurements: the log just made
        window.show_tab("measurements")
        _pump(app, 1.5)
        _capture(app, window, out / "screenshot-measurements.png")

        # Playback: a few seconds of the scene recorded with Record, then played back as the
        # source, paused and stepped, a distance measured on the recorded frame
        window.show_tab("live")
        live.clear_markers()
        live.set_paused(False)
        if live.start_recording(work / "recording") is None:
            raise SystemExit("screenshots: recording did not start")
        _wait(app, lambda: ctx.recorder.frames_written >= 45, 120, "recorded frames")
        live.stop_recording()
        _wait(app, lambda: not ctx.recorder.is_recording and not ctx.recorder.is_closing, 60,
              "the recording to close")
        window.open_source(SourceChoice(str(work / "recording")))
        _wait(app, lambda: live.playback.source() is not None, 60, "the recording as source")
        shown = live.frames_shown
        _wait(app, lambda: live.frames_shown >= shown + 3, 120, "played frames")
        live.playback.toggle_play()
        live.playback.step(-3)
        _pump(app, 1.5)
        n = len(ctx.measurement_log.records)
        live.measure_at(420, 215)
        _wait(app, lambda: len(ctx.measurement_log.records) > n, 60,
              "a measurement on the recording")
        live.readings.hovered("wls", 420.0, 215.0)
        _pump(app, 1.0)
        _capture(app, window, out / "screenshot-playback.png")
    finally:
        window.close()  # stops and joins the workers whatever happened
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
