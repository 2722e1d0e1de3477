"""Smoke checks that the bundled executable runs on itself, for tests/test_bundle.py.

`STEREO_GUI_BUNDLE_SMOKE=NAME dist/stereo-gui/stereo-gui` runs check NAME instead of the
command line (packaging/launcher.py) and prints one JSON object on stdout. A check that could
run exits 0 and says what it saw; the test judges it. The checks go through the window as a
user does (buttons, not private calls), so they need what the bundle ships and nothing of the
test environment.

- `cloud-view`: the main window on the simulated rig, the Live tab, "Use the simulated rig's
  true calibration", "3D view"; then either the view's note where no OpenGL context can be made
  (`problem`), or the drawn point cloud (`points`, and what the frame buffer holds).
"""

from __future__ import annotations

import importlib.util
import json
import sys

TIMEOUT_S = 120.0  # opening the rig builds its ray maps: seconds, more on a loaded machine


def _wait(signal, timeout_s: float):
    """Run the event loop until `signal` fires (its arguments) or `timeout_s` passes (None)."""
    from PySide6.QtCore import QEventLoop, QTimer

    loop = QEventLoop()
    got: list[tuple] = []

    def fired(*args):
        got.append(args)
        loop.quit()

    signal.connect(fired)
    QTimer.singleShot(int(timeout_s * 1000), loop.quit)
    loop.exec()
    signal.disconnect(fired)
    return got[0] if got else None


def _opengl_platform_modules() -> list[str]:
    """PyOpenGL's platform modules the bundle carries (it picks one by OS and session type)."""
    names = ("glx", "egl", "osmesa", "win32", "darwin")
    return [n for n in names if importlib.util.find_spec(f"OpenGL.platform.{n}") is not None]


def cloud_view() -> dict:
    from PySide6.QtWidgets import QApplication

    from stereo_gui.qt.app import build_window

    app = QApplication.instance() or QApplication(sys.argv[:1])
    report: dict = {"platform": app.platformName(),
                    "opengl_platform_modules": _opengl_platform_modules()}
    ctx, window = build_window(source="sim")
    try:
        window.show()
        window.show_tab("live")
        live = window.live_tab
        if _wait(window.sourceOpened, TIMEOUT_S) is None:
            return {**report, "error": "the simulated rig did not open"}
        live.no_calib.use_true.click()
        if _wait(live.frameShown, TIMEOUT_S) is None:
            return {**report, "error": "no frame was shown"}
        import OpenGL.platform

        report["opengl_platform"] = type(OpenGL.platform.PLATFORM).__module__
        live.cloud_button.click()
        view = live.cloud_view
        report["window_visible"] = view is not None and view.window().isVisible()
        if view.problem:
            return {**report, "problem": view.problem, "gl_view": view.gl is not None}
        shown = _wait(live.cloudShown, TIMEOUT_S)
        if shown is None:
            return {**report, "error": "the 3D view drew no point cloud"}
        image = view.gl.grabFramebuffer()
        w, h = image.width(), image.height()
        samples = [image.pixel(x, y) for y in range(0, h, 5) for x in range(0, w, 5)]
        corner = image.pixel(0, 0)  # the background colour (the cloud sits in the middle)
        return {**report, "points": shown[0].count, "framebuffer": [w, h],
                "colours": len(set(samples)),
                "drawn_fraction": sum(p != corner for p in samples) / max(len(samples), 1)}
    finally:
        window.close()
        ctx.shutdown(5000)


CHECKS = {"cloud-view": cloud_view}


def main(name: str) -> int:
    """Run check `name`, print its JSON report; 0 when it ran, 2 for an unknown name."""
    check = CHECKS.get(name)
    if check is None:
        sys.stderr.write(f"stereo-gui: error: no smoke check {name!r} "
                         f"(one of {', '.join(CHECKS)})\n")
        return 2
    sys.stdout.write(json.dumps(check()) + "\n")
    sys.stdout.flush()
    return 0
