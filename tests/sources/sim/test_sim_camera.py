"""The simulated rig's description: webcam-like defaults, its truth file round trip."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.sources.sim import (
    RigTruth,
)


def test_default_rig_is_webcam_like(rig):
    t = rig.truth
    assert t.image_size == (640, 480)
    assert t.baseline_mm == pytest.approx(110.0)
    assert t.T[0, 0] < -109.0  # the right camera sits to the right: T_right_left points left
    assert 0.5 <= t.relative_rotation_deg <= 1.5
    for M, D in ((t.M1, t.D1), (t.M2, t.D2)):
        assert 700 < M[0, 0] < 800 and 700 < M[1, 1] < 800
        assert M[0, 2] != 320 and abs(M[0, 2] - 320) < 15 and abs(M[1, 2] - 240) < 15
        assert -0.3 <= D[0, 0] <= -0.1 and D.shape == (1, 5)
    assert not np.allclose(t.M1, t.M2)


def test_truth_json_round_trip(rig):
    data = json.loads(json.dumps(rig.truth.to_json()))
    back = RigTruth.from_json(data)
    for name in ("M1", "D1", "M2", "D2", "R", "T"):
        np.testing.assert_array_equal(getattr(back, name), getattr(rig.truth, name))
    assert back.board == rig.truth.board and back.image_size == rig.truth.image_size
    assert data["baseline_mm"] == pytest.approx(110.0)
    with pytest.raises(InputError):
        RigTruth.from_json({"M1": [[1]]})
