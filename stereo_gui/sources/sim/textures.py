"""Textures of the simulated world (cached): the printed target and the multi-scale noise
of object surfaces, so that the matcher finds detail at every distance."""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from stereo_gui.core.board import BoardSpec

# grey levels of the printed board (not 0/255, so that noise does not clip)
_BLACK = 28.0
_WHITE = 225.0
_TEXELS_PER_SQUARE = 96  # board texture resolution: 0.26 mm texels for 25 mm squares
_TEXTURE_MAX_PX = 1536.0  # longest side of an object texture, texels
# multi-scale noise octaves of object textures: (size in texels, amplitude)
OCTAVES = ((1, 0.55), (2, 0.8), (4, 1.0), (8, 0.9), (16, 0.8), (48, 0.9), (160, 0.7))


@functools.lru_cache(maxsize=16)
def _texture(seed: int, width_mm: float, height_mm: float, contrast: float = 1.0
             ) -> tuple[np.ndarray, float]:
    """A rich colour texture (uint8 HxWx3) for an object, and its texel size in mm; `contrast`
    scales its variation around its mean colour.

    Multi-scale noise (octaves of smoothly upsampled random images) so that there is detail for
    the matcher at every distance: the texel follows the object's size, walls grow with distance.
    """
    texel = max(max(width_mm, height_mm) / _TEXTURE_MAX_PX, 0.35)
    tw = max(8, int(math.ceil(width_mm / texel)) + 2)
    th = max(8, int(math.ceil(height_mm / texel)) + 2)
    rng = np.random.default_rng(seed)
    acc = np.zeros((th, tw, 3), np.float32)
    total = 0.0
    for k, amp in OCTAVES:
        sw, sh = max(2, tw // k), max(2, th // k)
        small = rng.standard_normal((sh, sw, 3), dtype=np.float32)
        small[..., 1:] = 0.6 * small[..., :1] + 0.4 * small[..., 1:]  # partly grey, partly colour
        layer = small if k == 1 else cv2.resize(small, (tw, th), interpolation=cv2.INTER_CUBIC)
        acc += amp * layer[:th, :tw]
        total += amp * amp
    acc *= 46.0 * contrast / math.sqrt(total)
    acc += 125.0 + rng.uniform(-30.0, 30.0, 3).astype(np.float32)  # a tint per object
    tex = np.empty((th, tw, 4), np.uint8)
    tex[..., :3] = np.clip(acc, 10, 245)
    tex[..., 3] = 255  # alpha: outside the texture remap gives 0, which masks the object
    return tex, texel


@functools.lru_cache(maxsize=8)
def _board_texture(board: BoardSpec) -> tuple[np.ndarray, np.ndarray, float]:
    """The printed target over its outline (BoardSpec.outline_mm): its grey levels (uint8, one
    channel: it is grey), an alpha channel of the same size (255: remap's zero border around it
    marks rays that miss the board), and its texel size in mm: texel (i, j) has its centre at
    outline origin + (j + 0.5, i + 0.5) * texel.

    Chessboard and ChArUco squares are exact in texels (TEXELS_PER_SQUARE each); circles are
    drawn with an anti-aliased edge (the texel's covered share).
    """
    n = _TEXELS_PER_SQUARE
    texel = float(board.square_mm) / n
    a0, b0, a1, b1 = board.outline_mm()
    tw, th = int(round((a1 - a0) / texel)), int(round((b1 - b0) / texel))
    if board.target == "charuco":
        margin = int(round(-a0 / texel))
        img = board.aruco_board().generateImage((tw, th), marginSize=margin, borderBits=1)
        grey = np.where(img > 127, np.uint8(_WHITE), np.uint8(_BLACK))
    elif board.target == "chessboard":
        cols, rows = board.pattern_size
        qa = (np.arange(tw) + 0.5) / n - 2.0  # texel centres in squares from corner 0
        qb = (np.arange(th) + 0.5) / n - 2.0
        ia, ib = np.floor(qa).astype(int), np.floor(qb).astype(int)
        in_a = (ia >= -1) & (ia < cols)
        in_b = (ib >= -1) & (ib < rows)
        black = in_b[:, None] & in_a[None, :] & (((ib[:, None] + ia[None, :]) & 1) == 0)
        grey = np.where(black, np.uint8(_BLACK), np.uint8(_WHITE))
    else:
        a = a0 + (np.arange(tw) + 0.5) * texel
        b = b0 + (np.arange(th) + 0.5) * texel
        dist = _circle_distance(board, a, b)
        cover = np.clip(0.5 * board.marker_mm - dist + 0.5 * texel, 0.0, texel) / texel
        grey = np.round(_WHITE + (_BLACK - _WHITE) * cover).astype(np.uint8)
    return grey, np.full((th, tw), 255, np.uint8), texel


def _circle_distance(board: BoardSpec, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (mm) from each (b, a) texel centre to the nearest circle centre of a grid."""
    s = float(board.square_mm)
    cols, rows = board.pattern_size
    A, B = np.meshgrid(a, b)
    best = np.full(A.shape, np.inf)
    i0 = np.clip(np.round(B / s), 0, rows - 1)
    for di in (-1, 0, 1):
        i = np.clip(i0 + di, 0, rows - 1)
        if board.target == "acircles":
            shift = i % 2
            j = np.clip(np.round((A / s - shift) / 2.0), 0, cols - 1)
            cx = (2 * j + shift) * s
        else:
            j = np.clip(np.round(A / s), 0, cols - 1)
            cx = j * s
        best = np.minimum(best, np.hypot(A - cx, B - i * s))
    return best
