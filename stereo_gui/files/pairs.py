"""Finding and loading the image pairs of a folder.

Three layouts are recognised (file names case-insensitive, any of png jpg jpeg bmp tif tiff, any
zero padding of the number):
- the original capture script's naming, which our sessions keep: `chessboard-L1.png` /
  `chessboard-R1.png` (any prefix, then L or R and a number);
- `left01.jpg` / `right01.jpg` (any prefix, then left or right and a number);
- `left/` and `right/` subfolders, paired by the (last) number in each file name.
Files that do not pair up are reported, never silently dropped.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.errors import InputError
from stereo_gui.files.images import read_image_file

log = logging.getLogger(__name__)

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")

_WORD_RE = re.compile(r"^(?P<prefix>.*?)(?P<side>left|right)[-_ ]?(?P<num>\d+)$", re.IGNORECASE)
_LETTER_RE = re.compile(r"^(?P<prefix>.*?)(?P<side>[LR])[-_ ]?(?P<num>\d+)$", re.IGNORECASE)
_NUM_RE = re.compile(r"(\d+)(?!.*\d)")


@dataclass(frozen=True)
class ImagePair:
    """A left and a right image file that belong together; `number` orders the pairs."""

    name: str
    number: int
    left: Path
    right: Path


@dataclass(frozen=True)
class UnpairedFile:
    path: Path
    reason: str  # e.g. "no right image 3"


@dataclass(frozen=True)
class PairDiscovery:
    """The pairs found in a folder (sorted by number) and the image files that did not pair."""

    folder: Path
    layout: str  # "names" (left/right or L/R in the file names) or "subfolders"
    pairs: tuple[ImagePair, ...]
    unpaired: tuple[UnpairedFile, ...]

    def warning(self, limit: int = 8) -> str | None:
        """A one-line message listing the unpaired files, or None when every image paired."""
        if not self.unpaired:
            return None
        return f"{len(self.unpaired)} unpaired image file(s) ignored: {_list_unpaired(self.unpaired, limit)}"


def _list_unpaired(unpaired: Sequence[UnpairedFile], limit: int = 8) -> str:
    shown = [f"{u.path.name} ({u.reason})" for u in unpaired[:limit]]
    more = len(unpaired) - len(shown)
    return ", ".join(shown) + (f" and {more} more" if more > 0 else "")


def _images_in(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir()
                  if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS and not p.name.startswith("."))


def _subfolder(folder: Path, name: str) -> Path | None:
    for p in folder.iterdir():
        if p.is_dir() and p.name.lower() == name:
            return p
    return None


# one side's images: (prefix, number) -> (number, number as written, prefix, path)
_SideMap = dict[tuple[str, int], tuple[int, str, str, Path]]


def _pair_up(left: _SideMap, right: _SideMap, unpaired: list[UnpairedFile]) -> list[ImagePair]:
    """Join {key: (number, numtext, prefix, path)} of both sides on their key."""
    pairs: list[ImagePair] = []
    for key in sorted(set(left) | set(right), key=lambda k: (k[1], k[0])):
        if key in left and key in right:
            n, text, prefix, lp = left[key]
            rp = right[key][3]
            name = f"{prefix}{text}" if prefix else text
            pairs.append(ImagePair(name, n, lp, rp))
        elif key in left:
            unpaired.append(UnpairedFile(left[key][3], f"no right image {key[1]}"))
        else:
            unpaired.append(UnpairedFile(right[key][3], f"no left image {key[1]}"))
    return pairs


def _add(side_map: _SideMap, key: tuple[str, int], value: tuple[int, str, str, Path],
         path: Path, unpaired: list[UnpairedFile]) -> None:
    if key in side_map:
        unpaired.append(UnpairedFile(path, f"same number as {side_map[key][3].name}"))
    else:
        side_map[key] = value


def discover_pairs(folder: str | Path) -> PairDiscovery:
    """Find the image pairs of `folder`; raise InputError when there are none (saying why)."""
    folder = Path(folder)
    if not folder.exists():
        raise InputError(f"folder {folder} does not exist")
    if not folder.is_dir():
        raise InputError(f"{folder} is not a folder")
    unpaired: list[UnpairedFile] = []
    left: _SideMap = {}
    right: _SideMap = {}
    lsub, rsub = _subfolder(folder, "left"), _subfolder(folder, "right")
    if lsub is not None and rsub is not None:
        layout = "subfolders"
        for side_map, sub in ((left, lsub), (right, rsub)):
            for p in _images_in(sub):
                m = _NUM_RE.search(p.stem)
                if not m:
                    unpaired.append(UnpairedFile(p, "no number in the file name"))
                    continue
                n = int(m.group(1))
                _add(side_map, ("", n), (n, m.group(1), "", p), p, unpaired)
        images = _images_in(lsub) + _images_in(rsub)
    else:
        layout = "names"
        images = _images_in(folder)
        for p in images:
            m = _WORD_RE.match(p.stem) or _LETTER_RE.match(p.stem)
            if not m:
                unpaired.append(UnpairedFile(p, "not named as a left or right image"))
                continue
            side = m.group("side").lower()[0]
            prefix = m.group("prefix")
            n = int(m.group("num"))
            target = left if side == "l" else right
            _add(target, (prefix.lower(), n), (n, m.group("num"), prefix, p), p, unpaired)
    pairs = _pair_up(left, right, unpaired)
    unpaired.sort(key=lambda u: str(u.path))
    if not images:
        where = f"{folder} (nor in its left/ and right/ subfolders)" if layout == "names" else \
            f"{lsub} and {rsub}"
        raise InputError(f"no images ({', '.join(e[1:] for e in IMAGE_EXTENSIONS)}) found in {where}")
    if not pairs:
        raise InputError(f"no image pairs in {folder}: {len(unpaired)} unpaired file(s): "
                         f"{_list_unpaired(unpaired)}; name them like left1/right1 or "
                         "chessboard-L1/chessboard-R1, or put them in left/ and right/ subfolders")
    pairs.sort(key=lambda p: (p.number, p.name))
    disc = PairDiscovery(folder, layout, tuple(pairs), tuple(unpaired))
    if disc.unpaired:
        log.info("%s", disc.warning())  # callers show it to the user
    return disc


# ---- loading ---------------------------------------------------------------------------------
def load_image(path: str | Path, grayscale: bool = False) -> np.ndarray:
    """Read an image file (BGR uint8, or gray); raise InputError naming the file if it cannot
    (too large files and headers are refused before decoding: files.images)."""
    return read_image_file(path, cv2.IMREAD_GRAYSCALE if grayscale else cv2.IMREAD_COLOR)


def _size(img: np.ndarray) -> tuple[int, int]:
    return int(img.shape[1]), int(img.shape[0])


def load_pair(pair: ImagePair, grayscale: bool = False,
              expected_size: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Both images of a pair; raise InputError if either is unreadable or their sizes differ
    (from each other, or from `expected_size` (w, h) when given)."""
    left = load_image(pair.left, grayscale)
    right = load_image(pair.right, grayscale)
    ls, rs = _size(left), _size(right)
    if ls != rs:
        raise InputError(f"images of different sizes: {pair.left.name} is {ls[0]}x{ls[1]} but "
                         f"{pair.right.name} is {rs[0]}x{rs[1]}")
    if expected_size is not None and ls != tuple(expected_size):
        raise InputError(f"images of different sizes: {pair.left.name} and {pair.right.name} are "
                         f"{ls[0]}x{ls[1]} but the other pairs are "
                         f"{expected_size[0]}x{expected_size[1]}")
    return left, right


def image_size_of(path: str | Path) -> tuple[int, int]:
    """(width, height) of an image file, px (reads the whole image)."""
    return _size(load_image(path, grayscale=True))


def check_same_size(named_sizes: list[tuple[str, tuple[int, int]]]) -> tuple[int, int]:
    """Return the common size of (file name, (w, h)) entries, or raise InputError naming the odd
    one out against the most common size."""
    if not named_sizes:
        raise InputError("no images to check")
    counts: dict[tuple[int, int], int] = {}
    for _, s in named_sizes:
        key = (s[0], s[1])
        counts[key] = counts.get(key, 0) + 1
    common = max(counts, key=lambda s: counts[s])
    for name, s in named_sizes:
        if tuple(s) != common:
            raise InputError(f"images of different sizes: {name} is {s[0]}x{s[1]} but the others are "
                             f"{common[0]}x{common[1]}")
    return common
