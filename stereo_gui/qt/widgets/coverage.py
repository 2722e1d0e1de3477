"""Coverage guidance for capture: which regions of each image the target has reached, and what
is still missing, in words.

Two small maps (left and right image) show the target's points of the kept pairs in the 5 x 5
cells of core.coverage, counted by the readiness itself (core.coverage.Readiness), with the
borders of its nine regions and the regions still empty outlined: the map and the words under
it come from the same counts, so they always name the same regions. The readiness says in words
which regions are still empty and
whether tilt and distance vary enough; four bars show how much of the range of horizontal /
vertical position, size and tilt the kept poses span (as ROS camera_calibration does). The widget
only draws: the numbers come from the capture tab (which gets them from the core).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QRectF, Qt
from PySide6.QtGui import QColor, QPen
from PySide6.QtWidgets import (
    QGraphicsRectItem,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.coverage import GRID, MIN_POINTS_PER_CELL, REGIONS, Readiness
from stereo_gui.core.detect import Coverage

GRID_COLS = GRID  # cells across the image in a corner map: the regions' cells
GRID_ROWS = GRID


def pairs_kept(n: int) -> str:
    """"1 pair kept", "2 pairs kept": the noun agrees with the number."""
    return f"{n} pair{'' if n == 1 else 's'} kept"


@dataclass(frozen=True)
class CoverageBar:
    """One bar: `fraction` (0..1) of the wanted range covered, and a short hint for a person."""

    name: str
    fraction: float
    hint: str = ""


MISSING_RGB = (120, 24, 24)  # a cell without points: dark red
TOO_FEW_RGB = (200, 140, 20)  # a cell with some points, fewer than it needs: amber
EMPTY_REGION_PEN = "#ff5252"  # the outline of a region the guidance names as still empty
REGION_PEN = "#202020"  # the borders between the nine regions


def _map_lut() -> np.ndarray:
    """0: dark red (missing); 1: amber (too few points yet); 2..255: from mid to bright green.
    (Every cell with too few points was drawn green before: the ramp overwrote the amber.)"""
    lut = np.zeros((256, 3), np.uint8)
    ramp = np.linspace(0, 1, 254)
    lut[2:, 0] = (30 + 30 * ramp).astype(np.uint8)
    lut[2:, 1] = (120 + 135 * ramp).astype(np.uint8)
    lut[2:, 2] = (40 + 40 * ramp).astype(np.uint8)
    lut[0] = MISSING_RGB
    lut[1] = TOO_FEW_RGB
    return lut


def _region_rect(cells: Iterable[tuple[int, int]]) -> QRectF:
    rows = [r for r, _ in cells]
    cols = [c for _, c in cells]
    return QRectF(min(cols), min(rows), max(cols) - min(cols) + 1, max(rows) - min(rows) + 1)


class CornerMap(pg.GraphicsLayoutWidget):  # type: ignore[misc]  # pyqtgraph ships no types
    """A coarse grid over one image, coloured by how many board corners fell in each cell."""

    def __init__(self, title: str, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setBackground(None)
        self.ci.setContentsMargins(1, 1, 1, 1)
        self.counts = np.zeros((GRID_ROWS, GRID_COLS), np.int32)
        self.view = self.addViewBox(lockAspect=True, enableMouse=False)
        self.view.invertY(True)
        self.item = pg.ImageItem(axisOrder="row-major")
        self.item.setLookupTable(_map_lut())
        self.view.addItem(self.item)
        self.title = title
        self._empty: tuple[str, ...] = tuple(REGIONS)
        self._outlines: dict[str, QGraphicsRectItem] = {}
        for name, cells in REGIONS.items():
            box = QGraphicsRectItem(_region_rect(cells))
            self.view.addItem(box)
            self._outlines[name] = box
        self.setMinimumSize(140, 105)
        self.setMaximumHeight(125)  # a glance, not a picture: leave the height to the pair list
        # the grid fills the map: left to itself the view's range took the outlines' pens in
        # and showed the grid at half the size, in a margin of nothing
        self.view.disableAutoRange()
        self.view.setRange(xRange=(0, GRID_COLS), yRange=(0, GRID_ROWS), padding=0.03)
        self._redraw()

    def show_counts(self, counts: np.ndarray, empty_regions: Iterable[str]) -> None:
        """Show one camera's cell counts (GRID x GRID) and outline `empty_regions` (names of
        core.coverage.REGIONS): both from the same Readiness as the words under the maps."""
        self.counts = np.asarray(counts, np.int32).reshape(GRID_ROWS, GRID_COLS).copy()
        self._empty = tuple(r for r in REGIONS if r in set(empty_regions))
        self._redraw()

    def outlined_regions(self) -> list[str]:
        """The regions outlined as still empty, in REGIONS order."""
        return list(self._empty)

    def covered_fraction(self) -> float:
        """Share of grid cells with enough points."""
        return float(np.count_nonzero(self.counts >= MIN_POINTS_PER_CELL)) / self.counts.size

    def _redraw(self) -> None:
        c = self.counts.astype(np.float64)
        top = c.max()
        # cells with enough points map to 2..255 (log-like so one pose does not wash out the
        # rest), too few to 1
        full = 2 + np.round(253 * np.sqrt(c / top)) if top > 0 else np.zeros_like(c)
        img = np.where(c >= MIN_POINTS_PER_CELL, full, np.where(c > 0, 1, 0))
        self.item.setImage(img.astype(np.uint8), levels=(0, 255), autoLevels=False)
        self.item.setRect(0, 0, GRID_COLS, GRID_ROWS)
        for name, box in self._outlines.items():
            empty = name in self._empty
            pen = QPen(QColor(EMPTY_REGION_PEN if empty else REGION_PEN), 2.5 if empty else 1.5)
            pen.setCosmetic(True)  # screen px, whatever the map's size
            box.setPen(pen)
            box.setZValue(6 if empty else 4)  # an empty region's outline is never hidden
        empty_text = ", ".join(self._empty) or "none"
        self.setToolTip(f"{self.title}: where the target's points have been seen in the kept "
                        "pairs (dark red = none yet, amber = too few; a region counts when all "
                        f"its cells are green). Outlined in red, not yet covered: {empty_text}.")


class CoverageWidget(QWidget):
    """Maps of corner positions for both cameras and pose-coverage bars with a pair count."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        box = QGroupBox("Coverage")
        outer.addWidget(box)
        layout = QVBoxLayout(box)

        maps = QHBoxLayout()
        self.left_map = CornerMap("Left camera")
        self.right_map = CornerMap("Right camera")
        for title, m in (("Left", self.left_map), ("Right", self.right_map)):
            column = QVBoxLayout()
            lab = QLabel(title)
            lab.setAlignment(Qt.AlignmentFlag.AlignHCenter)
            column.addWidget(lab)
            column.addWidget(m)
            maps.addLayout(column)
        layout.addLayout(maps)

        grid = QGridLayout()
        self._bars: dict[str, QProgressBar] = {}
        self._hints: dict[str, str] = {}  # what each bar still needs, "ok" when full
        for i, name in enumerate(("X", "Y", "Size", "Tilt")):
            row, col = i // 2, 3 * (i % 2)  # two by two: half the height of a column of four
            grid.addWidget(QLabel(name), row, col)
            bar = QProgressBar()
            bar.setRange(0, 100)
            bar.setTextVisible(True)
            bar.setMaximumHeight(16)
            bar.setToolTip(f"{name}: how much of its range the kept poses span")
            grid.addWidget(bar, row, col + 1)
            self._bars[name] = bar
        grid.setColumnStretch(1, 1)
        grid.setColumnStretch(4, 1)
        layout.addLayout(grid)

        self.count_label = QLabel("0 pairs")
        self.count_label.setWordWrap(True)
        layout.addWidget(self.count_label)
        self.readiness_label = QLabel("")
        self.readiness_label.setWordWrap(True)
        layout.addWidget(self.readiness_label)
        # what would still help once ready (the far sides): smaller, it does not hold anything up
        self.advice_label = QLabel("")
        self.advice_label.setWordWrap(True)
        self.advice_label.setStyleSheet("color: #666666; font-size: 9pt")
        layout.addWidget(self.advice_label)
        self.set_bars([])
        self.set_count(0, 20)

    def set_bars(self, bars: Sequence[CoverageBar]) -> None:
        given = {b.name: b for b in bars}
        for name, bar in self._bars.items():
            b = given.get(name)
            frac = 0.0 if b is None else float(np.clip(b.fraction, 0.0, 1.0))
            bar.setValue(int(round(100 * frac)))
            colour = "#3a3" if frac >= 0.999 else ("#c90" if frac >= 0.5 else "#c33")
            bar.setStyleSheet(f"QProgressBar::chunk {{ background: {colour}; }}")
            self._hints[name] = "" if b is None else b.hint
            bar.setToolTip(f"{name}: how much of its range the kept poses span"
                           + (f" ({self._hints[name]})" if self._hints[name] else ""))

    def set_coverage(self, cov: Coverage) -> None:
        """Show a core `detect.Coverage` (bars, count against the recommended count)."""
        names = {"x": "X", "y": "Y", "size": "Size", "skew": "Tilt"}
        hints = {"x": "left-right", "y": "up-down", "size": "near-far", "skew": "tilt"}
        bars = []
        for a in cov.axes:
            hint = "ok" if a.progress >= 1.0 else f"need more {hints.get(a.name, a.name)}"
            bars.append(CoverageBar(names.get(a.name, a.name), a.progress, hint))
        self.set_bars(bars)
        self.set_count(cov.count, cov.recommended_count)
        missing = cov.missing()
        self.count_label.setToolTip("; ".join(missing) if missing else "coverage is complete")

    def set_readiness(self, r: Readiness) -> None:
        """Show a core.coverage.Readiness: its counts and empty regions on the maps, ready or
        not, and what is missing in words."""
        empty = r.empty
        self.left_map.show_counts(r.counts["left"], empty["left"])
        self.right_map.show_counts(r.counts["right"], empty["right"])
        advice = r.advice()
        self.readiness_label.setText(r.summary()[:-len(advice)].rstrip() if advice else r.summary())
        self.advice_label.setText(advice)
        self.advice_label.setVisible(bool(advice))
        self.readiness_label.setStyleSheet(
            "color: #1e7b34; font-weight: bold" if r.ready else "color: #9a5b00")
        self.count_label.setText(pairs_kept(r.pairs))  # (the words below say what is missing)

    def bar_values(self) -> dict[str, int]:
        """Percent shown on each bar (for tests and screenshots)."""
        return {name: bar.value() for name, bar in self._bars.items()}

    def set_count(self, n_pairs: int, recommended: int) -> None:
        self.count_label.setText(f"{pairs_kept(n_pairs)} (usually {recommended} or more)")
