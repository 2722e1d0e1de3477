"""`stereo-gui simulate OUT_DIR [--pairs N] [--scene] [--seed S] [--target T --board CxR ...]
[--lens pinhole|fisheye]`: write images of the simulated rig (a calibration set named as a
capture session names it, optional scene pairs) with its truth.json.

`stereo-gui simulate OUT_DIR --click-scenes [--seed S] [--seeds N] [--lens ...]`: instead, the
rectified scenes with true disparity that `bench --clicks` reads (sources/sim/click_scenes.py),
listed in OUT_DIR/clicks.tsv."""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from pathlib import Path

from stereo_gui.commands import options
from stereo_gui.core.board import TARGETS, BoardSpec, parse_board
from stereo_gui.core.errors import InputError
from stereo_gui.sources.sim import (
    SCENE_FOLDER,
    RigConfig,
    SimRig,
    calibration_set_names,
    write_calibration_set,
)
from stereo_gui.sources.sim.click_scenes import (
    CLICK_CONDITIONS,
    CLICK_FOLDER,
    CLICK_LIST,
    CLICK_WALLS_MM,
    MAX_CLICK_SEEDS,
    click_scene_names,
    rectified_spec,
    write_click_scenes,
)

# files of an earlier simulated set: replaced or removed with --overwrite
_OWN_NAMES = re.compile(r"^(chessboard-[LR]\d+|scenes/scene-[LR]\d+)\.png$|^truth\.json$")
# files of earlier click scenes: replaced or removed with --overwrite
_CLICK_NAMES = re.compile(r"^click-scenes/s\d+-[a-z]+-(wall[0-9.]+m|demo)"
                          r"-(L\.png|R\.png|truth\.pfm|mask\.png)$|^clicks\.tsv$")
DEFAULT_PAIRS = 20
DEFAULT_SEEDS = 3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("out_dir", metavar="OUT_DIR", help="folder to write (created if missing)")
    parser.add_argument("--pairs", type=options.whole(1, options.MAX_PAIRS), default=None,
                        metavar="N",
                        help=f"number of chessboard pairs (default {DEFAULT_PAIRS})")
    parser.add_argument("--scene", action="store_true",
                        help="also write scene pairs: walls at 0.5, 1, 1.5, 2, 3 m and the demo scene")
    parser.add_argument("--seed", type=options.seed, default=0, metavar="S",
                        help="random seed of the board poses and noise (default 0); with "
                             "--click-scenes the first seed")
    parser.add_argument("--click-scenes", action="store_true",
                        help="write, instead of a calibration set, rectified scenes with their "
                             "true disparity (PFM), a mask of the pixels both cameras see and "
                             "clicks.tsv listing them for `bench --clicks`: walls at 0.5, 1, 2, "
                             "3 m and the demo scene under the conditions rig, quarter and webcams")
    parser.add_argument("--seeds", type=options.whole(1, MAX_CLICK_SEEDS), default=None,
                        metavar="N",
                        help=f"with --click-scenes: how many seeds, S to S+N-1 (default "
                             f"{DEFAULT_SEEDS})")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace a simulated set already in OUT_DIR")
    parser.add_argument("--target", choices=TARGETS, default=None,
                        help="the target the rig shows (default chessboard)")
    parser.add_argument("--board", default=None,
                        help="COLSxROWS as `calibrate --board` counts them (default 9x6, 7x5 for "
                             "charuco)")
    parser.add_argument("--square-mm", type=options.declared(BoardSpec, "square_mm"), default=None,
                        help="square side or circle spacing, mm (default 25, 30 for charuco)")
    parser.add_argument("--marker-mm", type=options.declared(BoardSpec, "marker_mm"), default=None,
                        help="ChArUco marker side or circle diameter, mm (default: the target's)")
    parser.add_argument("--lens", choices=("pinhole", "fisheye"), default="pinhole",
                        help="the rig's cameras: webcams (default) or wide-angle fisheye webcams")
    parser.add_argument("--time-offset", type=options.number(0.0, 0.5, "s"), default=0.0,
                        metavar="S",
                        help="the right camera grabs S seconds after the left (two webcams that "
                             "are not synchronised), and the board, held by hand, moves between "
                             "the two grabs (about 100 mm/s and 10 deg/s; default 0: "
                             "synchronised, the board still)")


