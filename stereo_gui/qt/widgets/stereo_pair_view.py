"""Left and right live images side by side, with the chessboard corners found in each."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QHBoxLayout, QWidget

from stereo_gui.core.detect import Detection, PairDetection

_FOUND = "#2e9e3e"
_MISSING = "#c0392b"


class StereoPairView(QWidget):
    """Left and right images side by side (equal size), each with a title and the corners."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        row = QHBoxLayout(self)
        row.setContentsMargins(0, 0, 0, 0)
        row.setSpacing(2)
        self.titles: list[pg.LabelItem] = []
        self.images: list[pg.ImageItem] = []
        self.corner_lines: list[pg.PlotCurveItem] = []
        self.corner_dots: list[pg.ScatterPlotItem] = []
        self.views: list[pg.ViewBox] = []
        for name in ("Left", "Right"):
            glw = pg.GraphicsLayoutWidget()
            glw.setBackground("#202020")
            title = pg.LabelItem(name, size="11pt", color="w")
            glw.addItem(title, row=0, col=0)
            vb = glw.addViewBox(row=1, col=0, lockAspect=True, enableMouse=False)
            vb.invertY(True)
            img = pg.ImageItem(axisOrder="row-major")
            vb.addItem(img)
            line = pg.PlotCurveItem(pen=pg.mkPen("#ffd21f", width=1.5))
            dots = pg.ScatterPlotItem(size=6, pen=pg.mkPen(None), brush=pg.mkBrush("#ff5a1f"))
            vb.addItem(line)
            vb.addItem(dots)
            row.addWidget(glw, 1)
            self.titles.append(title)
            self.images.append(img)
            self.corner_lines.append(line)
            self.corner_dots.append(dots)
            self.views.append(vb)
        self._shape: tuple[int, int] | None = None

    def show_pair(self, left_rgb: np.ndarray, right_rgb: np.ndarray) -> None:
        for img, arr in zip(self.images, (left_rgb, right_rgb), strict=True):
            img.setImage(arr, levels=(0, 255), autoLevels=False)
        shape = left_rgb.shape[:2]
        if shape != self._shape:  # refit only when the size changes, not every frame
            self._shape = shape
            for vb in self.views:
                vb.setRange(xRange=(0, shape[1]), yRange=(0, shape[0]), padding=0.01)

    def clear(self, text: str = "") -> None:
        """Show no images and no corners; each title says `text` after its side's name."""
        for i, (img, name) in enumerate(zip(self.images, ("Left", "Right"), strict=True)):
            img.clear()
            self.show_corners(i, None, False)
            self.set_title(i, f"{name}: {text}" if text else name)

    def show_corners(self, side: int, det: Detection | None, both: bool) -> None:
        line, dots = self.corner_lines[side], self.corner_dots[side]
        if det is None:
            line.setData([], [])
            dots.setData([], [])
            return
        c = det.corners.reshape(-1, 2)
        line.setData(c[:, 0], c[:, 1])
        colour = "#2ee65a" if both else "#ffb01f"
        line.setPen(pg.mkPen(colour, width=1.5))
        dots.setData(c[:, 0], c[:, 1], brush=pg.mkBrush(colour))

    def set_title(self, side: int, text: str, colour: str = "w") -> None:
        self.titles[side].setText(text, color=colour)

    def show_detection(self, det: PairDetection) -> None:
        """Draw both sides' corners and say in each title whether the board was found."""
        both = det.found
        for i, (d, name) in enumerate(((det.left, "Left"), (det.right, "Right"))):
            self.show_corners(i, d, both)
            if d is None:
                self.set_title(i, f"{name}: no board", _MISSING)
            else:
                self.set_title(i, f"{name}: board found", _FOUND)
