"""Take the screenshots of docs/guide.md from the real application under Xvfb.

    xvfb-run -a -s "-screen 0 1366x768x24" python packaging/guide_screenshots.py [OUT_DIR]

It starts the application window exactly as `stereo-gui` does (build_window on the automatic
source, which is the simulated rig on a machine without cameras), drives it through the guide's
steps with the same methods its buttons call, and grabs the X screen (QScreen.grabWindow), so
the pictures are what a technician sees. Settings go to a temporary folder; OUT_DIR defaults to
docs/. It is a documentation tool, not a test: it waits for real frames with a deadline and
says which step did not happen.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WINDOW_SIZE = (1366, 768)  # a laptop screen (the window keeps within the screen it is on)


def main(argv: list[str]) -> int:
    out_dir = Path(argv[1]) if len(argv) > 1 else ROOT / "docs"
    out_dir.mkdir(parents=True, exist_ok=True)
    # a short, readable folder: its path shows in the screenshots
    work = Path(tempfile.gettempdir()) / "stereo-guide"
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir()
    os.environ["STEREO_GUI_CONFIG_DIR"] = str(work / "config")
    os.environ["STEREO_GUI_DATA_DIR"] = str(work / "data")  # no measurement log of the user's
    os.environ.setdefault("QT_QPA_PLATFORM", "xcb")

    from PySide6.QtCore import QPoint
    from PySide6.QtWidgets import QApplication

    from stereo_gui.qt.app import build_window

    app = QApplication.instance() or QApplication(["stereo-gui"])
    app.setApplicationName("Stereo GUI")
    ctx, window = build_window(None, None)
    window.resize(*WINDOW_SIZE)
    window.move(0, 0)
    window.show()

    def pump(seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            app.processEvents()
            time.sleep(0.02)

    def wait_for(what: str, cond, timeout: float = 60.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            app.processEvents()
            if cond():
                return True
            time.sleep(0.02)
        print(f"guide_screenshots: gave up waiting for {what}", file=sys.stderr)
        return False

    def shot(name: str, widget=None) -> Path:
        """Grab the screen area of `widget` (the main window by default) as docs/guide-NAME.png."""
        pump(0.4)
        w = widget or window
        top_left = w.mapToGlobal(QPoint(0, 0)) if widget is not None else w.frameGeometry().topLeft()
        size = w.size() if widget is not None else w.frameGeometry().size()
        pixmap = app.primaryScreen().grabWindow(0, top_left.x(), top_left.y(),
                                                size.width(), size.height())
        path = out_dir / f"guide-{name}.png"
        pixmap.save(str(path), "PNG")
        print(path)
        return path

    # 1. start-up: automatic source (the simulated rig here), no calibration yet
    wait_for("the first frames", lambda: ctx.frames.source() is not None and
             ctx.frames.status().camera_fps > 0)
    pump(2.0)
    shot("start")

    # 2. the source chooser, with the simulated rig looking at a painted wall
    from stereo_gui.qt.dialogs.source_dialog import SourceChoice, SourceDialog

    dlg = SourceDialog(SourceChoice("sim:wall:weak:1.5"), parent=window)
    dlg.show()
    dlg.move(200, 150)
    pump(0.5)
    shot("source", dlg)
    dlg.reject()

    # 3. capture: a new session, the first pair frozen for review, a few pairs saved
    capture = window.capture_tab
    window.show_tab("capture")
    session = work / "session"
    capture.new_session(session)
    saved = 0
    deadline = time.monotonic() + 150
    while saved < 4 and time.monotonic() < deadline:
        if not wait_for("a frozen pair", lambda: capture.state == "review",
                        deadline - time.monotonic()):
            break
        if saved == 1:
            shot("capture-review")
        if capture.save_frozen():
            saved += 1
    pump(1.0)
    shot("capture-saved")

    # 4. coverage of a full set: a 20-pair set written by `stereo-gui simulate`
    from stereo_gui.commands import simulate

    full = work / "sim-set"
    import argparse

    p = argparse.ArgumentParser()
    simulate.add_arguments(p)
    simulate.run(p.parse_args([str(full), "--pairs", "20"]))
    capture.open_session(full)
    wait_for("the session scan", lambda: not capture.scanning())
    pump(1.0)
    shot("capture-coverage")

    # 5. calibration of that set, the per-pair error chart and the rectification check
    calib_tab = window.calibration_tab
    window.show_tab("calibration")
    calib_tab.folder_edit.setText(str(full))
    calib_tab.start_calibration()
    wait_for("the calibration", lambda: not calib_tab.is_running(), 300)
    wait_for("the first pair rectified", lambda: calib_tab.rect_view.shown is not None, 30)
    pump(1.0)
    window.save_calibration(str(work / "calibration.yaml"))
    pump(0.5)
    shot("calibration")
    shot("rectification", calib_tab.rect_view)

    # 6. live views with two distance markers and a ruler measurement
    live = window.live_tab
    window.show_tab("live")
    drawn = []  # each frame as its views are drawn
    live.frameShown.connect(drawn.append)
    wait_for("live frames", lambda: len(drawn) > 10)
    live.set_paused(True)
    live.pause_button.setChecked(True)
    pump(0.5)  # (a frame being drawn is finished)
    w, h = ctx.calibration.image_size
    points = _pick_points(drawn[-1].result.valid, drawn[-1].result.final_px)
    for x, y in points["single"]:
        live.measure_at(x, y)
        pump(1.0)
    live.ruler_button.setChecked(True)
    for x, y in points["ruler"]:
        live.measure_at(x, y)
        pump(1.0)
    live.ruler_button.setChecked(False)
    x, y = points["single"][0]
    live.readings.hovered("wls", x + 3, y + 3)  # what the readout line shows with the pointer there
    pump(1.0)
    shot("live")
    # the whole parameter panel (taller than the screen: rendered by Qt rather than grabbed)
    panel = live.params_panel.grab()
    panel.save(str(out_dir / "guide-parameters.png"), "PNG")
    print(out_dir / "guide-parameters.png")

    # 6b. export the frame shown (all four depth files), then record two seconds of the stream
    exports = work / "frame-export"
    exports.mkdir()
    live.export_frame(exports)
    wait_for("the frame export", lambda: len(list(exports.iterdir())) >= 4, 60)
    print("exported", sorted(p.name for p in exports.iterdir()))
    live.pause_button.setChecked(False)
    recording = work / "recording"
    live.start_recording(recording)
    pump(2.5)
    ctx.recorder.stop_recording()
    wait_for("the recording to close", lambda: not ctx.recorder.is_recording, 30)
    pump(1.0)
    print("recorded", recording, len(list(recording.glob("*"))), "files")

    # 7. regression: a flat target at known distances (the simulated walls, played back as
    #    recorded folders), two readings on each, the true distance typed into the log
    from stereo_gui.qt.dialogs.source_dialog import SourceChoice
    from stereo_gui.qt.widgets.measurement_table import TRUE_COL

    walls = work / "walls"
    simulate.run(p.parse_args([str(walls), "--pairs", "1", "--scene"]))
    scenes = json.loads((walls / "truth.json").read_text())["scenes"]
    live.pause_button.setChecked(False)
    live.clear_markers()
    table = window.measurements_tab
    table_start = len(ctx.measurement_log.records)
    for scene in scenes:
        if not scene["name"].startswith("wall-"):
            continue
        folder = work / scene["name"]
        folder.mkdir()
        shutil.copy(walls / scene["left"], folder / "left1.png")
        shutil.copy(walls / scene["right"], folder / "right1.png")
        window.open_source(SourceChoice(str(folder), (640, 480), False))
        wait_for(f"the {scene['name']} source", lambda: not window.is_opening_source())
        shown = live.frames_shown
        wait_for(f"frames of {scene['name']}", lambda: live.frames_shown > shown + 3)
        for fx, fy in ((0.5, 0.5), (0.62, 0.38)):
            n = len(ctx.measurement_log.records)
            live.measure_at(fx * w, fy * h)
            wait_for("a reading", lambda: len(ctx.measurement_log.records) > n, 20)
            index = table.model.index(len(ctx.measurement_log.records) - 1, TRUE_COL)
            table.model.setData(index, f"{scene['distance_mm']:g}")
    # the recording made above, played back as a source: the playback bar appears
    window.show_tab("live")
    live.clear_markers()
    window.open_source(SourceChoice(str(recording), (640, 480), False))
    wait_for("the recording as source", lambda: not window.is_opening_source())
    shown = live.frames_shown
    wait_for("frames of the recording", lambda: live.frames_shown > shown + 20)
    pump(0.5)
    shot("playback")
    window.show_tab("measurements")
    table.use_model("inverse")
    pump(1.5)
    shot("measurements")
    for path in (work / "measurements.xlsx", work / "measurements.csv"):
        ok = table.export_xlsx(path) if path.suffix == ".xlsx" else table.export_csv(path)
        wait_for(f"the export {path.name}", lambda: path.exists(), 30)
        new = len(ctx.measurement_log.records) - table_start
        print(f"exported {path} ({ok}, {new} new readings)")

    window.close()
    pump(0.5)
    return 0


def _pick_points(valid, disp_px) -> dict[str, list[tuple[float, float]]]:
    """Pixels to click for the pictures: two valid points at different distances, one point
    with no match (to show how an invalid reading looks), and a ruler pair on valid pixels."""

    h, w = valid.shape
    good = []
    for y in range(int(0.15 * h), int(0.9 * h), 12):
        for x in range(int(0.2 * w), int(0.95 * w), 12):
            if valid[y - 6:y + 7, x - 6:x + 7].all():
                good.append((x, y, float(disp_px[y, x])))
    bad = [(x, y) for y in range(20, h - 20, 16) for x in range(20, w - 20, 16)
           if not valid[y - 6:y + 7, x - 6:x + 7].any()]
    if len(good) < 4:
        raise SystemExit("guide_screenshots: too few valid pixels in the live frame")
    good.sort(key=lambda p: p[2])
    far, near = good[len(good) // 5], good[-len(good) // 5]
    single = [(float(near[0]), float(near[1])), (float(far[0]), float(far[1]))]
    if bad:
        single.append(tuple(float(v) for v in bad[len(bad) // 2]))
    # the ruler: two points well inside the image, apart, away from the single markers
    inner = [p for p in good if 0.3 * w < p[0] < 0.75 * w
             and min(abs(p[1] - q[1]) for q in (far, near)) > 30] or good
    a = inner[0]
    b = max(inner, key=lambda p: abs(p[0] - a[0]) + abs(p[2] - a[2]))
    return {"single": single, "ruler": [(float(a[0]), float(a[1])), (float(b[0]), float(b[1]))]}


if __name__ == "__main__":
    sys.exit(main(sys.argv))
