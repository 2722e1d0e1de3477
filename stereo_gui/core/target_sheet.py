"""A printable calibration target laid out on a page, in millimetres (no drawing, no files).

The sheet holds the target at true scale with its white border, a 100 mm scale bar to check the
print with a ruler, and the target's parameters in words. Coordinates are millimetres from the
page's top-left corner, y down. A target that does not fit inside the page's margins in either
orientation is refused (InputError) with its size and the room there is.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from stereo_gui.core.board import TARGET_NAMES, BoardSpec
from stereo_gui.core.errors import InputError

PAGES_MM = {"a4": (210.0, 297.0), "a3": (297.0, 420.0), "a2": (420.0, 594.0),
            "letter": (215.9, 279.4), "legal": (215.9, 355.6), "tabloid": (279.4, 431.8)}
MARGIN_MM = 6.0  # most printers print to 5 mm of the edge
TEXT_MM = 3.5  # line height of the text (its letters are 0.8 of that)
TEXT_BLOCK_MM = 11.0  # room under the target for the scale bar and two lines of text
SCALE_BAR_MM = 100.0
MAX_PAGE_MM = 2000.0  # wider than A0 (841 x 1189 mm) and the rolls of large-format printers
# a printer's dot is 0.02 to 0.08 mm: below this a square (and the marker or circle in it) does
# not print sharply enough for a detector to place its corners
MIN_PRINTED_SQUARE_MM = 2.0


@dataclass(frozen=True)
class Rect:
    """A black rectangle: top-left corner and size, mm."""

    x: float
    y: float
    w: float
    h: float


@dataclass(frozen=True)
class Circle:
    """A black disc: centre and radius, mm."""

    cx: float
    cy: float
    r: float


@dataclass(frozen=True)
class TargetSheet:
    """Everything a writer draws: page size, black shapes, the scale bar and text lines (mm)."""

    page_mm: tuple[float, float]  # (width, height)
    page_name: str
    board: BoardSpec
    origin_mm: tuple[float, float]  # where the board's point (0, 0) (its object frame) lies
    outline: Rect  # the target with its white border (drawn as a thin grey frame)
    rects: tuple[Rect, ...]
    circles: tuple[Circle, ...]
    scale_bar: Rect  # SCALE_BAR_MM long (or shorter where the page is narrow)
    lines: tuple[str, ...]
    text_at_mm: tuple[float, float]  # baseline of the first line
    text_mm: float = TEXT_MM


def parse_page(text: str) -> tuple[str, tuple[float, float]]:
    """'a4', 'letter', ... or 'WxH' in mm: (name, (width, height) mm)."""
    key = (text or "").strip().lower()
    if key in PAGES_MM:
        return key.upper() if key.startswith("a") else key.capitalize(), PAGES_MM[key]
    m = re.match(r"^\s*(\d+(?:\.\d+)?)\s*[xX]\s*(\d+(?:\.\d+)?)\s*(mm)?\s*$", text or "")
    if not m:
        raise InputError(f"page {text!r} is not known: use {', '.join(PAGES_MM)} or WIDTHxHEIGHT "
                         "in millimetres, for example 300x400")
    w, h = float(m.group(1)), float(m.group(2))
    if w <= 2 * MARGIN_MM or h <= 2 * MARGIN_MM:
        raise InputError(f"a page of {w:g} x {h:g} mm leaves no room inside its margins")
    if w > MAX_PAGE_MM or h > MAX_PAGE_MM:
        raise InputError(f"a page of {w:g} x {h:g} mm is larger than any printer's (at most "
                         f"{MAX_PAGE_MM:g} mm a side)")
    return f"{w:g} x {h:g} mm", (w, h)


def printed_outline_mm(board: BoardSpec) -> tuple[float, float, float, float]:
    """The printed pattern with the white quiet zone the detectors need around it, in the
    board's object frame: (a0, b0, a1, b1) mm. Narrower than the simulated board's border, so
    that the usual boards fit usual paper (a 9x6 chessboard of 25 mm squares on A4)."""
    s = board.square_mm
    if board.target == "chessboard":
        q = max(4.0, 0.2 * s)
        return (-s - q, -s - q, board.cols * s + q, board.rows * s + q)
    if board.target == "charuco":
        q = max(4.0, 0.2 * s)
        return (-q, -q, board.cols * s + q, board.rows * s + q)
    pts = board.object_points_mm()
    q = board.marker_mm / 2.0 + max(4.0, 0.5 * s)
    return (-q, -q, float(pts[:, 0].max()) + q, float(pts[:, 1].max()) + q)


def target_size_mm(board: BoardSpec) -> tuple[float, float]:
    """Width and height of the printed target with its white quiet zone, mm."""
    a0, b0, a1, b1 = printed_outline_mm(board)
    return (a1 - a0, b1 - b0)


def describe(board: BoardSpec) -> str:
    """The target's parameters in words, as printed on the sheet."""
    if board.target == "chessboard":
        return (f"Chessboard {board.cols}x{board.rows} inner corners "
                f"({board.cols + 1}x{board.rows + 1} squares), squares {board.square_mm:g} mm")
    if board.target == "charuco":
        return (f"ChArUco board {board.cols}x{board.rows} squares, squares {board.square_mm:g} mm, "
                f"markers {board.marker_mm:g} mm, dictionary {board.dictionary}")
    spacing = ("rows" if board.target == "acircles" else "centres")
    return (f"{TARGET_NAMES[board.target].capitalize()} {board.cols}x{board.rows}, "
            f"{spacing} {board.square_mm:g} mm apart, circles {board.marker_mm:g} mm across")


