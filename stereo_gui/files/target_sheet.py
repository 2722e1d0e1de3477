"""Printable calibration targets as PDF, SVG or PNG, at true scale (core.target_sheet lays them
out). Every file is written atomically.

- PDF: one page of the paper's size in points, the shapes in a content stream scaled to mm
  (uncompressed, so that its coordinates can be checked), text in the standard Helvetica font.
- SVG: width and height in mm and a viewBox in mm, so one user unit is one millimetre.
- PNG: drawn at `dpi` dots per inch with subpixel edges, and a pHYs chunk that tells viewers and
  printers that resolution.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from stereo_gui.core.errors import InputError
from stereo_gui.core.target_sheet import TargetSheet
from stereo_gui.files.atomic import write_bytes_atomic, write_text_atomic

PT_PER_MM = 72.0 / 25.4
FORMATS = (".pdf", ".svg", ".png")
MAX_PNG_PIXELS = 250_000_000  # A4 at 1600 dpi; the image is drawn whole in memory
_GREY_FRAME = 0.75  # the outline of the target: light grey, to cut along


def write_target(sheet: TargetSheet, path: str | Path, dpi: float = 300.0) -> Path:
    """Write `sheet` to `path`; the suffix (.pdf, .svg or .png) chooses the format."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise InputError(f"cannot write a target as {path.name}: use a .pdf, .svg or .png file")
    if not path.parent.is_dir():
        raise InputError(f"cannot write {path}: folder {path.parent} does not exist")
    if suffix == ".pdf":
        return write_bytes_atomic(path, pdf_bytes(sheet))
    if suffix == ".svg":
        return write_text_atomic(path, svg_text(sheet))
    if not 50 <= dpi <= 2400:
        raise InputError(f"--dpi must be between 50 and 2400, not {dpi:g}")
    w, h = (round(v / 25.4 * dpi) for v in sheet.page_mm)
    if w * h > MAX_PNG_PIXELS:
        raise InputError(f"{sheet.page_name} at {dpi:g} dpi would be a PNG of {w} x {h} px (at "
                         f"most {MAX_PNG_PIXELS // 1_000_000} megapixels): give a lower --dpi, "
                         "or write a .pdf or .svg, which print at any size")
    return write_bytes_atomic(path, png_bytes(sheet, dpi))


# ---- PDF -------------------------------------------------------------------------------------
def _pdf_text(s: str) -> str:
    s = s.encode("latin-1", "replace").decode("latin-1")
    return s.replace("\\", "\\\\").replace("(", "\\(").replace(")", "\\)")


def _num(v: float) -> str:
    return f"{v:.4f}".rstrip("0").rstrip(".") or "0"


def pdf_content(sheet: TargetSheet) -> str:
    """The page's content stream. The shapes are drawn in mm with y down: the first operator
    maps (x mm, y mm from the top) to points."""
    pw, ph = sheet.page_mm
    k = PT_PER_MM
    ops = ["q", f"{_num(k)} 0 0 {_num(-k)} 0 {_num(ph * k)} cm"]
    o = sheet.outline
    ops.append(f"{_GREY_FRAME} G 0.2 w {_num(o.x)} {_num(o.y)} {_num(o.w)} {_num(o.h)} re S")
    ops.append("0 g")
    for r in sheet.rects:
        ops.append(f"{_num(r.x)} {_num(r.y)} {_num(r.w)} {_num(r.h)} re f")
    c4 = 0.5522847498
    for c in sheet.circles:
        x, y, rad = c.cx, c.cy, c.r
        d = c4 * rad
        ops.append(
            f"{_num(x + rad)} {_num(y)} m "
            f"{_num(x + rad)} {_num(y + d)} {_num(x + d)} {_num(y + rad)} "
            f"{_num(x)} {_num(y + rad)} c "
            f"{_num(x - d)} {_num(y + rad)} {_num(x - rad)} {_num(y + d)} "
            f"{_num(x - rad)} {_num(y)} c "
            f"{_num(x - rad)} {_num(y - d)} {_num(x - d)} {_num(y - rad)} "
            f"{_num(x)} {_num(y - rad)} c "
            f"{_num(x + d)} {_num(y - rad)} {_num(x + rad)} {_num(y - d)} "
            f"{_num(x + rad)} {_num(y)} c f")
    b = sheet.scale_bar
    ops.append(f"{_num(b.x)} {_num(b.y)} {_num(b.w)} {_num(b.h)} re f")
    ops.append("Q")
    # text in points, y up
    size = sheet.text_mm * k
    x = sheet.text_at_mm[0] * k
    y = (ph - sheet.text_at_mm[1]) * k
    ops.append(f"BT /F1 {_num(size * 0.8)} Tf {_num(size * 1.1)} TL {_num(x)} {_num(y)} Td")
    for i, line in enumerate(sheet.lines):
        ops.append(("" if i == 0 else "T* ") + f"({_pdf_text(line)}) Tj")
    ops.append("ET")
    return "\n".join(ops) + "\n"


