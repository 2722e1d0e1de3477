"""The measurement workbook (openpyxl): made with its three sheets and saved atomically, its zip
checked before it replaces the old file; an existing one loaded, checked to be ours, appended
to and read back. The sheets are written by `sheet_measurements`, `sheet_regression` and
`sheet_calibration`; `spreadsheet` is the face callers use (it loads this module, and openpyxl,
on first use).
"""

from __future__ import annotations

import logging
import os
import zipfile
import zlib
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from openpyxl import Workbook, load_workbook
from openpyxl.utils.exceptions import InvalidFileException

from stereo_gui.core.errors import InputError
from stereo_gui.core.jobs import Cancel, ProgressCallback, check_cancel
from stereo_gui.core.regression import FitResult
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.atomic import atomic_path, os_error_text
from stereo_gui.files.measurement_record import MeasurementRecord
from stereo_gui.files.sheet_calibration import write_calibration_sheet
from stereo_gui.files.sheet_columns import HEADERS, XLSX_HEADERS, record_from_row
from stereo_gui.files.sheet_draft import Sheet, bold_font
from stereo_gui.files.sheet_measurements import append_measurement_rows, write_measurements_sheet
from stereo_gui.files.sheet_regression import regression_samples, write_regression_sheet

log = logging.getLogger(__name__)

FORMAT_VERSION = 1
MEASUREMENTS_SHEET = "Measurements"
REGRESSION_SHEET = "Regression"
CALIBRATION_SHEET = "Calibration"
# written into the workbook's properties so that a workbook of ours can be recognised
WORKBOOK_KEYWORDS = f"stereo-gui measurements v{FORMAT_VERSION}"


# ---- workbooks ------------------------------------------------------------------------------
def _check_xlsx_name(path: Path) -> None:
    if path.suffix.lower() != ".xlsx":
        raise InputError(f"{path}: a workbook file name must end in .xlsx")


def _new_workbook(records: Sequence[MeasurementRecord], fits: Sequence[FitResult] | None,
                  calibration: StereoCalibration | None, calibration_file: str | None,
                  target: Path, cancel: Cancel = None,
                  progress: ProgressCallback | None = None) -> Workbook:
    wb = Workbook(write_only=True)  # streamed: linear in the rows
    try:
        # write-only sheets stream their rows into temporary files as they are appended, so a
        # full disk already shows here
        write_measurements_sheet(wb.create_sheet(MEASUREMENTS_SHEET), records, cancel, progress)
        fitted = tuple(fits or ())
        write_regression_sheet(wb.create_sheet(REGRESSION_SHEET),
                               regression_samples(records, fitted), fitted)
        write_calibration_sheet(wb.create_sheet(CALIBRATION_SHEET), calibration,
                                calibration_file)
    except OSError as exc:
        _discard_write_only(wb)
        raise InputError(f"cannot write {target}: {os_error_text(exc)}; "
                         f"{'it was left untouched' if target.exists() else 'nothing was written'}"
                         ) from exc
    except BaseException:  # cancelled: the streamed rows' temporary files go too
        _discard_write_only(wb)
        raise
    wb.properties.keywords = WORKBOOK_KEYWORDS
    wb.properties.creator = "stereo-gui"
    wb.properties.title = "Stereo GUI measurements"
    return wb


def _verify_xlsx(path: Path) -> None:
    """A workbook that does not read back (a torn zip, a member whose CRC fails) is refused."""
    with zipfile.ZipFile(path) as z:
        bad = z.testzip()
    if bad is not None:
        raise ValueError(f"{bad} is damaged")


def _save(wb: Workbook, path: Path) -> Path:
    try:
        with atomic_path(path, verify=_verify_xlsx) as tmp:
            wb.save(tmp)
    except BaseException:
        _discard_write_only(wb)
        raise
    return path


def _discard_write_only(wb: Workbook) -> None:
    """After a failed save, close the streamed sheets of a write-only workbook and remove their
    temporary files (left open, they print a traceback when they are collected later)."""
    if not getattr(wb, "write_only", False):
        return
    for ws in wb.worksheets:
        writer = getattr(ws, "_writer", None)
        if writer is None or ws.closed:
            continue
        try:
            ws.close()
        except Exception:  # noqa: BLE001 - best effort after the real error
            log.debug("closing sheet %s after a failed save", ws.title, exc_info=True)
        try:
            writer.cleanup()
        except Exception:  # noqa: BLE001
            log.debug("removing the temporary file of sheet %s", ws.title, exc_info=True)


