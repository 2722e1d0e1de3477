"""The 3D point cloud of the current frame: pyqtgraph's OpenGL view (drag to rotate, wheel to
zoom, middle or Ctrl-drag to pan), coloured from the image or by distance.

The cloud is computed off the UI thread (`stereo_gui.pipeline.cloud`, on a job runner of its
own, a few times a second); this widget only hands the arrays to OpenGL. pyqtgraph's OpenGL
module needs PyOpenGL and an OpenGL context: where either is missing the view says so instead.
"""

from __future__ import annotations

import logging
import os
import sys

from PySide6.QtCore import Signal
from PySide6.QtGui import QGuiApplication, QOffscreenSurface, QOpenGLContext, QVector3D
from PySide6.QtWidgets import QComboBox, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from stereo_gui.core.util import how_many
from stereo_gui.pipeline.cloud import IMAGE_BACKGROUND_RGB, CloudPoints

log = logging.getLogger(__name__)

COLOUR_TEXT = {"image": "colour from the image", "distance": "colour by distance"}


MIN_GL_VERSION = (2, 1)  # what pyqtgraph's GLViewWidget checks for


def _match_pyopengl_to_qt() -> None:
    """PyOpenGL chooses GLX or EGL when it is first imported, from the session (EGL when
    WAYLAND_DISPLAY is set); Qt on X11 (xcb, also under XWayland) makes GLX contexts unless told
    otherwise. Where they would disagree, PyOpenGL is told Qt's choice (the view stayed empty)."""
    if "OpenGL" in sys.modules or "PYOPENGL_PLATFORM" in os.environ:
        return
    if QGuiApplication.platformName() == "xcb":
        egl = os.environ.get("QT_XCB_GL_INTEGRATION", "") == "xcb_egl"
        os.environ["PYOPENGL_PLATFORM"] = "egl" if egl else "glx"


def opengl_problem() -> str:
    """Why no OpenGL view can be made here ("" when it can): PyOpenGL missing, or no context."""
    _match_pyopengl_to_qt()
    try:
        # imported here, after _match_pyopengl_to_qt: PyOpenGL fixes GLX or EGL on import;
        # it is what pyqtgraph.opengl needs, and ships no types
        import OpenGL.GL  # type: ignore[import-untyped]  # noqa: F401
    except ImportError as exc:
        return f"the 3D view needs PyOpenGL ({exc})"
    except Exception as exc:  # noqa: BLE001 - PyOpenGL raises other errors without a GL library
        return f"the 3D view needs an OpenGL library ({type(exc).__name__}: {exc})"
    ctx = QOpenGLContext()
    if not ctx.create():
        return "no OpenGL context can be made on this display"
    version = ctx.format().version()
    if not ctx.isOpenGLES() and version < MIN_GL_VERSION:
        # (offscreen Qt with an X display present makes a 2.0 context, which pyqtgraph refuses:
        # the view stayed black or the process crashed)
        return (f"the 3D view needs OpenGL {MIN_GL_VERSION[0]}.{MIN_GL_VERSION[1]}; this display "
                f"gives {version[0]}.{version[1]}")
    surface = QOffscreenSurface()
    surface.setFormat(ctx.format())
    surface.create()
    ok = surface.isValid() and ctx.makeCurrent(surface)
    if ok:
        ctx.doneCurrent()
    surface.destroy()
    return "" if ok else "no OpenGL surface can be made on this display"


class CloudView(QWidget):
    """The point cloud view; `colouringChanged(str)` when the user picks another colouring."""

    colouringChanged = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.colour_combo = QComboBox()
        for key, text in COLOUR_TEXT.items():
            self.colour_combo.addItem(text, key)
        self.colour_combo.currentIndexChanged.connect(
            lambda _i: self.colouringChanged.emit(self.colouring))
        self.info = QLabel("waiting for a frame…")
        row = QHBoxLayout()
        row.addWidget(self.colour_combo)
        row.addWidget(self.info, 1)
        col = QVBoxLayout(self)
        col.setContentsMargins(4, 4, 4, 4)
        col.addLayout(row)
        self.problem = opengl_problem()
        self.gl = None
        self.scatter = None
        if self.problem:
            note = QLabel(f"No 3D view: {self.problem}.")
            note.setWordWrap(True)
            col.addWidget(note, 1)
            self.colour_combo.setEnabled(False)
            self.info.setText("")
            return
        # lazy: pyqtgraph.opengl and PyOpenGL cost 170-220 ms, for a window most runs never open
        import pyqtgraph.opengl as gl

        self.gl = gl.GLViewWidget()
        self.gl.setBackgroundColor(IMAGE_BACKGROUND_RGB)
        self.gl.setCameraPosition(distance=3.0, elevation=12, azimuth=-90)
        grid = gl.GLGridItem()
        grid.setSize(4, 6)
        grid.setSpacing(0.5, 0.5)
        grid.translate(0, 3, -1.0)
        self.gl.addItem(grid)
        axes = gl.GLAxisItem()
        axes.setSize(0.3, 0.3, 0.3)  # the left camera: x right, y ahead, z up
        self.gl.addItem(axes)
        # opaque: the default additive blending turns dense parts of the cloud white
        self.scatter = gl.GLScatterPlotItem(size=2.0, pxMode=True, glOptions="opaque")
        self.gl.addItem(self.scatter)
        col.addWidget(self.gl, 1)
        self._centred = False

    @property
    def colouring(self) -> str:
        return str(self.colour_combo.currentData())

    def show_points(self, cloud: CloudPoints) -> None:
        """Draw a `stereo_gui.pipeline.cloud.CloudPoints` (arrays handed over, nothing more)."""
        self.info.setText(f"{how_many(cloud.count, 'point')}, {cloud.z_near_m:.2f} – {cloud.z_far_m:.2f} m")
        self.points = cloud
        if self.gl is None or self.scatter is None:
            return
        self.gl.setBackgroundColor(cloud.background_rgb)  # (by distance: a grey of its own)
        self.scatter.setData(pos=cloud.xyz_m, color=cloud.rgba)
        if not self._centred and cloud.count:
            mid = (cloud.z_near_m + cloud.z_far_m) / 2
            self.gl.opts["center"] = QVector3D(0.0, float(mid), 0.0)
            self.gl.setCameraPosition(distance=max(1.0, 1.6 * mid))
            self._centred = True

    def show_problem(self, text: str) -> None:
        self.info.setText(text)
