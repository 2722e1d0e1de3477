"""Images for the views: what the processors hand to pyqtgraph (no Qt here)."""

from __future__ import annotations

import cv2
import numpy as np


def display_rgb(image: np.ndarray) -> np.ndarray:
    """A BGR (or gray) image as C-contiguous RGB uint8 for pyqtgraph."""
    code = cv2.COLOR_GRAY2RGB if image.ndim == 2 else cv2.COLOR_BGR2RGB
    return cv2.cvtColor(image, code)
