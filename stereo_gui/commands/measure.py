"""`stereo-gui measure`: distances at pixels of the rectified left image of a raw stereo pair."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from stereo_gui.commands import options
from stereo_gui.commands.disparity import add_pair_arguments, run_pipeline
from stereo_gui.core.errors import InputError
from stereo_gui.core.measure import PATCH_PX, Measurement, measure_point
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.fit_file import load_fit
from stereo_gui.files.measurement_record import MeasurementRecord
from stereo_gui.files.spreadsheet import append_measurements

MAX_PATCH_PX = 101  # as the window's own patch setting: wider patches straddle surfaces
MAX_POINTS = 10_000


def _point(text: str) -> tuple[float, float]:
    try:
        xs, ys = text.split(",")
        return float(xs), float(ys)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y in pixels, e.g. 320,240 (not {text!r})") from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_pair_arguments(parser)
    parser.add_argument("--at", action="append", type=_point, required=True, metavar="X,Y",
                        help="pixel of the rectified left image (repeat for more points)")
    parser.add_argument("--patch", type=options.whole(1, MAX_PATCH_PX), default=PATCH_PX,
                        metavar="N", help=f"side of the square patch around each point, px "
                        f"(default {PATCH_PX}, at most {MAX_PATCH_PX})")
    parser.add_argument("--model", metavar="FIT",
                        help="a regression fit (JSON) to use instead of triangulation")
    parser.add_argument("--mode", choices=("point", "object"), default="point",
                        help="point: median of the patch; object: most frequent disparity of the "
                        "surface around the point")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--xlsx", metavar="FILE",
                        help="append the measurements to this workbook (.xlsx; created if missing, "
                        "earlier rows kept)")
    # further outputs add their options here and a branch in write_outputs()


def measure_all(args: argparse.Namespace) -> tuple[StereoCalibration, list[Measurement]]:
    """Run the pipeline once and measure every --at point; returns (calibration, measurements)."""
    if args.patch < 1:
        raise InputError(f"--patch must be at least 1, not {args.patch}")
    if len(args.at) > MAX_POINTS:
        raise InputError(f"{len(args.at)} --at points: give at most {MAX_POINTS} at a time")
    fit = None
    if args.model:
        fit = load_fit(args.model)
    calib, result = run_pipeline(args)
    w, h = result.size
    for x, y in args.at:
        if not (0 <= x <= w - 1 and 0 <= y <= h - 1):
            raise InputError(f"point {x:g},{y:g} is outside the {w}x{h} image")
    out = [measure_point(result, x, y, patch=args.patch, mode=args.mode, fit=fit)
           for x, y in args.at]
    return calib, out


def format_line(m: Measurement) -> str:
    where = f"{m.x:g},{m.y:g}"
    if not m.valid:
        return f"{where}: no distance ({m.reason})"
    return (f"{where}: Z = {m.Z_mm:.1f} mm +- {m.expected_error_mm:.1f}, range {m.range_mm:.1f} mm, "
            f"X = {m.X_mm:.1f} Y = {m.Y_mm:.1f} mm, disparity {m.disparity_px:.3f} px, "
            f"{100 * m.valid_fraction:.0f}% valid, {m.method}")


def write_outputs(args: argparse.Namespace, calib: StereoCalibration,
                  measurements: list[Measurement]) -> None:
    """Print the results (text or JSON); further output files hook in here."""
    if args.xlsx:  # first: a refused workbook then fails the command before anything is printed
        calib_file = (args.calib if args.calib.startswith("rectified:")
                      else str(Path(args.calib).resolve()))
        records = [MeasurementRecord.from_measurement(m, calibration_file=calib_file,
                                                      calibration_rms_px=calib.rms_stereo)
                   for m in measurements]
        append_measurements(args.xlsx, records, calibration=calib, calibration_file=calib_file)
    if args.json:
        print(json.dumps({"points": [m.to_json_dict() for m in measurements]}, indent=2))
    else:
        for m in measurements:
            print(format_line(m))


def run(args: argparse.Namespace) -> int:
    calib, measurements = measure_all(args)
    write_outputs(args, calib, measurements)
    return 0
