"""`stereo-gui target --type charuco --board 7x5 --square-mm 30 --marker-mm 22 -o board.pdf`.

Writes a printable calibration target at true scale (PDF, SVG or PNG by the file's suffix) with
its parameters and a 100 mm scale bar printed on the sheet; refuses a target that does not fit
the page.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from stereo_gui.commands import options
from stereo_gui.core.board import DEFAULT_DICTIONARY, DICTIONARIES, TARGETS, BoardSpec, parse_board
from stereo_gui.core.target_sheet import PAGES_MM, describe, layout
from stereo_gui.files.target_sheet import write_target


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--type", dest="target", choices=TARGETS, default="chessboard",
                   help="chessboard (default), circles, acircles (asymmetric circle grid) or "
                        "charuco")
    p.add_argument("--board", default=None,
                   help="COLSxROWS: inner corners of a chessboard (default 9x6), circles of a "
                        "circle grid, squares of a ChArUco board (default 7x5)")
    p.add_argument("--square-mm", type=options.declared(BoardSpec, "square_mm"), default=25.0,
                   help="side of a square, or the spacing of a circle grid, mm (default 25)")
    p.add_argument("--marker-mm", type=options.declared(BoardSpec, "marker_mm"), default=0.0,
                   help="ChArUco: marker side (default 0.75 x square); circle grids: circle "
                        "diameter (default 0.5 x spacing, 0.7 for acircles)")
    p.add_argument("--dict", default=DEFAULT_DICTIONARY, choices=DICTIONARIES, metavar="NAME",
                   help=f"ChArUco: the ArUco dictionary (default {DEFAULT_DICTIONARY})")
    p.add_argument("--page", default="a4",
                   help=f"paper: {', '.join(PAGES_MM)} or WIDTHxHEIGHT in mm (default a4)")
    p.add_argument("--dpi", type=options.number(50, 2400), default=300.0,
                   help="resolution of a PNG target, dots per inch (default 300)")
    p.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="the target to write: .pdf, .svg or .png")


def run(args: argparse.Namespace) -> int:
    board = parse_board(args.board or ("7x5" if args.target == "charuco" else "9x6"),
                        args.square_mm, args.target, args.marker_mm, args.dict)
    sheet = layout(board, args.page)
    path = write_target(sheet, Path(args.output), dpi=args.dpi)
    w, h = sheet.page_mm
    sys.stdout.write(f"wrote {path}: {describe(board)}, on {sheet.page_name} "
                     f"({w:g} x {h:g} mm); print it at 100 %\n")
    return 0
