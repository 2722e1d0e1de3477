"""The regression plot: true distance against disparity (samples and both fits) above the
residuals of each fit."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QWidget

from stereo_gui.core.regression import FitResult

MODELS = ("cubic", "inverse")
_COLOURS = {"cubic": "#f39c12", "inverse": "#5dade2"}  # curves, on the plots' dark background


RESIDUAL_MIN_MM = 1.0  # the residual axis shows at least +- this


class RegressionPlot(pg.GraphicsLayoutWidget):  # type: ignore[misc]  # pyqtgraph ships no types
    """Distance against disparity (samples and both fits) above the residuals of each fit."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.main = self.addPlot(row=0, col=0)
        self.main.setLabel("left", "true distance", units="mm")
        self.main.setLabel("bottom", "disparity", units="px")
        self.main.showGrid(x=True, y=True, alpha=0.25)
        for plot in (self.main,):
            for ax in ("left", "bottom"):
                plot.getAxis(ax).enableAutoSIPrefix(False)  # "kmm" helps nobody
        self.main.addLegend(offset=(-10, 10))
        self.resid = self.addPlot(row=1, col=0)
        self.resid.setLabel("left", "residual", units="mm")
        self.resid.setLabel("bottom", "disparity", units="px")
        self.resid.showGrid(x=True, y=True, alpha=0.25)
        self.resid.setXLink(self.main)
        for ax in ("left", "bottom"):
            self.resid.getAxis(ax).enableAutoSIPrefix(False)
        zero = pg.InfiniteLine(angle=0, pos=0, pen=pg.mkPen("#888", style=Qt.PenStyle.DashLine))
        self.resid.addItem(zero)
        self.ci.layout.setRowStretchFactor(0, 3)
        self.ci.layout.setRowStretchFactor(1, 2)
        self.samples = pg.ScatterPlotItem(size=8, brush=pg.mkBrush("#f4f4f4"), pen=None,
                                          name="samples")
        self.main.addItem(self.samples)
        self.curves = {}
        self.resid_points = {}
        for m in MODELS:
            self.curves[m] = self.main.plot([], [], pen=pg.mkPen(_COLOURS[m], width=2), name=m)
            self.resid_points[m] = pg.ScatterPlotItem(size=7, brush=pg.mkBrush(_COLOURS[m]),
                                                      pen=None)
            self.resid.addItem(self.resid_points[m])

    def draw(self, samples: Sequence[tuple[float, float]], fits: Mapping[str, FitResult]
             ) -> None:
        if samples:
            d = np.array([s[0] for s in samples])
            z = np.array([s[1] for s in samples])
            self.samples.setData(d, z)
            lo, hi = float(d.min()), float(d.max())
            pad = max(0.05 * (hi - lo), 0.5)
            grid = np.linspace(lo - pad, hi + pad, 200)
        else:
            self.samples.setData([], [])
            grid = None
        for m in MODELS:
            fit = fits.get(m)
            if fit is None or grid is None:
                self.curves[m].setData([], [])
                self.resid_points[m].setData([], [])
                continue
            with np.errstate(all="ignore"):
                y = np.asarray(fit.predict(grid), np.float64)
            y = np.where(np.isfinite(y), y, np.nan)
            self.curves[m].setData(grid, y, connect="finite")
            fd = np.array([s[0] for s in fit.samples], float)
            self.resid_points[m].setData(fd, np.asarray(fit.residuals_mm, float))
        if samples:
            z = np.array([s[1] for s in samples])
            span = max(float(z.max() - z.min()), 10.0)
            self.main.setYRange(float(z.min()) - 0.15 * span, float(z.max()) + 0.15 * span)
        # residuals of a millimetre or less (or none: a fit through every sample) on an axis of
        # +-RESIDUAL_MIN_MM, not of +-5e-14
        top = max((float(np.nanmax(np.abs(np.asarray(f.residuals_mm, float))))
                   for f in fits.values() if f is not None and len(f.residuals_mm)),
                  default=0.0)
        top = max(top if np.isfinite(top) else 0.0, RESIDUAL_MIN_MM)
        self.resid.setYRange(-1.15 * top, 1.15 * top, padding=0)
