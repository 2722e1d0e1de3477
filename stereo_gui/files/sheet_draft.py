"""A small sheet drafted cell by cell in any order, then written into a worksheet in row order
(a write-only sheet takes rows only from top to bottom): the Regression and Calibration sheets."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeAlias

from openpyxl.cell import WriteOnlyCell
from openpyxl.styles import Alignment, Font
from openpyxl.utils import get_column_letter
from openpyxl.worksheet._write_only import WriteOnlyWorksheet
from openpyxl.worksheet.worksheet import Worksheet

# a sheet of a workbook being streamed (write-only) or loaded (openpyxl has no type hints)
Sheet: TypeAlias = Worksheet | WriteOnlyWorksheet
# what styles a cell: (cell, row, column, number format, bold)
CellStyler = Callable[[Any, int, int, str | None, bool], None]


def bold_font() -> Font:
    return Font(bold=True)


def print_landscape_one_page_wide(ws: Sheet) -> None:
    """Print (or make a PDF of) the sheet landscape, scaled to one page's width."""
    ws.page_setup.orientation = "landscape"
    ws.sheet_properties.pageSetUpPr.fitToPage = True
    ws.page_setup.fitToWidth = 1
    ws.page_setup.fitToHeight = 0


class SheetDraft:
    """The cells of a small sheet, written in any order and then put into a worksheet in row
    order (a write-only sheet takes rows only from top to bottom)."""

    def __init__(self) -> None:
        self.cells: dict[tuple[int, int], tuple[Any, str | None, bool]] = {}
        self.widths: dict[int, float] = {}
        self.hidden: set[int] = set()
        self.charts: list[tuple[Any, str]] = []
        self.print_one_page_wide = False  # landscape, scaled to the page's width when printed
        self.wrapped: set[tuple[int, int]] = set()

    def set(self, row: int, col: int, value: Any, fmt: str | None = None,
            bold: bool = False, wrap: bool = False) -> None:
        self.cells[(row, col)] = (value, fmt, bold)
        if wrap:  # long text wraps within its column's width, not past the printed page
            self.wrapped.add((row, col))

    def to_sheet(self, ws: Sheet) -> None:
        self._lay_out(ws)
        style = self._styler()
        if isinstance(ws, WriteOnlyWorksheet):
            self._append_rows(ws, style)
        else:
            for (r, c), (value, fmt, is_bold) in self.cells.items():
                style(ws.cell(row=r, column=c, value=value), r, c, fmt, is_bold)
        for chart, anchor in self.charts:
            ws.add_chart(chart, anchor)

    def _lay_out(self, ws: Sheet) -> None:
        """Column widths, hidden columns, the heights of rows of wrapped text, printing."""
        for col, width in self.widths.items():
            ws.column_dimensions[get_column_letter(col)].width = width
        for col in self.hidden:
            ws.column_dimensions[get_column_letter(col)].hidden = True
        for r, lines in self._wrapped_lines().items():
            if lines > 1:
                ws.row_dimensions[r].height = 15 * lines
        if self.print_one_page_wide:
            print_landscape_one_page_wide(ws)

    def _wrapped_lines(self) -> dict[int, int]:
        """A row of wrapped text as tall as its lines (neither Excel nor LibreOffice grows a row
        written by openpyxl: the lines ran over the rows below)."""
        heights: dict[int, int] = {}
        for r, c in self.wrapped:
            text = str(self.cells[(r, c)][0] or "")
            per_line = max(1.0, 1.1 * self.widths.get(c, 8.43))
            heights[r] = max(heights.get(r, 1), math.ceil(len(text) / per_line))
        return heights

    def _styler(self) -> CellStyler:
        """What styles a cell: its number format, bold, wrapped text and the top alignment of
        the other cells of a row of wrapped text."""
        bold = bold_font()
        wrap = Alignment(wrap_text=True, vertical="top")
        top = Alignment(vertical="top")  # the other cells of a row of wrapped text
        wrapped_rows = {r for r, _ in self.wrapped}

        def style(cell: Any, r: int, c: int, fmt: str | None, is_bold: bool) -> None:
            if fmt:
                cell.number_format = fmt
            if is_bold:
                cell.font = bold
            if (r, c) in self.wrapped:
                cell.alignment = wrap
            elif r in wrapped_rows:
                cell.alignment = top

        return style

    def _append_rows(self, ws: WriteOnlyWorksheet, style: CellStyler) -> None:
        n_rows = max((r for r, _ in self.cells), default=0)
        n_cols = max((c for _, c in self.cells), default=0)
        for r in range(1, n_rows + 1):
            row: list[Any] = [None] * n_cols
            for c in range(1, n_cols + 1):
                if (r, c) in self.cells:
                    value, fmt, is_bold = self.cells[(r, c)]
                    cell = WriteOnlyCell(ws, value)
                    style(cell, r, c, fmt, is_bold)
                    row[c - 1] = cell
            ws.append(row)
