"""Lens shading: how much darker each camera's image gets towards its corners (vignetting), measured
on the white squares of the chessboard pairs a calibration is made from, and undone before
matching.

Both cameras darken the same image corners, but a surface point is seen nearer a corner by one
camera than by the other (by its disparity), so the two images of a smooth wall differ in
brightness by an amount that changes across the frame. On weak texture that difference outweighs
the texture and pulls matches towards no disparity: on the simulated rig's painted wall at half
contrast with corners 35 % darker, a click reads at 66-70 % of the grid instead of 97 %.

The model, per camera: relative brightness V(r) = 1 + k1 r^2 + k2 r^4 of what the sensor records
above its black level c, r the distance from the image centre divided by the half-diagonal (1 in
the corners); undone as (I - c) / V + c. It is measured as follows. In every pair the board's
squares are sampled at their centres (a window of a fifth of a square); each image's white and
black squares have their own brightness S (its exposure and lighting), so the samples
b = S V(r) + c are fitted by alternating least squares: every S and c given V, then k1, k2 given
those (the black squares, whose S is small, fix c). Samples that are clipped (>= 250) or far off
the fit (a reflection, a shadow) are left out. A board held at many places across the frame, as the capture guidance asks for, gives
V over the whole frame; when the boards' samples do not reach far enough from the centre (less
than half the half-diagonal), no shading is measured.
"""

from __future__ import annotations

import logging
import math
import numbers
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import overload

import cv2
import numpy as np

from stereo_gui.core.errors import CalibrationValueError

log = logging.getLogger(__name__)

CLIPPED = 250.0  # grey level: a sample at or above it may be saturated
MIN_REACH = 0.5  # samples must reach this far from the centre (of the half-diagonal) ...
MIN_SAMPLES = 60  # ... and be at least this many, over at least MIN_IMAGES images
MIN_IMAGES = 3
NEGLIGIBLE = 0.02  # corners less than 2 % darker: no correction is applied
MAX_LOSS = 0.8  # a fit with corners more than 80 % darker is not believed
MIN_BLACK, MAX_BLACK = -16.0, 64.0  # grey levels: a black level outside is not believed


@dataclass(frozen=True)
class LensShading:
    """One camera's relative brightness V(r) = 1 + k1 r^2 + k2 r^4 (r = 1 in the corners) of
    what its sensor records above its black level `black` (grey levels: what black gives).

    Checked on construction (CalibrationValueError): finite values, a black level from MIN_BLACK
    to MAX_BLACK, and V within MAX_LOSS of 1 over the whole frame (a fit beyond is not believed).
    """

    k1: float = 0.0
    k2: float = 0.0
    black: float = 0.0

    def __post_init__(self) -> None:
        for name, v in (("k1", self.k1), ("k2", self.k2), ("black", self.black)):
            if not (isinstance(v, numbers.Real) and math.isfinite(v)):
                raise CalibrationValueError(f"{name} should be a finite number")
            object.__setattr__(self, name, float(v))
        if not MIN_BLACK <= self.black <= MAX_BLACK:
            raise CalibrationValueError(f"black should be from {MIN_BLACK:g} to {MAX_BLACK:g} "
                                        f"grey levels, found {self.black:g}")
        ramp = self.brightness(np.linspace(0.0, 1.0, 21))
        if not (np.all(np.isfinite(ramp)) and ramp.min() > 1.0 - MAX_LOSS
                and ramp.max() < 1.0 + MAX_LOSS):
            raise CalibrationValueError(f"k1 {self.k1:g} and k2 {self.k2:g} darken or brighten "
                                        f"the image by more than {100 * MAX_LOSS:.0f} %")

    @property
    def coefficients(self) -> tuple[float, float, float]:
        """(k1, k2, black)."""
        return (self.k1, self.k2, self.black)

    @overload
    def brightness(self, r2: float) -> float: ...

    @overload
    def brightness(self, r2: np.ndarray) -> np.ndarray: ...

    def brightness(self, r2: np.ndarray | float) -> np.ndarray | float:
        """V at squared normalised radius r2."""
        return 1.0 + self.k1 * r2 + self.k2 * r2 * r2

    @property
    def corner_loss(self) -> float:
        """How much darker the corners are than the centre (0.35: 35 % darker)."""
        return float(1.0 - self.brightness(1.0))

    @property
    def negligible(self) -> bool:
        return abs(self.corner_loss) < NEGLIGIBLE

    def gain_map(self, size: tuple[int, int]) -> np.ndarray:
        """1 / V at every pixel of a raw image of `size` (w, h), float32."""
        return (1.0 / self.brightness(radius2_map(size))).astype(np.float32)

    def offset_map(self, gain: np.ndarray) -> np.ndarray:
        """What to add after multiplying by `gain` (a gain map, possibly resampled) so that the
        black level stays where it was: black * (1 - gain), float32."""
        return (np.float32(self.black) * (np.float32(1.0) - gain)).astype(np.float32)


