"""Small helpers shared by the core."""

from __future__ import annotations

import cv2
import numpy as np
from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]  # (no types)


def to_gray(image: np.ndarray) -> np.ndarray:
    """A uint8 single-channel view of a BGR, BGRA or grayscale image."""
    if image.ndim == 2:
        return image
    if image.shape[2] == 4:
        return cv2.cvtColor(image, cv2.COLOR_BGRA2GRAY)
    return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


def mutual_ratio_matches(dl: np.ndarray, dr: np.ndarray, ratio: float = 0.75
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Indices (left, right) of the descriptor pairs that pass Lowe's ratio test from left to
    right and are each other's nearest neighbour (the pairs OpenCV's BFMatcher gives with
    knnMatch(k=2) and a match() back).

    Both directions come from one matrix of squared L2 distances, |a|^2 + |b|^2 - 2 a.b, made
    by one matrix product on one BLAS thread: several times cheaper than BFMatcher's two passes
    for the same pairs, which matters because the live health check runs this every two seconds
    beside the frame lanes, and its CPU is theirs."""
    a = np.asarray(dl, np.float32)
    b = np.asarray(dr, np.float32)
    with threadpool_limits(1, "blas"):  # a BLAS pool would spin on the lanes' cores
        d2 = a @ b.T
    d2 *= np.float32(-2.0)
    d2 += np.einsum("ij,ij->i", a, a)[:, None]
    d2 += np.einsum("ij,ij->i", b, b)[None, :]
    np.maximum(d2, 0.0, out=d2)  # (rounding: a distance is never negative)
    rows = np.arange(len(a))
    back = np.argmin(d2, axis=0)  # each right descriptor's nearest left one
    nearest = np.argmin(d2, axis=1)  # each left descriptor's nearest right one
    best = d2[rows, nearest]
    d2[rows, nearest] = np.inf
    runner_up = d2.min(axis=1)  # the second nearest
    ok = (best < np.float32(ratio * ratio) * runner_up) & (back[nearest] == rows)
    return rows[ok], nearest[ok]


def how_many(n: int, noun: str, plural: str | None = None) -> str:
    """A count with its noun in the right number: "1 reading", "2 readings", "0 readings",
    "20,000 readings" (`plural` when it is not noun + "s")."""
    word = noun if n == 1 else (plural or noun + "s")
    return f"{n:,} {word}"
