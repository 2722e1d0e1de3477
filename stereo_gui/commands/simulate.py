"""`stereo-gui simulate OUT_DIR [--pairs N] [--scene] [--seed S] [--target T --board CxR ...]
[--lens pinhole|fisheye]`: write images of the simulated rig (a calibration set named as a
capture session names it, optional scene pairs) with its truth.json."""

from __future__ import annotations

import argparse
import os
import re
import sys
from pathlib import Path


from stereo_gui.commands import options
from stereo_gui.core.board import TARGETS, parse_board
from stereo_gui.core.errors import InputError
from stereo_gui.sources.sim import (SCENE_FOLDER, RigConfig, SimRig, calibration_set_names,
                                    write_calibration_set)

# files of an earlier simulated set: replaced or removed with --overwrite
_OWN_NAMES = re.compile(r"^(chessboard-[LR]\d+|scenes/scene-[LR]\d+)\.png$|^truth\.json$")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("out_dir", metavar="OUT_DIR", help="folder to write (created if missing)")
    parser.add_argument("--pairs", type=int, default=20, metavar="N",
                        help="number of chessboard pairs (default 20)")
    parser.add_argument("--scene", action="store_true",
                        help="also write scene pairs: walls at 0.5, 1, 1.5, 2, 3 m and the demo scene")
    parser.add_argument("--seed", type=options.seed, default=0, metavar="S",
                        help="random seed of the board poses and noise (default 0)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace a simulated set already in OUT_DIR")
    parser.add_argument("--target", choices=TARGETS, default="chessboard",
                        help="the target the rig shows (default chessboard)")
    parser.add_argument("--board", default=None,
                        help="COLSxROWS as `calibrate --board` counts them (default 9x6, 7x5 for "
                             "charuco)")
    parser.add_argument("--square-mm", type=float, default=None,
                        help="square side or circle spacing, mm (default 25, 30 for charuco)")
    parser.add_argument("--marker-mm", type=float, default=0.0,
                        help="ChArUco marker side or circle diameter, mm (default: the target's)")
    parser.add_argument("--lens", choices=("pinhole", "fisheye"), default="pinhole",
                        help="the rig's cameras: webcams (default) or wide-angle fisheye webcams")


def _prepare(out: Path, overwrite: bool) -> list[Path]:
    """Check OUT_DIR (create it); return earlier simulated files that --overwrite will remove."""
    if out.exists() and not out.is_dir():
        raise InputError(f"{out} is a file, not a folder: give a folder to write the images into")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create folder {out}: {exc.strerror or exc}") from exc
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"cannot write into folder {out}: permission denied")
    scenes = out / SCENE_FOLDER
    candidates = list(out.iterdir()) + (list(scenes.iterdir()) if scenes.is_dir() else [])
    earlier = sorted(p for p in candidates if _OWN_NAMES.match(p.relative_to(out).as_posix()))
    if earlier and not overwrite:
        raise InputError(f"{out} already holds a simulated set ({earlier[0].name}, ...): "
                         "choose an empty folder or add --overwrite")
    return earlier


def run(args: argparse.Namespace) -> int:
    if args.pairs < 1:
        raise InputError(f"--pairs must be at least 1, not {args.pairs}")
    if args.pairs > 10000:
        raise InputError(f"--pairs {args.pairs} is more than anyone needs; give at most 10000")
    charuco = args.target == "charuco"
    # an explicit 0 is refused as a square size, not taken for the default
    square_mm = (30.0 if charuco else 25.0) if args.square_mm is None else args.square_mm
    board = parse_board(args.board or ("7x5" if charuco else "9x6"), square_mm, args.target,
                        args.marker_mm or (22.0 if charuco else 0.0))
    config = (RigConfig.fisheye(board=board) if args.lens == "fisheye" else RigConfig(board=board))
    out = Path(args.out_dir)
    earlier = _prepare(out, args.overwrite)
    interactive = sys.stderr.isatty()

    def progress(done: int, total_: int) -> None:
        if interactive:
            sys.stderr.write(f"\rrendering {done}/{total_}")
            sys.stderr.flush()

    try:
        write_calibration_set(out, n_pairs=args.pairs, seed=args.seed, scene=args.scene,
                              config=config, progress=progress,
                              what=f"the new simulated set in {out}")
    finally:
        if interactive:
            sys.stderr.write("\n")
    # a smaller set over an earlier larger one would leave pairs that truth.json does not describe
    keep = set(calibration_set_names(args.pairs, args.scene))
    stale = [p for p in earlier if p.relative_to(out).as_posix() not in keep]
    for p in stale:
        p.unlink(missing_ok=True)

    truth = SimRig(config, seed=args.seed).truth
    print(f"wrote {args.pairs} {args.target} pairs (chessboard-L1.png/chessboard-R1.png .. "
          f"chessboard-L{args.pairs}.png/chessboard-R{args.pairs}.png) to {out}")
    if args.scene:
        print(f"wrote 6 scene pairs to {out / SCENE_FOLDER} (scene-L1.png/scene-R1.png .. "
              "scene-L6.png/scene-R6.png): "
              "walls at 500, 1000, 1500, 2000, 3000 mm and the demo scene")
    if stale:
        print(f"removed {len(stale)} files of an earlier simulated set")
    print(f"wrote {out / 'truth.json'}: board {truth.board.label()}, image {truth.image_size[0]}x"
          f"{truth.image_size[1]}, fx {truth.M1[0, 0]:.1f}/{truth.M2[0, 0]:.1f} px, baseline "
          f"{truth.baseline_mm:.1f} mm, {truth.model} lenses, seed {args.seed}")
    return 0
