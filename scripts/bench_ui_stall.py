#!/usr/bin/env python
"""How responsive the window stays while live: the longest event-loop stall over N seconds.

Runs the main window offscreen on the simulated rig with its true calibration, Live tab shown,
the `live` preset (or --preset). A 1 ms QTimer records the gaps between its ticks; a gap is how
long the event loop could not run anything (drawing, a click, a key). Target: below 30 ms.

    python scripts/bench_ui_stall.py [--seconds 10] [--preset live] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="measured live time (s)")
    ap.add_argument("--preset", default="live", help="matcher preset")
    ap.add_argument("--mode", default="mixed", choices=("mixed", "scene", "board"),
                    help="what the simulated rig shows")
    ap.add_argument("--idle", action="store_true",
                    help="no source: the stall the machine's load alone causes (a reference)")
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    args = ap.parse_args(argv)

    import tempfile

    os.environ.setdefault("STEREO_GUI_CONFIG_DIR", tempfile.mkdtemp(prefix="stall-bench-"))
    from PySide6.QtCore import QElapsedTimer, Qt, QTimer
    from PySide6.QtWidgets import QApplication

    from stereo_gui.pipeline.concurrency import use_opencv_threads_beside_lanes
    from stereo_gui.qt.app import configure_pyqtgraph, freeze_startup_objects
    from stereo_gui.qt.context import AppContext
    from stereo_gui.qt.dialogs.source_dialog import SourceChoice
    from stereo_gui.qt.main_window import MainWindow
    from stereo_gui.sources.open import open_source

    use_opencv_threads_beside_lanes()  # as run_app does first

    app = QApplication.instance() or QApplication(sys.argv[:1])
    configure_pyqtgraph()
    # the simulated rig as the application opens it; building it takes seconds: before timing
    source = open_source(f"sim:{args.mode}").source
    ctx = AppContext()
    window = MainWindow(ctx)
    window.resize(1400, 900)
    window.show()
    ctx.calibration_model.set(source.rig.true_calibration(), None,
                              note="simulated rig's TRUE calibration")
    window.live_tab.params_panel.apply_preset(args.preset)
    window.show_tab("live")
    freeze_startup_objects()  # as run_app does once the window is shown
    if not args.idle:
        window.use_source(source, SourceChoice("sim"))

    # warm-up: first frames build the pipeline and the images' textures
    t_end = time.monotonic() + 60
    while not args.idle and window.live_tab.frames_shown < 5 and time.monotonic() < t_end:
        app.processEvents()
        time.sleep(0.001)

    gaps_ms: list[float] = []
    clock = QElapsedTimer()
    clock.start()
    last = [clock.nsecsElapsed()]

    def tick() -> None:
        now = clock.nsecsElapsed()
        gaps_ms.append((now - last[0]) / 1e6)
        last[0] = now

    timer = QTimer()
    timer.setTimerType(Qt.TimerType.PreciseTimer)
    timer.setInterval(1)
    timer.timeout.connect(tick)
    shown0 = window.live_tab.frames_shown
    cam_fps, proc_fps = [], []

    def sample_fps() -> None:
        cam_fps.append(ctx.frames.status().camera_fps)
        proc_fps.append(ctx.frames.status().processing_fps)

    fps_timer = QTimer()
    fps_timer.setInterval(500)
    fps_timer.timeout.connect(sample_fps)
    t0 = time.monotonic()
    elapsed, shown = 0.0, 0

    def finish() -> None:
        # the measurement ends before the quit: QApplication.quit() closes the window, and
        # closing (stopping the frame worker, saving the settings) is not the live view
        nonlocal elapsed, shown
        timer.stop()
        fps_timer.stop()
        elapsed = time.monotonic() - t0
        shown = window.live_tab.frames_shown - shown0
        app.quit()

    QTimer.singleShot(int(args.seconds * 1000), finish)
    timer.start()
    fps_timer.start()
    app.exec()
    window.close()

    gaps = sorted(gaps_ms)
    result = {
        "seconds": round(elapsed, 2),
        "preset": args.preset,
        "idle": args.idle,
        "load_average_1min": round(os.getloadavg()[0], 2),
        "longest_stall_ms": round(gaps[-1], 2) if gaps else None,
        "p99_gap_ms": round(gaps[int(0.99 * (len(gaps) - 1))], 2) if gaps else None,
        "median_gap_ms": round(gaps[len(gaps) // 2], 2) if gaps else None,
        "stalls_over_30ms": sum(g > 30 for g in gaps),
        "frames_drawn_per_s": round(shown / elapsed, 1),
        "camera_fps": round(sum(cam_fps) / len(cam_fps), 1) if cam_fps else 0.0,
        "processing_fps": round(sum(proc_fps) / len(proc_fps), 1) if proc_fps else 0.0,
        "cpu_count": os.cpu_count(),
        "target_ms": 30,
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        what = "idle window (no source)" if args.idle else "live view"
        print(f"{what} for {result['seconds']} s on the simulated rig, preset {args.preset}; "
              f"machine load average {result['load_average_1min']} on {os.cpu_count()} CPUs")
        print(f"longest event-loop stall: {result['longest_stall_ms']} ms (target < 30 ms); "
              f"99th percentile gap {result['p99_gap_ms']} ms; "
              f"{result['stalls_over_30ms']} gaps over 30 ms")
        print(f"frames drawn: {result['frames_drawn_per_s']}/s; camera {result['camera_fps']} fps, "
              f"processing {result['processing_fps']} fps (as the status bar shows them)")
    return 0 if gaps and gaps[-1] < 30 else 1


if __name__ == "__main__":
    sys.exit(main())
