#!/usr/bin/env python
"""The guide's screenshots of targets, uncertainty, swapped cameras and drift (issue 10), under
Xvfb on the simulated rig: docs/guide-<name>.png (and, with --size, at another screen size).

    python scripts/screenshots_calibration.py [--out docs] [--size 1366x768] [--suffix ""]

- guide-target-capture.png: the Capture tab with a ChArUco board, coverage in words
- guide-print-target.png: the Print a target... dialog
- guide-uncertainty.png: the Calibration tab after a calibration from ChArUco pairs (each value
  with its 1 sigma, the warnings)
- guide-swapped.png: the same pairs with left and right exchanged: the swapped warning
- guide-drift.png: the Live tab after the right camera was turned by 0.3 degree
"""

from __future__ import annotations

import argparse
import logging
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))
from screenshots import _pump, _wait  # noqa: E402 - the same event-loop helpers

log = logging.getLogger("screenshots")


def _capture(app, path: Path) -> None:
    """The whole screen (dialogs included), as the X server shows it."""
    _pump(app, 0.8)
    if not app.primaryScreen().grabWindow(0).save(str(path)):
        raise SystemExit(f"screenshots: could not write {path}")
    log.warning("wrote %s", path)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(REPO / "docs"))
    ap.add_argument("--size", default="1366x768", help="screen size WIDTHxHEIGHT")
    ap.add_argument("--suffix", default="", help="added to the file names (e.g. -1280)")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.size.split("x"))
    if not os.environ.get("STEREO_GUI_SCREENSHOT_CHILD"):
        cmd = ["xvfb-run", "-a", "-s", f"-screen 0 {w}x{h}x24", sys.executable,
               str(Path(__file__).resolve()), *argv]
        env = dict(os.environ, QT_QPA_PLATFORM="xcb", STEREO_GUI_SCREENSHOT_CHILD="1")
        return subprocess.call(cmd, env=env)

    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="stereo-gui-shots-"))
    os.environ["STEREO_GUI_CONFIG_DIR"] = str(work / "config")

    from stereo_gui.core.board import BoardSpec
    from stereo_gui.sources.sim import RigConfig, write_calibration_set

    board = BoardSpec(7, 5, 30.0, "charuco", 22.0)
    pairs = work / "charuco-pairs"
    pairs.mkdir()
    write_calibration_set(pairs, n_pairs=18, seed=8, config=RigConfig(board=board))
    swapped = work / "swapped-pairs"
    swapped.mkdir()
    for f in pairs.glob("chessboard-*.png"):
        shutil.copy(f, swapped / f.name.replace("-L", "-X").replace("-R", "-L").replace("-X", "-R"))

    from PySide6.QtWidgets import QApplication

    from stereo_gui.qt.app import build_window
    from stereo_gui.qt.dialogs.source_dialog import SourceChoice
    from stereo_gui.qt.widgets.target_dialog import TargetDialog

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("Stereo GUI")
    ctx, window = build_window(source="sim")
    try:
        window.setGeometry(0, 0, w, h)
        window.showMaximized()
        _wait(app, lambda: ctx.frames.source() is not None, 120, "the simulated rig")

        cap = window.capture_tab
        window.show_tab("capture")
        cap.set_board(board)
        cap.open_session(pairs)
        _wait(app, lambda: not cap.scanning(), 120, "the session scan")
        _pump(app, 5.0)
        _capture(app, out / f"guide-target-capture{args.suffix}.png")

        dlg = TargetDialog(board, work)
        dlg.resize(700, 600)
        dlg.move(80, 60)
        dlg.show()
        _pump(app, 1.0)
        _capture(app, out / f"guide-print-target{args.suffix}.png")
        dlg.close()

        cal = window.calibration_tab
        window.show_tab("calibration")
        for folder, name in ((pairs, "guide-uncertainty"), (swapped, "guide-swapped")):
            cal.folder_edit.setText(str(folder))
            if not cal.start_calibration():
                raise SystemExit("screenshots: calibration did not start")
            _wait(app, lambda: not cal.is_running() and cal.run is not None
                  and cal.run.folder == folder, 600, "calibration")
            _wait(app, lambda: cal.rect_view.shown is not None, 30, "the pair rectified")
            _pump(app, 1.0)
            _capture(app, out / f"{name}{args.suffix}.png")

        # Live: the rig's true calibration, the right camera turned by 0.3 degree of tilt
        window.open_source(SourceChoice("sim:scene"))
        _wait(app, lambda: getattr(ctx.frames.source(), "mode", "") == "scene", 120, "scene")
        rig = ctx.frames.source().rig
        ctx.calibration_model.set(rig.true_calibration(), None, note="")
        window.show_tab("live")
        live = window.live_tab
        panel = live.health
        _wait(app, lambda: panel.health is not None, 120, "a health figure")
        panel.turn_sim_camera()
        _wait(app, lambda: panel.health is not None and panel.health.drifted, 120, "drift")
        _pump(app, 1.0)
        _capture(app, out / f"guide-drift{args.suffix}.png")
    finally:
        window.close()
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
