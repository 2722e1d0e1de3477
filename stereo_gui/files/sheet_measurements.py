"""The Measurements sheet: one row per `MeasurementRecord`, units in the headers, the time a
date-time cell (UTC); streamed into a new workbook, or appended below the rows of a loaded one."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from openpyxl.cell import WriteOnlyCell
from openpyxl.utils import get_column_letter
from openpyxl.worksheet._write_only import WriteOnlyWorksheet

from stereo_gui.core.jobs import Cancel, ProgressCallback, check_cancel
from stereo_gui.core.util import how_many
from stereo_gui.files.measurement_record import MeasurementRecord
from stereo_gui.files.sheet_columns import (
    COLUMNS,
    ERROR_COLUMNS,
    ERROR_FIELDS,
    NOTE_COLUMN,
    XLSX_HEADERS,
    number_formats,
    row_values,
)
from stereo_gui.files.sheet_draft import Sheet, bold_font, print_landscape_one_page_wide

CANCEL_EVERY_ROWS = 500  # a streamed export looks at its cancel flag and reports this often


def _lay_out(ws: WriteOnlyWorksheet) -> None:
    """Column widths, the frozen header, printing."""
    widths = [c[3] for c in COLUMNS] + [c[2] for c in ERROR_COLUMNS] + [NOTE_COLUMN[3]]
    names = [c[0] for c in COLUMNS] + list(ERROR_FIELDS) + [NOTE_COLUMN[0]]
    for i, (name, header, width) in enumerate(zip(names, XLSX_HEADERS, widths, strict=True),
                                              start=1):
        # wide enough for the bold header with its unit ("Expected error (mm)" was cut off)
        width = max(21 if name == "time" else width, round(1.1 * len(header) + 2))
        ws.column_dimensions[get_column_letter(i)].width = width
    ws.freeze_panes = "A2"
    # printed (or made a PDF) landscape, one page wide, the header on every page: it was cut
    # into five pages of columns
    print_landscape_one_page_wide(ws)
    ws.print_title_rows = "1:1"


def write_measurements_sheet(ws: WriteOnlyWorksheet, records: Sequence[MeasurementRecord],
                             cancel: Cancel = None,
                             progress: ProgressCallback | None = None) -> int:
    """Stream the header and one row per record into a write-only sheet; return the count.

    `cancel` (see core.jobs.Cancel) is looked at and `progress(done, total, text)` called
    every CANCEL_EVERY_ROWS rows."""
    _lay_out(ws)
    bold = bold_font()
    header = []
    for text in XLSX_HEADERS:
        c = WriteOnlyCell(ws, text)
        c.font = bold
        header.append(c)
    ws.append(header)
    formats = number_formats()
    n = 0
    for rec in records:
        row = []
        for value, fmt in zip(row_values(rec), formats, strict=True):
            c = WriteOnlyCell(ws, value)
            c.number_format = fmt
            row.append(c)
        ws.append(row)
        n += 1
        if n % CANCEL_EVERY_ROWS == 0:
            check_cancel(cancel)
            if progress is not None:
                progress(n, len(records), f"{n:,} of {how_many(len(records), 'row')}")
    return n


def append_measurement_rows(ws: Sheet, records: Iterable[MeasurementRecord]) -> int:
    """Append records below the last row of a loaded (not write-only) sheet."""
    # the sheet's size is read once: ws.max_row scans every cell, so asking it per row made a
    # 20,000-row export quadratic
    row = ws.max_row
    formats = number_formats()
    n = 0
    for rec in records:
        row += 1
        for col, (value, fmt) in enumerate(zip(row_values(rec), formats, strict=True), start=1):
            ws.cell(row=row, column=col, value=value).number_format = fmt
        n += 1
    return n