def command_for(board: BoardSpec) -> str:
    """The `stereo-gui calibrate` options that describe this target."""
    out = f"--target {board.target} --board {board.cols}x{board.rows} --square-mm {board.square_mm:g}"
    if board.target != "chessboard":
        out += f" --marker-mm {board.marker_mm:g}"
    if board.target == "charuco":
        out += f" --dict {board.dictionary}"
    return out


def layout(board: BoardSpec, page: str = "a4", margin_mm: float = MARGIN_MM) -> TargetSheet:
    """The target centred on the page (turned to landscape when it fits only so), with the scale
    bar and text under it; InputError when it fits neither way."""
    name, (pw, ph) = parse_page(page)
    if board.square_mm < MIN_PRINTED_SQUARE_MM:
        raise InputError(f"squares of {board.square_mm:g} mm do not print sharply enough to be "
                         f"detected: give at least {MIN_PRINTED_SQUARE_MM:g} mm")
    tw, th = target_size_mm(board)
    need_h = th + TEXT_BLOCK_MM
    fits = [(w, h) for w, h in ((pw, ph), (ph, pw))
            if tw <= w - 2 * margin_mm + 1e-9 and need_h <= h - 2 * margin_mm + 1e-9]
    if not fits:
        raise InputError(
            f"a {describe(board)} is {tw:g} x {th:g} mm with its border (and needs "
            f"{TEXT_BLOCK_MM:g} mm more for its scale bar and text), which does not fit on {name} "
            f"({pw - 2 * margin_mm:g} x {ph - 2 * margin_mm:g} mm inside {margin_mm:g} mm margins) "
            "in either orientation: use smaller squares, fewer of them, or a larger page")
    pw, ph = fits[0]
    x0 = (pw - tw) / 2.0
    y0 = margin_mm + max(0.0, (ph - 2 * margin_mm - need_h) / 2.0)
    a0, b0, _, _ = printed_outline_mm(board)
    ox, oy = x0 - a0, y0 - b0  # page position of the board's object point (0, 0)
    rects, circles = _shapes(board, ox, oy)
    bar = min(SCALE_BAR_MM, pw - 2 * margin_mm)
    ty = y0 + th + 1.5
    bar_rect = Rect(pw - margin_mm - bar, ty, bar, 1.0)
    lines = (f"{describe(board)}. Print at 100 % (no 'fit to page'): the bar measures {bar:g} mm.",
             f"Page {name}. stereo-gui calibrate DIR {command_for(board)}")
    return TargetSheet((pw, ph), name, board, (ox, oy), Rect(x0, y0, tw, th), rects, circles,
                       bar_rect, lines, (margin_mm, ty + 1.0 + 3.6))


def _shapes(board: BoardSpec, ox: float, oy: float) -> tuple[tuple[Rect, ...], tuple[Circle, ...]]:
    s = board.square_mm
    rects: list[Rect] = []
    circles: list[Circle] = []
    if board.target == "chessboard":
        # (cols + 1) x (rows + 1) squares, from -1 in squares from corner 0; (-1, -1) black
        for j in range(-1, board.rows):
            for i in range(-1, board.cols):
                if (i + j) % 2 == 0:
                    rects.append(Rect(ox + i * s, oy + j * s, s, s))
    elif board.target in ("circles", "acircles"):
        r = board.marker_mm / 2.0
        for x, y, _ in board.object_points_mm().astype(np.float64):
            circles.append(Circle(ox + x, oy + y, r))
    else:
        for j in range(board.rows):  # the top-left square is black (OpenCV's ChArUco layout)
            for i in range(board.cols):
                if (i + j) % 2 == 0:
                    rects.append(Rect(ox + i * s, oy + j * s, s, s))
        rects += _marker_rects(board, ox, oy)
    return tuple(rects), tuple(circles)


def _marker_rects(board: BoardSpec, ox: float, oy: float) -> list[Rect]:
    """The ArUco markers as black cells: each marker's bit grid (with its black border), rows
    of neighbouring black cells merged into one rectangle."""
    ab = board.aruco_board()
    d = ab.getDictionary()
    bits = int(d.markerSize) + 2
    out = []
    for mid, corners in zip(np.asarray(ab.getIds()).reshape(-1), ab.getObjPoints()):
        c = np.asarray(corners, np.float64).reshape(4, 3)
        x0, y0 = c[:, 0].min(), c[:, 1].min()
        cell = (c[:, 0].max() - x0) / bits
        img = d.generateImageMarker(int(mid), bits)
        for r in range(bits):
            row = img[r] < 128
            k = 0
            while k < bits:
                if not row[k]:
                    k += 1
                    continue
                start = k
                while k < bits and row[k]:
                    k += 1
                out.append(Rect(ox + x0 + start * cell, oy + y0 + r * cell, (k - start) * cell, cell))
    return out