def undo_shading(gray: np.ndarray, gain: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """A uint8 image with its lens shading undone: (I - black) / V + black, as gray * gain +
    offset (`LensShading.gain_map`, `offset_map`, both the image's size)."""
    out = cv2.multiply(gray, gain, dtype=cv2.CV_32F)
    cv2.add(out, offset, out)
    return cv2.convertScaleAbs(out)


@dataclass(frozen=True)
class PairShading:
    """Both cameras' lens shading and how many samples of how many images measured it."""

    left: LensShading
    right: LensShading
    samples: int = 0
    images: int = 0

    def __post_init__(self) -> None:
        for name, n in (("samples", self.samples), ("images", self.images)):
            if isinstance(n, bool) or not isinstance(n, numbers.Integral) or n < 0:
                raise CalibrationValueError(f"{name} should be a whole number >= 0, found {n!r}")

    def side(self, side: str) -> LensShading:
        """The lens shading of the "left" or "right" camera."""
        if side not in ("left", "right"):
            raise KeyError(side)
        return self.left if side == "left" else self.right

    @property
    def negligible(self) -> bool:
        return self.left.negligible and self.right.negligible

    def describe(self) -> str:
        pct = [int(round(100 * lens.corner_loss)) + 0 for lens in (self.left, self.right)]
        if min(pct) >= 0:
            return f"corners {pct[0]} % (left) and {pct[1]} % (right) darker than the centre"
        words = [f"{abs(v)} % {'darker' if v >= 0 else 'brighter'}" for v in pct]
        return f"corners {words[0]} (left) and {words[1]} (right) than the centre"


def radius2_map(size: tuple[int, int]) -> np.ndarray:
    """Squared normalised radius at every pixel of an image of `size` (w, h): 0 at the centre,
    1 in the corners (float64)."""
    w, h = size
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    return radius2(x, y, size)


def radius2(x: np.ndarray, y: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    w, h = size
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    return ((x - cx) ** 2 + (y - cy) ** 2) / (cx * cx + cy * cy)


@dataclass(frozen=True)
class BoardSamples:
    """One image's samples of a chessboard: squared normalised radius and mean grey level at the
    centres of its white squares and of its black squares."""

    r2_white: np.ndarray
    white: np.ndarray
    r2_black: np.ndarray
    black: np.ndarray


def board_samples(gray: np.ndarray, corners: np.ndarray, cols: int, rows: int) -> BoardSamples:
    """The samples at the centres of a chessboard's squares between its inner corners: `corners`
    (cols * rows, 2) in row order, as a full chessboard detection gives them. Which squares are
    white is found from the image (the brighter of the two alternating sets)."""
    g = gray if gray.ndim == 2 else cv2.cvtColor(gray, cv2.COLOR_BGR2GRAY)
    pts = np.asarray(corners, np.float64).reshape(rows, cols, 2)
    centres = 0.25 * (pts[:-1, :-1] + pts[:-1, 1:] + pts[1:, :-1] + pts[1:, 1:])
    side = np.sqrt(0.5 * (np.linalg.norm(pts[:-1, 1:] - pts[:-1, :-1], axis=2) ** 2
                          + np.linalg.norm(pts[1:, :-1] - pts[:-1, :-1], axis=2) ** 2))
    h, w = g.shape
    integral = cv2.integral(g.astype(np.float64))
    half = np.maximum(1, np.floor(side / 10.0)).astype(int)  # a window of a fifth of a square
    x0 = np.clip(np.rint(centres[..., 0]).astype(int) - half, 0, w - 1)
    y0 = np.clip(np.rint(centres[..., 1]).astype(int) - half, 0, h - 1)
    x1 = np.clip(np.rint(centres[..., 0]).astype(int) + half + 1, 1, w)
    y1 = np.clip(np.rint(centres[..., 1]).astype(int) + half + 1, 1, h)
    area = np.maximum((x1 - x0) * (y1 - y0), 1)
    mean = (integral[y1, x1] - integral[y0, x1] - integral[y1, x0] + integral[y0, x0]) / area
    parity = (np.add.outer(np.arange(rows - 1), np.arange(cols - 1)) % 2).astype(bool)
    white = parity if mean[parity].mean() > mean[~parity].mean() else ~parity
    r2 = radius2(centres[..., 0], centres[..., 1], (w, h))
    return BoardSamples(r2[white], mean[white], r2[~white], mean[~white])


def fit_shading(samples: Sequence[BoardSamples]) -> LensShading | None:
    """V and the black level from each image's board samples (see the module's docstring); None
    when they are too few or do not reach far enough from the centre to say.

    Every image has its own brightness S (exposure, lighting); its black squares reflect a share
    rho of what its white squares do, the same for every image of one board; all share V and the
    camera's black level c: a white sample is S V(r) + c, a black one rho S V(r) + c (that the
    black squares are darker by the same share everywhere is what tells c from S). Alternating
    least squares: every S and c given V and rho, rho given those, then V; samples far off the
    fit (a reflection, a shadow) are left out and the fit made again."""
    images = _usable_images(samples)
    if len(images) < MIN_IMAGES or sum(len(im[1]) for im in images) < MIN_SAMPLES:
        return None
    if math.sqrt(float(np.percentile(np.concatenate([im[0] for im in images]), 95))) < MIN_REACH:
        return None
    r2 = np.concatenate([np.concatenate([im[0], im[2]]) for im in images])
    b = np.concatenate([np.concatenate([im[1], im[3]]) for im in images])
    image = np.concatenate([np.full(len(im[1]) + len(im[3]), i) for i, im in enumerate(images)])
    is_black = np.concatenate([np.r_[np.zeros(len(im[1]), bool), np.ones(len(im[3]), bool)]
                               for im in images])
    n = len(images)
    keep = np.ones(len(b), bool)
    k = np.zeros(2)
    rho = float(np.mean(b[is_black]) / np.mean(b[~is_black]))
    for _ in range(4):  # trim outliers, then fit again
        k, rho, scale, black = _alternating_fit(r2, b, image, is_black, n, keep, k, rho)
        fit = scale[image] * np.where(is_black, rho, 1.0) * (1.0 + k[0] * r2 + k[1] * r2 * r2)
        resid = b - (fit + black)
        spread = 1.4826 * float(np.median(np.abs(resid[keep]))) + 1e-3
        keep = np.abs(resid) <= max(4.0 * spread, 2.0)
    try:  # (a black level or a V out of bounds is not believed)
        return LensShading(float(k[0]), float(k[1]), black)
    except CalibrationValueError as exc:
        log.info("lens shading fit out of bounds (%s): not used", exc)
        return None


def _usable_images(samples: Sequence[BoardSamples]
                   ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """(r^2 of the white samples, their values, r^2 of the black ones, their values) of each
    image with at least 4 unclipped samples of each and white samples not too dark."""
    images = []
    for s in samples:
        w_ok, b_ok = s.white < CLIPPED, s.black < CLIPPED
        if w_ok.sum() >= 4 and b_ok.sum() >= 4 and float(s.white[w_ok].mean()) > 8.0:
            images.append((np.asarray(s.r2_white, np.float64)[w_ok],
                           np.asarray(s.white, np.float64)[w_ok],
                           np.asarray(s.r2_black, np.float64)[b_ok],
                           np.asarray(s.black, np.float64)[b_ok]))
    return images


def _alternating_fit(r2: np.ndarray, b: np.ndarray, image: np.ndarray, is_black: np.ndarray,
                     n: int, keep: np.ndarray, k: np.ndarray, rho: float
                     ) -> tuple[np.ndarray, float, np.ndarray, float]:
    """One alternating least-squares fit over the samples `keep`s (values `b` at `r2`, of image
    `image`, black where `is_black`, of `n` images) from V's (k1, k2) `k` and `rho`: (k, rho,
    every image's S, the black level c)."""
    for _ in range(50):
        v = 1.0 + k[0] * r2 + k[1] * r2 * r2
        share = np.where(is_black, rho, 1.0)
        # every image's S and the black level, given V and rho
        scale, black = _scales_and_black((share * v)[keep], b[keep], image[keep], n)
        # rho, given those
        sv = (scale[image] * v)[keep & is_black]
        rho = float(np.sum((b - black)[keep & is_black] * sv) / max(np.sum(sv * sv), 1e-9))
        # V, given those: b - c - S' = S' (k1 r^2 + k2 r^4), S' = S (white) or rho S (black)
        a = scale[image] * np.where(is_black, rho, 1.0)
        k_new = np.linalg.lstsq(np.stack([a * r2, a * r2 * r2], axis=1)[keep],
                                (b - black - a)[keep], rcond=None)[0]
        done = np.max(np.abs(k_new - k)) < 1e-7
        k = k_new
        if done:
            break
    return k, rho, scale, black


def _scales_and_black(a: np.ndarray, b: np.ndarray, image: np.ndarray, n: int
                      ) -> tuple[np.ndarray, float]:
    """The least-squares S (one per image) and c of b = S[image] a + c: each image's S given c
    is its own ratio, which leaves one equation in c (the normal equations solved by their
    structure, not as a dense system of every sample by every image: a calibration's 57 pairs
    spent 5 of its 10 s there)."""
    saa = np.bincount(image, a * a, n)
    sa = np.bincount(image, a, n)
    sab = np.bincount(image, a * b, n)
    has = saa > 0
    # S_i = (sab_i - c sa_i) / saa_i; sum_j (b_j - S_i a_j - c) = 0 gives c
    ratio = np.where(has, sa / np.where(has, saa, 1.0), 0.0)
    denom = len(b) - float(np.sum(ratio * sa))
    c = (float(np.sum(b)) - float(np.sum(ratio * sab))) / denom if abs(denom) > 1e-12 else 0.0
    scale = np.where(has, (sab - c * sa) / np.where(has, saa, 1.0), 0.0)
    return scale, c


def measure_pair_shading(pairs: Sequence[tuple[object, Callable[[], np.ndarray],
                                               Callable[[], np.ndarray]]],
                         cols: int, rows: int) -> PairShading | None:
    """Both cameras' shading from (PairDetection, left image loader, right image loader) of pairs
    with a full chessboard of `cols` x `rows` inner corners in both images; None when either
    camera's cannot be measured (see `fit_shading`). Each image is read once."""
    left: list[BoardSamples] = []
    right: list[BoardSamples] = []
    for det, load_left, load_right in pairs:
        for side, load, out in (("left", load_left, left), ("right", load_right, right)):
            d = getattr(det, side)
            if d is None or d.ids is not None or len(d.corners) != cols * rows:
                continue
            img = load()
            if img is None:
                continue
            out.append(board_samples(img, d.corners, cols, rows))
    fits = fit_shading(left), fit_shading(right)
    if fits[0] is None or fits[1] is None:
        return None
    return PairShading(fits[0], fits[1], samples=sum(len(x.white) + len(x.black) for x in left + right),
                       images=len(left) + len(right))


def shading_text(shading: PairShading | None) -> str:
    """What a calibration's lens shading is and does, in a few words."""
    if shading is None:
        return "not measured (measured on chessboard pairs)"
    if shading.negligible:
        return f"none worth undoing ({shading.describe()})"
    return f"{shading.describe()}; undone before matching"


def shading_words(shading: PairShading | None) -> str:
    """One line for a calibration summary."""
    return f"lens shading: {shading_text(shading)}"
