"""`stereo-gui disparity`: write the disparity map of a stereo pair (colour view and exports).

Also holds the small helpers the measuring commands share: loading a calibration, a pair of
images, and a preset, each failing with one clear line (InputError / CalibrationFileError).
"""

from __future__ import annotations

import argparse
import logging
from collections.abc import Iterable
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.colouring import color_scale_caption
from stereo_gui.core.errors import InputError
from stereo_gui.core.matching import PipelineResult
from stereo_gui.core.preset import Preset
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files import depth_export
from stereo_gui.files.any_calibration import load_any_calibration
from stereo_gui.files.atomic import AtomicItem, StrPath, encode_image, write_many_atomic
from stereo_gui.files.images import read_image_file
from stereo_gui.files.presets import load_preset
from stereo_gui.pipeline.concurrency import preset_pipeline

log = logging.getLogger(__name__)


# ---- shared helpers ------------------------------------------------------------------------
CALIB_HELP = ("calibration: our file, an OpenCV stereo calibration (one YAML/XML file with "
              "M1 D1 M2 D2 R T, or its intrinsics.yml + extrinsics.yml), a ROS left.yaml or "
              "right.yaml, a Kalibr camchain.yaml, a EuRoC cam0/sensor.yaml, a Middlebury "
              "calib.txt, or rectified:F,B[,DOFFS] for a pair that is "
              "already rectified (focal px, baseline mm, cx_right - cx_left px)")


def load_calibration(spec: str, left_image: str | None = None) -> StereoCalibration:
    """The calibration `spec` names (see CALIB_HELP); a file without an image size, and
    `rectified:F,B[,DOFFS]`, take the size of `left_image`."""
    def size() -> tuple[int, int] | None:
        if left_image is None:
            return None
        img = read_image(left_image, "left")
        return img.shape[1], img.shape[0]

    loaded = load_any_calibration(spec, size)
    if loaded.kind != "stereo-gui":
        log.info("calibration: %s", loaded.description)
    return loaded.calibration


def read_image(path: str, what: str) -> np.ndarray:
    """The image `path` (BGR); InputError naming it as the `what` image (too large files and
    headers are refused before decoding: files.images)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{what} image {path} does not exist")
    return read_image_file(p, cv2.IMREAD_COLOR, name=f"{what} image {path}")


# smaller images hold nothing to match (below a few pixels OpenCV's matchers fail with their
# own assertions); the simulated rig's smallest frame, as `bench --size` allows
MIN_IMAGE_SIZE = (64, 48)


def read_pair(left: str, right: str, calibration: StereoCalibration) -> tuple[np.ndarray, np.ndarray]:
    """Both images, checked against the calibration's image size."""
    w, h = calibration.image_size
    out = []
    for path, what in ((left, "left"), (right, "right")):
        img = read_image(path, what)
        if img.shape[1] < MIN_IMAGE_SIZE[0] or img.shape[0] < MIN_IMAGE_SIZE[1]:
            raise InputError(f"{what} image {path} is {img.shape[1]}x{img.shape[0]} px: too small "
                             f"to match (at least {MIN_IMAGE_SIZE[0]}x{MIN_IMAGE_SIZE[1]} px)")
        if (img.shape[1], img.shape[0]) != (w, h):
            raise InputError(f"{what} image {path} is {img.shape[1]}x{img.shape[0]} but the "
                             f"calibration is for {w}x{h}")
        out.append(img)
    return out[0], out[1]


def load_params(name: str) -> Preset:
    return load_preset(name)


def run_pipeline(args: argparse.Namespace) -> tuple[StereoCalibration, PipelineResult]:
    """Calibration, images and preset from the common options, and the processed frame."""
    calib = load_calibration(args.calib, args.left)
    params = load_params(args.preset)
    left, right = read_pair(args.left, args.right, calib)
    with preset_pipeline(calib, params) as pipe:
        # a calibration made with the cameras found swapped takes its images exchanged
        return calib, pipe.process(*calib.ordered(left, right))


def add_pair_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--calib", required=True, metavar="C", help=CALIB_HELP)
    parser.add_argument("left", metavar="LEFT", help="left raw camera image")
    parser.add_argument("right", metavar="RIGHT", help="right raw camera image")
    parser.add_argument("--preset", default="live", metavar="P",
                        help="matcher preset: seed, live (default), quality, a user preset or a .json file")