def write_workbook(path: str | os.PathLike[str], records: Iterable[MeasurementRecord],
                   fits: Sequence[FitResult] = (), calibration: StereoCalibration | None = None,
                   calibration_file: str | os.PathLike[str] | None = None, cancel: Cancel = None,
                   progress: ProgressCallback | None = None) -> Path:
    """Write a new workbook (replacing `path` atomically) with the three sheets and the chart.

    `fits` are `stereo_gui.core.regression.FitResult`s; `calibration_file` names the file the
    calibration was loaded from (shown in the Calibration sheet). `cancel` (an Event or a
    callable, see core.jobs.Cancel) stops the export between rows with Cancelled: nothing is
    written, no temporary file is left, `path` stays as it was. `progress(done, total, text)`
    is told the rows written.
    """
    path = Path(path)
    _check_xlsx_name(path)
    records = list(records)
    wb = _new_workbook(records, fits, calibration,
                       None if calibration_file is None else str(calibration_file), path,
                       cancel, progress)
    try:
        check_cancel(cancel)
    except BaseException:
        _discard_write_only(wb)
        raise
    _save(wb, path)
    log.info("wrote %d measurements to %s", len(records), path)
    return path


def _load_ours(path: Path) -> Workbook:
    """Load an existing workbook of ours, or raise InputError naming what is wrong (untouched)."""
    try:
        wb = load_workbook(path)
    except (InvalidFileException, zipfile.BadZipFile, KeyError, ValueError, OSError, TypeError,
            AttributeError, IndexError, EOFError, SyntaxError, zlib.error, RecursionError) as exc:
        # SyntaxError: xml.etree's ParseError on the junk XML of a damaged zip
        raise InputError(f"{path} is not a readable .xlsx workbook ({exc}); "
                         "it was left untouched") from exc
    if MEASUREMENTS_SHEET not in wb.sheetnames:
        raise InputError(f"{path} is not a measurement workbook of stereo-gui (no "
                         f"{MEASUREMENTS_SHEET!r} sheet); it was left untouched")
    ws = wb[MEASUREMENTS_SHEET]
    header = tuple(c.value for c in next(ws.iter_rows(min_row=1, max_row=1)))
    # workbooks written before the time became a date-time cell head it "Time (ISO 8601)"
    n = len(HEADERS)  # the error columns after them are derived; older workbooks lack them
    if header[:n] not in (XLSX_HEADERS[:n], HEADERS):
        raise InputError(f"{path}: the {MEASUREMENTS_SHEET!r} sheet does not have the columns "
                         "stereo-gui writes; it was left untouched")
    return wb


def read_measurements(path: str | os.PathLike[str]) -> list[MeasurementRecord]:
    """The measurement log of a workbook written by `write_workbook` / `append_measurements`."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such workbook")
    return _records_in(_load_ours(path), f"{path}, ")


def append_measurements(path: str | os.PathLike[str], records: Iterable[MeasurementRecord],
                        fits: Sequence[FitResult] | None = None,
                        calibration: StereoCalibration | None = None,
                        calibration_file: str | os.PathLike[str] | None = None) -> int:
    """Append `records` to the workbook at `path`, keeping every earlier row; return the count.

    The workbook is created if missing. `fits` / `calibration`, when given, replace the
    Regression / Calibration sheets; otherwise those sheets stay as they are (a new workbook gets
    samples from the records' true distances). A file that is not a workbook of ours raises
    InputError and is not touched.
    """
    path = Path(path)
    _check_xlsx_name(path)
    records = list(records)
    if not path.exists():
        write_workbook(path, records, fits or (), calibration, calibration_file)
        return len(records)
    wb = _load_ours(path)
    for col, text in enumerate(XLSX_HEADERS, start=1):  # (older workbooks lack the last ones)
        cell = wb[MEASUREMENTS_SHEET].cell(row=1, column=col)
        cell.value = text
        cell.font = bold_font()
    n = append_measurement_rows(wb[MEASUREMENTS_SHEET], records)
    cf = None if calibration_file is None else str(calibration_file)
    if fits is not None:
        all_records = _records_in(wb)
        _replace_sheet(wb, REGRESSION_SHEET, 1,
                       lambda ws: write_regression_sheet(
                           ws, regression_samples(all_records, tuple(fits)), tuple(fits)))
    if calibration is not None:
        _replace_sheet(wb, CALIBRATION_SHEET, 2,
                       lambda ws: write_calibration_sheet(ws, calibration, cf))
    _save(wb, path)
    log.info("appended %d measurements to %s", n, path)
    return n


def _records_in(wb: Workbook, where: str = "") -> list[MeasurementRecord]:
    ws = wb[MEASUREMENTS_SHEET]
    return [record_from_row(row, f"{where}row {i}")
            for i, row in enumerate(ws.iter_rows(min_row=2, values_only=True), start=2)
            if row and any(v is not None for v in row)]


def _replace_sheet(wb: Workbook, title: str, index: int, fill: Callable[[Sheet], None]) -> None:
    if title in wb.sheetnames:
        index = wb.sheetnames.index(title)
        wb.remove(wb[title])
    fill(wb.create_sheet(title, index))
