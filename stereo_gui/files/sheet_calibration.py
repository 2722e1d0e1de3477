"""The Calibration sheet: the figures (RMS, baseline, board, date) and each camera's parameters,
each with its 1-sigma uncertainty, the warnings, the pairs it was not made from, each pair's
error, and the matrices M1 D1 M2 D2 R T P1 P2 Q as small tables. Printed landscape, one page
wide."""

from __future__ import annotations

from typing import Any

import numpy as np

from stereo_gui.core.lens import distortion_names
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.core.uncertainty import corner_sigma_px
from stereo_gui.files.sheet_columns import cell_value
from stereo_gui.files.sheet_draft import Sheet, SheetDraft

_MATRIX_NOTES = {
    "M1": "left camera matrix (px)",
    "D1": "left distortion (k1 k2 p1 p2 k3 ...)",
    "M2": "right camera matrix (px)",
    "D2": "right distortion (k1 k2 p1 p2 k3 ...)",
    "R": "rotation left to right camera",
    "T": "translation left to right camera (mm)",
    "P1": "left rectified projection (px)",
    "P2": "right rectified projection (px, mm)",
    "Q": "disparity-to-depth (mm)",
}
CALIBRATION_MATRICES = tuple(_MATRIX_NOTES)


def _calibration_figures(calib: StereoCalibration, calib_file: str | None
                         ) -> list[tuple[str, Any, str, float | None]]:
    """(label with unit, value, number format, 1 sigma or None) of the Calibration sheet."""
    u = calib.uncertainty
    board = calib.board
    return [
        ("File", calib_file or "", "@", None),
        ("Created", calib.created, "@", None),
        ("Made", calib.origin, "@", None),
        ("Method", calib.method, "@", None),
        ("Lens model", calib.model, "@", None),
        ("Image width (px)", calib.width, "0", None),
        ("Image height (px)", calib.height, "0", None),
        ("Board", board.label() if board else "", "@", None),
        ("Square (mm)", board.square_mm if board else None, "0.00", None),
        ("RMS left (px)", calib.rms_left, "0.0000", None),
        ("RMS right (px)", calib.rms_right, "0.0000", None),
        ("RMS stereo (px)", calib.rms_stereo, "0.0000", None),
        ("Epipolar error (px)", calib.epipolar_error_px, "0.0000", None),
        ("Baseline (mm)", calib.baseline_mm, "0.00",
         None if u is None else u.baseline_sigma_mm(calib.T)),
        ("Rectified baseline (mm)", calib.rectified_baseline_mm, "0.00", None),
        ("Rectified focal length (px)", calib.focal_px, "0.00", None),
        ("Relative rotation (deg)", calib.relative_rotation_deg, "0.000",
         None if u is None else u.rotation_sigma_deg(calib.R)),
        ("Alpha", calib.alpha, "0.00", None),
    ]


def _camera_rows(calib: StereoCalibration, side: str) -> list[tuple[str, float, float | None]]:
    """(name with unit, value, 1 sigma or None) of one camera's intrinsics and distortion."""
    M, D = (calib.M1, calib.D1) if side == "left" else (calib.M2, calib.D2)
    M, D = np.asarray(M, float), np.asarray(D, float).reshape(-1)
    u = calib.uncertainty
    rows: list[tuple[str, float, float | None]] = []
    for name, value in (("fx", M[0, 0]), ("fy", M[1, 1]), ("cx", M[0, 2]), ("cy", M[1, 2])):
        rows.append((f"{name} (px)", float(value),
                     None if u is None else u.sigma(f"{side}.{name}")))
    for name, value in zip(distortion_names(calib.model, D.size), D, strict=False):
        rows.append((name, float(value), None if u is None else u.distortion_sigma(side, name)))
    if u is not None:
        rows.append(("lens at the corners (px)", float("nan"), corner_sigma_px(calib, side)))
    return rows


def _figures_table(draft: SheetDraft, calib: StereoCalibration, calib_file: str | None) -> int:
    """From row 3: the figures, each with its 1 sigma where known; returns the row below."""
    for j, text in enumerate(("Figure", "Value", "± (1 sigma)")):
        draft.set(3, 1 + j, text, bold=True)
    row = 4
    for label, value, fmt, sigma in _calibration_figures(calib, calib_file):
        draft.set(row, 1, label, bold=True)
        draft.set(row, 2, cell_value(value), fmt, wrap=fmt == "@")
        if sigma is not None:
            draft.set(row, 3, cell_value(sigma), fmt)
        row += 1
    return row


