"""Render the application icon's PNGs from resources/icons/stereo-gui.svg.

Run from the repository root after editing the SVG:

    python packaging/make_icons.py

It writes resources/icons/stereo-gui-<N>.png for each size in SIZES (N x N pixels) with Qt's own
SVG renderer, so the PNGs always match the SVG. Needs PySide6 (already a dependency) and no
display: it forces the offscreen platform.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

SIZES = (16, 24, 32, 48, 64, 128, 256)
ICON_DIR = Path(__file__).resolve().parents[1] / "resources" / "icons"


def render(svg: Path, out_dir: Path, sizes: tuple[int, ...] = SIZES) -> list[Path]:
    """Render `svg` to one square PNG per size in `out_dir`; return the written paths."""
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtCore import Qt
    from PySide6.QtGui import QGuiApplication, QImage, QPainter
    from PySide6.QtSvg import QSvgRenderer

    _app = QGuiApplication.instance() or QGuiApplication(sys.argv[:1])
    renderer = QSvgRenderer(str(svg))
    if not renderer.isValid():
        raise SystemExit(f"make_icons: {svg} is not a valid SVG")
    written = []
    for size in sizes:
        image = QImage(size, size, QImage.Format.Format_ARGB32_Premultiplied)
        image.fill(Qt.GlobalColor.transparent)
        painter = QPainter(image)
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        painter.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform)
        renderer.render(painter)
        painter.end()
        path = out_dir / f"stereo-gui-{size}.png"
        if not image.save(str(path), "PNG"):
            raise SystemExit(f"make_icons: could not write {path}")
        written.append(path)
    return written


def main() -> int:
    for path in render(ICON_DIR / "stereo-gui.svg", ICON_DIR):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