def _prepare(out: Path, overwrite: bool, own: re.Pattern[str] = _OWN_NAMES,
             folder: str = SCENE_FOLDER) -> list[Path]:
    """Check OUT_DIR (create it); return earlier simulated files (named as `own` matches, in
    OUT_DIR and its subfolder `folder`) that --overwrite will remove."""
    if out.exists() and not out.is_dir():
        raise InputError(f"{out} is a file, not a folder: give a folder to write the images into")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create folder {out}: {exc.strerror or exc}") from exc
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"cannot write into folder {out}: permission denied")
    scenes = out / folder
    candidates = list(out.iterdir()) + (list(scenes.iterdir()) if scenes.is_dir() else [])
    earlier = sorted(p for p in candidates if own.match(p.relative_to(out).as_posix()))
    if earlier and not overwrite:
        raise InputError(f"{out} already holds a simulated set ({earlier[0].name}, ...): "
                         "choose an empty folder or add --overwrite")
    return earlier


def run(args: argparse.Namespace) -> int:
    if not args.out_dir.strip():
        raise InputError("OUT_DIR is empty: give the folder to write (nothing was written)")
    if args.click_scenes:
        return _run_click_scenes(args)
    if args.seeds is not None:
        raise InputError("--seeds goes with --click-scenes (a calibration set has one --seed)")
    args.pairs = DEFAULT_PAIRS if args.pairs is None else args.pairs
    args.target = args.target or "chessboard"
    charuco = args.target == "charuco"
    # an explicit 0 is refused as a square size, not taken for the default
    square_mm = (30.0 if charuco else 25.0) if args.square_mm is None else args.square_mm
    board = parse_board(args.board or ("7x5" if charuco else "9x6"), square_mm, args.target,
                        args.marker_mm or (22.0 if charuco else 0.0))
    timing = {"time_offset_s": args.time_offset}
    config = (RigConfig.fisheye(board=board, **timing) if args.lens == "fisheye"
              else RigConfig(board=board, **timing))
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
          f"{truth.baseline_mm:.1f} mm, {truth.model} lenses, seed {args.seed}"
          + (f"; the right camera {1000 * args.time_offset:g} ms late, the board moving"
             if args.time_offset else ""))
    return 0


def _run_click_scenes(args: argparse.Namespace) -> int:
    """`simulate OUT_DIR --click-scenes`: the rectified scenes with true disparity and
    clicks.tsv (sources/sim/click_scenes.py)."""
    given = [name for name, value in (("--pairs", args.pairs), ("--scene", args.scene or None),
                                      ("--target", args.target), ("--board", args.board),
                                      ("--square-mm", args.square_mm),
                                      ("--marker-mm", args.marker_mm),
                                      ("--time-offset", args.time_offset or None))
             if value is not None]
    if given:
        raise InputError(f"{given[0]} does not go with --click-scenes (it writes scenes, not a "
                         "calibration set): leave it out, or run simulate twice")
    n = DEFAULT_SEEDS if args.seeds is None else args.seeds
    if args.seed + n - 1 > options.SEED_MAX:
        raise InputError(f"--seed {args.seed} with --seeds {n} passes the largest seed, "
                         f"{options.SEED_MAX}")
    seeds = list(range(args.seed, args.seed + n))
    config = RigConfig.fisheye() if args.lens == "fisheye" else RigConfig()
    out = Path(args.out_dir)
    earlier = _prepare(out, args.overwrite, _CLICK_NAMES, CLICK_FOLDER)
    interactive = sys.stderr.isatty()

    def progress(done: int, total_: int) -> None:
        if interactive:
            sys.stderr.write(f"\rrendering scene {done}/{total_}")
            sys.stderr.flush()

    started = time.perf_counter()
    try:
        scenes = write_click_scenes(out, seeds, config=config, progress=progress,
                                    what=f"the new click scenes in {out}")
    finally:
        if interactive:
            sys.stderr.write("\n")
    seconds = time.perf_counter() - started
    # fewer seeds over an earlier run would leave scenes that clicks.tsv does not list
    keep = set(click_scene_names(seeds))
    stale = [p for p in earlier if p.relative_to(out).as_posix() not in keep]
    for p in stale:
        p.unlink(missing_ok=True)

    seed_text = f"seed {seeds[0]}" if n == 1 else f"seeds {seeds[0]}..{seeds[-1]}"
    walls = ", ".join(f"{z:g}" for z in CLICK_WALLS_MM)
    print(f"wrote {len(scenes)} click scenes to {out / CLICK_FOLDER} in {seconds:.1f} s "
          f"({seed_text}; each: walls at {walls} mm and the demo scene under "
          f"{', '.join(CLICK_CONDITIONS)}): rectified NAME-L.png/NAME-R.png, true disparity "
          "NAME-truth.pfm, NAME-mask.png (255 where both cameras see)")
    if stale:
        print(f"removed {len(stale)} files of earlier click scenes")
    calib = SimRig(config, seed=seeds[0]).true_calibration(alpha=0.0)
    print(f"wrote {out / CLICK_LIST}: {len(scenes)} scenes, calibration {rectified_spec(calib)} "
          f"(the rig's true calibration, alpha 0, {args.lens} lenses)")
    return 0