def pdf_bytes(sheet: TargetSheet) -> bytes:
    """A one-page PDF 1.4 file of the sheet."""
    pw, ph = sheet.page_mm
    content = pdf_content(sheet).encode("latin-1")
    objs = [
        b"<< /Type /Catalog /Pages 2 0 R >>",
        b"<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
        (f"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {_num(pw * PT_PER_MM)} "
         f"{_num(ph * PT_PER_MM)}] /Resources << /Font << /F1 5 0 R >> >> /Contents 4 0 R >>"
         ).encode(),
        b"<< /Length " + str(len(content)).encode() + b" >>\nstream\n" + content + b"endstream",
        b"<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica /Encoding /WinAnsiEncoding >>",
        (f"<< /Title ({_pdf_text(sheet.lines[0])}) /Producer (stereo-gui target) >>").encode(),
    ]
    out = bytearray(b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n")
    offsets = []
    for i, body in enumerate(objs, start=1):
        offsets.append(len(out))
        out += f"{i} 0 obj\n".encode() + body + b"\nendobj\n"
    xref = len(out)
    out += f"xref\n0 {len(objs) + 1}\n0000000000 65535 f \n".encode()
    for off in offsets:
        out += f"{off:010d} 00000 n \n".encode()
    out += (f"trailer\n<< /Size {len(objs) + 1} /Root 1 0 R /Info {len(objs)} 0 R >>\n"
            f"startxref\n{xref}\n%%EOF\n").encode()
    return bytes(out)


# ---- SVG -------------------------------------------------------------------------------------
def _xml(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def svg_text(sheet: TargetSheet) -> str:
    """The sheet as SVG; one user unit is one millimetre."""
    pw, ph = sheet.page_mm
    o = sheet.outline
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<svg xmlns="http://www.w3.org/2000/svg" width="{_num(pw)}mm" height="{_num(ph)}mm" '
           f'viewBox="0 0 {_num(pw)} {_num(ph)}">',
           f"<title>{_xml(sheet.lines[0])}</title>",
           f'<rect x="0" y="0" width="{_num(pw)}" height="{_num(ph)}" fill="white"/>',
           f'<rect x="{_num(o.x)}" y="{_num(o.y)}" width="{_num(o.w)}" height="{_num(o.h)}" '
           f'fill="none" stroke="#bfbfbf" stroke-width="0.2"/>',
           '<g fill="black" shape-rendering="crispEdges">']
    for r in sheet.rects:
        out.append(f'<rect x="{_num(r.x)}" y="{_num(r.y)}" width="{_num(r.w)}" '
                   f'height="{_num(r.h)}"/>')
    out.append("</g>")
    out.append('<g fill="black">')
    for c in sheet.circles:
        out.append(f'<circle cx="{_num(c.cx)}" cy="{_num(c.cy)}" r="{_num(c.r)}"/>')
    b = sheet.scale_bar
    out.append(f'<rect x="{_num(b.x)}" y="{_num(b.y)}" width="{_num(b.w)}" height="{_num(b.h)}"/>')
    out.append("</g>")
    x, y = sheet.text_at_mm
    for i, line in enumerate(sheet.lines):
        out.append(f'<text x="{_num(x)}" y="{_num(y + i * sheet.text_mm * 1.1)}" '
                   f'font-family="Helvetica, Arial, sans-serif" '
                   f'font-size="{_num(sheet.text_mm * 0.8)}">{_xml(line)}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


# ---- PNG -------------------------------------------------------------------------------------
_SHIFT = 8  # subpixel bits of cv2's drawing


def png_image(sheet: TargetSheet, dpi: float) -> np.ndarray:
    """The sheet drawn at `dpi` (gray uint8, white paper)."""
    pw, ph = sheet.page_mm
    k = dpi / 25.4  # px per mm
    w, h = int(round(pw * k)), int(round(ph * k))
    img = np.full((h, w), 255, np.uint8)
    f = float(1 << _SHIFT)

    def poly(x0: float, y0: float, x1: float, y1: float) -> NDArray[np.int32]:
        # pixel (i, j) covers [i, i + 1): the mm edge x maps to pixel edge x * k, whose
        # centre-based coordinate is x * k - 0.5
        x0, y0, x1, y1 = ((v * k - 0.5) * f for v in (x0, y0, x1, y1))
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], np.int32)

    o = sheet.outline
    cv2.polylines(img, [poly(o.x, o.y, o.x + o.w, o.y + o.h)], True, 190, max(1, int(0.2 * k)),
                  cv2.LINE_AA, _SHIFT)
    shapes = [poly(r.x, r.y, r.x + r.w, r.y + r.h) for r in sheet.rects]
    b = sheet.scale_bar
    shapes.append(poly(b.x, b.y, b.x + b.w, b.y + b.h))
    if shapes:
        cv2.fillPoly(img, shapes, 0, cv2.LINE_AA, _SHIFT)
    for c in sheet.circles:
        cv2.circle(img, (int(round((c.cx * k - 0.5) * f)), int(round((c.cy * k - 0.5) * f))),
                   int(round(c.r * k * f)), 0, -1, cv2.LINE_AA, _SHIFT)
    x, y = sheet.text_at_mm
    scale = sheet.text_mm * 0.8 * k / 22.0  # Hershey simplex is about 22 px high at scale 1
    for i, line in enumerate(sheet.lines):
        yy = int(round((y + i * sheet.text_mm * 1.1) * k))
        cv2.putText(img, line.encode("ascii", "replace").decode(), (int(round(x * k)), yy),
                    cv2.FONT_HERSHEY_SIMPLEX, scale, 0, max(1, int(round(scale * 1.5))), cv2.LINE_AA)
    return img


def _with_phys(png: bytes, dpi: float) -> bytes:
    """Insert a pHYs chunk (pixels per metre) after IHDR."""
    ppm = int(round(dpi / 0.0254))
    data = struct.pack(">IIB", ppm, ppm, 1)
    chunk = struct.pack(">I", len(data)) + b"pHYs" + data
    chunk += struct.pack(">I", zlib.crc32(b"pHYs" + data) & 0xFFFFFFFF)
    ihdr_end = 8 + 8 + 13 + 4  # signature, IHDR length+type, IHDR data, CRC
    return png[:ihdr_end] + chunk + png[ihdr_end:]


def png_bytes(sheet: TargetSheet, dpi: float) -> bytes:
    ok, buf = cv2.imencode(".png", png_image(sheet, dpi))
    if not ok:
        raise InputError("the target could not be encoded as PNG")
    return _with_phys(buf.tobytes(), dpi)