# ---- the command ---------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_pair_arguments(parser)
    parser.add_argument("-o", "--output", required=True, metavar="OUT.png",
                        help="colourised disparity view (what the live view shows)")
    parser.add_argument("--npy", metavar="OUT.npy",
                        help="the preset's final disparity as float32 px, NaN where invalid")
    parser.add_argument("--png16", metavar="OUT.png",
                        help="the final disparity as 16-bit PNG, x16 fixed point, 0 = invalid")
    parser.add_argument("--depth-png", metavar="OUT.png",
                        help="depth Z in millimetres as 16-bit PNG, 0 = invalid")
    parser.add_argument("--ply", metavar="OUT.ply",
                        help="coloured point cloud of the valid pixels (binary PLY, mm)")


def check_outputs(outputs: Iterable[tuple[StrPath | None, str | None]],
                  inputs: Iterable[StrPath | None] = ()) -> None:
    """Every output path (path, required suffix or None) can be written, before any is: its
    folder exists, it is not a folder nor anything else but a regular file (a device, a FIFO),
    its suffix is right, no two are the same file, and none is one of the run's `inputs` (the
    same file, also through a link)."""
    seen: set[Path] = set()
    read = {_same_file_key(Path(i)) for i in inputs if i and Path(i).exists()}
    for path, suffix in outputs:
        if path is None:
            continue
        if not str(path):
            raise InputError("an output's name is empty (nothing was written)")
        p = Path(path)
        folder = p.parent if str(p.parent) else Path(".")
        if not folder.is_dir():
            raise InputError(f"cannot write {p}: folder {folder} does not exist (nothing was "
                             "written)")
        if p.is_dir():
            raise InputError(f"cannot write {p}: it is a folder (nothing was written)")
        if p.exists() and not p.is_file():
            raise InputError(f"cannot write {p}: it is not a regular file (a device or a pipe; "
                             "nothing was written)")
        if suffix and p.suffix.lower() != suffix:
            raise InputError(f"{p}: this output must be a {suffix} file (nothing was written)")
        if p.exists() and _same_file_key(p) in read:
            raise InputError(f"{p} is an input of this command: writing it would destroy it "
                             "(nothing was written)")
        key = p.resolve()
        if key in seen:
            raise InputError(f"{p} is given for two outputs (nothing was written)")
        seen.add(key)


def _same_file_key(p: Path) -> tuple[int, int]:
    """What two names of one file share (hard and symbolic links included)."""
    st = p.stat()
    return st.st_dev, st.st_ino


def run(args: argparse.Namespace) -> int:
    if Path(args.output).suffix.lower() not in (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"):
        raise InputError(f"{args.output}: the colour view needs an image suffix such as .png")
    check_outputs([(args.output, None), (args.npy, ".npy"), (args.png16, ".png"),
                   (args.depth_png, ".png"), (args.ply, ".ply")],
                  inputs=(args.left, args.right, args.calib))
    calib, result = run_pipeline(args)
    d = result.final_px
    items: list[AtomicItem] = [(args.output, encode_image(args.output, result.color_bgr), None)]
    written = [args.output]
    if args.npy:
        items.append(depth_export.disparity_npy_item(args.npy, d))
        written.append(args.npy)
    if args.png16:
        items.append(depth_export.disparity_png16_item(args.png16, d))
        written.append(args.png16)
    if args.depth_png:
        items.append(depth_export.depth_png16_item(args.depth_png, d, calib))
        written.append(args.depth_png)
    if args.ply:
        item, n = depth_export.ply_item(args.ply, d, result.rectified_left, calib)
        items.append(item)
        written.append(f"{args.ply} ({n} points)")
    # all the outputs, or none: half old and half new outputs would not belong together
    write_many_atomic(items, what="the set of outputs" if len(items) > 1 else None)
    valid = float(result.valid.mean()) * 100.0
    lo, hi = result.disparity_range_px
    colours = ("" if result.color_scale is None or not calib.metric
               else f"; {color_scale_caption(result.color_scale)}")
    print(f"preset {result.preset.name}: {valid:.1f}% valid, disparity range {lo:.0f}..{hi:.0f} px"
          f"{colours}; wrote {', '.join(written)}")
    return 0