def _camera_tables(draft: SheetDraft, calib: StereoCalibration, row: int) -> int:
    """From `row`: each camera's parameters with their 1 sigma; returns the row below."""
    for side in ("left", "right"):
        draft.set(row, 1, f"{side.capitalize()} camera", bold=True)
        draft.set(row, 2, "Value", bold=True)
        draft.set(row, 3, "± (1 sigma)", bold=True)
        row += 1
        for name, value, sigma in _camera_rows(calib, side):
            draft.set(row, 1, name)
            draft.set(row, 2, cell_value(value), "0.000000" if abs(value) < 10 else "0.00")
            draft.set(row, 3, cell_value(sigma), "0.000000" if sigma is not None and sigma < 0.1
                      else "0.00")
            row += 1
        row += 1
    return row


def _notes(draft: SheetDraft, calib: StereoCalibration, row: int) -> int:
    """From `row`: the warnings, then the pairs left out and why; returns the row below."""
    draft.set(row, 1, "Warnings", bold=True)
    row += 1
    for w in calib.warnings or ():
        draft.set(row, 1, w.code)
        draft.set(row, 2, w.message, wrap=True)
        row += 1
    if not calib.warnings:
        draft.set(row, 1, "none")
        row += 1
    row += 1
    draft.set(row, 1, "Pairs left out", bold=True)
    draft.set(row, 2, "Why", bold=True)
    row += 1
    for name, why in calib.left_out:
        draft.set(row, 1, name)
        draft.set(row, 2, why, wrap=True)
        row += 1
    if not calib.left_out:
        draft.set(row, 1, "none")
        row += 1
    return row


def _pair_errors(draft: SheetDraft, calib: StereoCalibration, row: int) -> None:
    """From `row`: each pair's error, when the calibration has them."""
    if not calib.per_pair:
        return
    for j, text in enumerate(("Pair", "Error left (px)", "Error right (px)")):
        draft.set(row, 1 + j, text, bold=True)
    for k, pe in enumerate(calib.per_pair):
        draft.set(row + 1 + k, 1, pe.name)
        draft.set(row + 1 + k, 2, cell_value(pe.error_left), "0.0000")
        draft.set(row + 1 + k, 3, cell_value(pe.error_right), "0.0000")


def _matrices(draft: SheetDraft, calib: StereoCalibration) -> None:
    """The matrices stacked in columns E.., each under a bold label row."""
    col0 = 5
    r = 3
    for name, note in _MATRIX_NOTES.items():
        m = np.atleast_2d(calib.matrices()[name])
        draft.set(r, col0, name, bold=True)
        draft.set(r, col0 + 1, note)
        for i in range(m.shape[0]):
            for j in range(m.shape[1]):
                draft.set(r + 1 + i, col0 + j, cell_value(m[i, j]), "0.000000")
        r += m.shape[0] + 2
    for j in range(5):
        draft.widths[col0 + j] = 14


def write_calibration_sheet(ws: Sheet, calib: StereoCalibration | None,
                            calib_file: str | None) -> None:
    """The calibration in use: its figures, each camera's parameters, each with its 1-sigma
    uncertainty where the calibration has one, its warnings, the pairs it was not made from,
    each pair's error, and the matrices. Printed landscape, one page wide."""
    draft = SheetDraft()
    draft.print_one_page_wide = True
    draft.set(1, 1, "Calibration", bold=True)
    if calib is None:
        draft.set(3, 1, "no calibration given")
        draft.to_sheet(ws)
        return
    sigma_note = ("1 sigma: the true value lies within ± 1 sigma about two times in three"
                  if calib.uncertainty is not None else "no uncertainty recorded")
    draft.set(1, 2, sigma_note)
    row = _figures_table(draft, calib, calib_file) + 1
    row = _camera_tables(draft, calib, row)
    row = _notes(draft, calib, row) + 1
    _pair_errors(draft, calib, row)
    draft.widths[1] = 26
    draft.widths[2] = 44
    draft.widths[3] = 17  # wide enough for "Error right (px)"
    _matrices(draft, calib)
    draft.to_sheet(ws)
