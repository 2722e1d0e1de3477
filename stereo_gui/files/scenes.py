"""Rectified stereo scenes with ground-truth disparity, listed in a scene file (the format of
`../shared/data/scenes.tsv`): one scene a line, tab-separated

    name  left  right  ground_truth  divide_by  [calib  [mask]]

paths relative to the list's folder; `#` starts a comment line. The optional sixth field is the
scene's metric calibration (what `--calib` takes: a Middlebury calib.txt, one of our files, or
rectified:F,B[,DOFFS]; `-` for none), the seventh a mask of the pixels both cameras see (255 seen,
anything else occluded; `-` for none). Without them a `calib.txt` and a `mask0nocc.png` beside the
left image are used where they exist (Middlebury 2014's layout). The ground truth is a PFM file
(float pixels, bottom row first, inf = unknown: Middlebury 2014) or an integer image (PNG, PGM)
holding disparity x `divide_by`, 0 = unknown (Middlebury 2001-2006, KITTI). Truth is handed out
as float32 px with 0 where unknown.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.files.atomic import os_error_text
from stereo_gui.files.images import read_image_file
from stereo_gui.files.readers import read_user_text

MAX_LIST_BYTES = 1 << 20  # a list of scenes, not a data set
MAX_PFM_SIDE = 30_000


@dataclass(frozen=True)
class SceneSpec:
    """One line of a scene list: paths resolved against the list's folder."""

    name: str
    left: Path
    right: Path
    truth: Path
    divide_by: float
    calib: str | None = None  # a --calib spec (a path resolved against the list's folder)
    mask: Path | None = None  # pixels both cameras see: 255


@dataclass(frozen=True, eq=False)
class Scene:
    """A loaded scene: BGR uint8 images and the left view's true disparity (float32 px, 0 where
    unknown), all of one size."""

    name: str
    left: np.ndarray
    right: np.ndarray
    truth_px: np.ndarray

    @property
    def size(self) -> tuple[int, int]:
        return self.left.shape[1], self.left.shape[0]


def read_scene_list(path: str | os.PathLike[str]) -> list[SceneSpec]:
    """The scenes of a list file; InputError with the file and line for anything malformed."""
    path = Path(path)
    try:
        text = read_user_text(path, "scene list", MAX_LIST_BYTES)
    except UnicodeDecodeError:
        raise InputError(f"scene list {path} is not UTF-8 text") from None
    folder = path.parent
    out = []
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = line.rstrip("\r\n").split("\t")
        if not 5 <= len(fields) <= 7:
            raise InputError(f"{path}, line {number}: expected 5 to 7 tab-separated fields "
                             f"(name, left, right, ground truth, divide by[, calibration[, "
                             f"mask]]), found {len(fields)}")
        name, left, right, truth, div = (f.strip() for f in fields[:5])
        extra = [f.strip() for f in fields[5:]] + ["", ""]
        calib = (None if extra[0] == "-" else _calib_spec(folder, extra[0])
                 or _beside(folder / left, "calib.txt"))
        mask = (None if extra[1] == "-" else folder / extra[1] if extra[1]
                else _beside(folder / left, "mask0nocc.png"))
        try:
            divide_by = float(div)
        except ValueError:
            divide_by = float("nan")
        if not (np.isfinite(divide_by) and divide_by > 0):
            raise InputError(f"{path}, line {number}: divide_by must be a positive number, "
                             f"not {div!r}")
        out.append(SceneSpec(name, folder / left, folder / right, folder / truth, divide_by,
                             None if calib is None else str(calib), mask))
    if not out:
        raise InputError(f"scene list {path} names no scene")
    return out


def _calib_spec(folder: Path, text: str) -> str | None:
    """A list's calibration field: `rectified:...` as it is, a path against the list's folder."""
    if not text:
        return None
    return text if text.startswith("rectified:") else str(folder / text)


def _beside(image: Path, name: str) -> Path | None:
    """The file `name` in the folder of `image`, if there is one."""
    candidate = image.parent / name
    return candidate if candidate.is_file() else None


def read_pfm(path: str | os.PathLike[str]) -> np.ndarray:
    """A single-channel PFM image as float32, top row first (PFM stores the bottom row first;
    a negative scale means little-endian)."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            kind = fh.readline().strip()
            dims = fh.readline().split()
            scale = float(fh.readline().strip())
            if kind not in (b"Pf", b"PF") or len(dims) != 2:
                raise ValueError("not a PFM header")
            w, h = int(dims[0]), int(dims[1])
            channels = 3 if kind == b"PF" else 1
            if not (0 < w <= MAX_PFM_SIDE and 0 < h <= MAX_PFM_SIDE) or scale == 0:
                raise ValueError(f"size {w}x{h}, scale {scale}")
            data = np.fromfile(fh, "<f4" if scale < 0 else ">f4", w * h * channels)
    except OSError as exc:
        raise InputError(f"cannot read {path}: {os_error_text(exc)}") from None
    except ValueError as exc:
        raise InputError(f"{path} is not a PFM image ({exc})") from None
    if data.size != w * h * channels:
        raise InputError(f"{path} is cut short: {data.size} of {w * h * channels} values")
    image = data.reshape(h, w, channels)[..., 0] if channels == 3 else data.reshape(h, w)
    return np.ascontiguousarray(image[::-1]).astype(np.float32)


def read_truth(path: str | os.PathLike[str], divide_by: float) -> np.ndarray:
    """Ground-truth disparity in float32 px, 0 where unknown (PFM: inf or NaN; images: 0)."""
    path = Path(path)
    if path.suffix.lower() == ".pfm":
        truth = read_pfm(path) / np.float32(divide_by)
        truth[~np.isfinite(truth) | (truth < 0)] = 0.0
        return truth
    raw = _imread(path, cv2.IMREAD_UNCHANGED, "ground truth")
    if raw.ndim == 3:
        raw = raw[..., 0]
    return raw.astype(np.float32) / np.float32(divide_by)


def read_seen_mask(spec: SceneSpec) -> np.ndarray | None:
    """The scene's mask of pixels both cameras see (bool, the images' size), None without one."""
    if spec.mask is None:
        return None
    raw = _imread(spec.mask, cv2.IMREAD_GRAYSCALE, f"{spec.name}: mask")
    seen: np.ndarray = raw == 255
    return seen


def load_scene(spec: SceneSpec) -> Scene:
    """Both images and the truth of a scene, checked to be of one size."""
    left = _imread(spec.left, cv2.IMREAD_COLOR, f"{spec.name}: left image")
    right = _imread(spec.right, cv2.IMREAD_COLOR, f"{spec.name}: right image")
    truth = read_truth(spec.truth, spec.divide_by)
    shapes = {left.shape[:2], right.shape[:2], truth.shape[:2]}
    if len(shapes) != 1:
        raise InputError(f"scene {spec.name}: the left image, the right image and the ground "
                         f"truth differ in size ({left.shape[1]}x{left.shape[0]}, "
                         f"{right.shape[1]}x{right.shape[0]}, {truth.shape[1]}x{truth.shape[0]})")
    if not (truth > 0).any():
        raise InputError(f"scene {spec.name}: its ground truth {spec.truth} knows no pixel")
    return Scene(spec.name, left, right, truth)


def _imread(path: Path, flags: int, what: str) -> np.ndarray:
    return read_image_file(path, flags, name=f"{what} {path}")
