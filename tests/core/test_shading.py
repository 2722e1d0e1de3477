"""Lens shading: measured on the white squares of rendered chessboard pairs, stored with the
calibration, and undone before matching so that a vignetted weak wall is read as well as a plain
one."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stereo_gui.core.calibrate import with_measured_shading
from stereo_gui.core.detect import PairInput, detect_pairs
from stereo_gui.core.matching import StereoPipeline
from stereo_gui.core.shading import (
    BoardSamples,
    LensShading,
    PairShading,
    fit_shading,
    measure_pair_shading,
    radius2_map,
    shading_words,
    undo_shading,
)
from stereo_gui.core.stereo_calibration import PairError
from stereo_gui.files.presets import load_preset
from stereo_gui.sources.sim import RigConfig, SimRig, SimSource

SEED = 17


def _samples(shading: LensShading, n_images: int, rng, reach: float = 1.0, rho: float = 0.15):
    """Boards seen by a camera with `shading`: each image its own exposure and lighting, its
    black squares reflecting `rho` of what its white ones do, 1 % noise."""
    out = []
    for _ in range(n_images):
        r2 = rng.uniform(0.0, reach, 40) ** 2
        a = rng.uniform(120.0, 220.0)

        def seen(share):
            v = a * share * shading.brightness(r2) + shading.black
            return v * (1 + rng.normal(0, 0.01, r2.size))

        out.append(BoardSamples(r2, seen(1.0), r2.copy(), seen(rho)))
    return out


@pytest.mark.parametrize("black", [0.0, 12.0])
def test_fit_recovers_a_known_falloff_and_black_level_whatever_each_images_brightness(black):
    rng = np.random.default_rng(SEED)
    truth = LensShading(-0.30, -0.08, black)
    got = fit_shading(_samples(truth, 12, rng))
    assert got is not None
    assert got.corner_loss == pytest.approx(truth.corner_loss, abs=0.01)
    assert got.brightness(0.5) == pytest.approx(truth.brightness(0.5), abs=0.01)
    assert got.black == pytest.approx(black, abs=2.0)


def test_fit_leaves_out_reflections_and_clipped_samples():
    rng = np.random.default_rng(SEED)
    truth = LensShading(-0.35, 0.0)
    parts = _samples(truth, 12, rng)
    white = parts[0].white.copy()
    white[:5] = 255.0  # clipped
    white[5:8] *= 1.6  # a reflection
    parts[0] = replace(parts[0], white=white)
    assert fit_shading(parts).corner_loss == pytest.approx(0.35, abs=0.01)


def test_no_fit_from_too_little():
    rng = np.random.default_rng(SEED)
    truth = LensShading(-0.35, 0.0)
    assert fit_shading(_samples(truth, 2, rng)) is None  # too few images
    assert fit_shading(_samples(truth, 12, rng, reach=0.3)) is None  # only the middle seen


def test_gain_map_undoes_the_falloff():
    lens = LensShading(-0.35, 0.0)
    size = (64, 48)
    g = lens.gain_map(size)
    np.testing.assert_allclose(g * lens.brightness(radius2_map(size)), 1.0, rtol=1e-5)
    assert g[0, 0] == pytest.approx(1 / 0.65, rel=1e-3) and g[24, 32] == pytest.approx(1.0, abs=2e-3)
    # above a black level of 12: (I - 12) / V + 12, so that black stays black
    dark = LensShading(-0.35, 0.0, 12.0)
    g = dark.gain_map(size)
    seen = np.full((48, 64), 12.0) + 100.0 * dark.brightness(radius2_map(size))
    undone = undo_shading(np.rint(seen).astype(np.uint8), g, dark.offset_map(g))
    assert np.abs(undone.astype(float) - 112.0).max() <= 1.0


@pytest.fixture(scope="module")
def vignetted_pairs():
    rig = SimRig(replace(RigConfig(), vignetting=0.35), seed=SEED)
    images = rig.calibration_set(12, seed=SEED)
    inputs = [PairInput(f"pair{i}", left, right) for i, (left, right) in enumerate(images)]
    return rig, inputs, detect_pairs(inputs, rig.config.board)


def test_measured_on_the_white_squares_of_rendered_boards(vignetted_pairs):
    rig, inputs, dets = vignetted_pairs
    board = rig.config.board
    got = measure_pair_shading([(d, (lambda i=i: i.left), (lambda i=i: i.right))
                                for d, i in zip(dets, inputs, strict=True)], board.cols, board.rows)
    assert got is not None and got.images >= 20
    for lens in (got.left, got.right):
        assert lens.corner_loss == pytest.approx(0.35, abs=0.04)
    assert "undone before matching" in shading_words(got)


def test_none_measured_where_there_is_none():
    rig = SimRig(seed=SEED)
    images = rig.calibration_set(8, seed=SEED)
    inputs = [PairInput(f"pair{i}", left, right) for i, (left, right) in enumerate(images)]
    dets = detect_pairs(inputs, rig.config.board)
    board = rig.config.board
    got = measure_pair_shading([(d, (lambda i=i: i.left), (lambda i=i: i.right))
                                for d, i in zip(dets, inputs, strict=True)], board.cols, board.rows)
    assert got is not None and got.negligible
    assert "none worth undoing" in shading_words(got) and "-0" not in shading_words(got)


def test_calibration_flows_attach_it_only_for_a_chessboard(vignetted_pairs):
    rig, inputs, dets = vignetted_pairs
    # as calibrate_stereo leaves it: made from these pairs, no shading yet
    calib = rig.true_calibration().with_updates(
        lens_shading=None, per_pair=tuple(PairError(d.name, 0.1, 0.1) for d in dets))
    got = with_measured_shading(calib, dets, inputs, rig.config.board)
    assert got.lens_shading is not None
    assert got.lens_shading.left.corner_loss == pytest.approx(0.35, abs=0.04)
    charuco = replace(rig.config.board, target="charuco")
    assert with_measured_shading(calib, dets, inputs, charuco).lens_shading is None


def _left_columns_density(condition: str, shading: bool) -> float:
    """Density of the live preset's final map over the second and third sixths of the width
    (left of centre, where the right camera sees the wall nearer its darker corner) on a
    weak wall at 1 m."""
    src = SimSource(SimRig(seed=SEED), mode="wall", condition=condition, wall_mm=1000.0,
                    paced=False, seed=SEED)
    calib = src.rig.true_calibration()
    if not shading:
        calib = calib.with_updates(lens_shading=None)
    frame = src.read()
    with StereoPipeline(calib, load_preset("live")) as pipe:
        final = pipe.process(frame.left, frame.right).final_px
    w = final.shape[1]
    return float(np.isfinite(final[:, w // 6:w // 2]).mean())


def test_undoing_the_shading_gives_a_vignetted_weak_wall_back_its_readings():
    plain = _left_columns_density("half", shading=True)  # no vignetting: nothing to undo
    assert plain > 0.9
    assert _left_columns_density("vignetting", shading=True) > plain - 0.05
    assert _left_columns_density("vignetting", shading=False) < plain - 0.2


def test_a_calibration_without_shading_changes_nothing():
    calib = SimRig(seed=SEED).true_calibration()
    assert calib.lens_shading is None
    pipe = StereoPipeline(calib, load_preset("live"))
    flat = PairShading(LensShading(-0.01, 0.0), LensShading(0.0, 0.0))
    assert flat.negligible
    src = SimSource(SimRig(seed=SEED), mode="scene", paced=False, seed=SEED)
    f = src.read()
    a = pipe.process(f.left, f.right).final_px
    b = StereoPipeline(calib.with_updates(lens_shading=flat), load_preset("live")).process(
        f.left, f.right).final_px
    np.testing.assert_array_equal(np.isnan(a), np.isnan(b))
    np.testing.assert_array_equal(a[np.isfinite(a)], b[np.isfinite(b)])


def test_a_lens_shading_no_lens_has_is_refused_when_it_is_built():
    """What a fit or a file may hold and no lens has: a black level out of bounds, corners more
    than 80 % darker (or brighter), values that are not numbers; a pair's counts below zero."""
    from stereo_gui.core.errors import CalibrationValueError

    assert LensShading(-0.35, 0.02, 63.0).coefficients == (-0.35, 0.02, 63.0)
    for values, words in (((-0.35, 0.0, 65.0), "black should be from -16 to 64"),
                          ((-0.35, 0.0, -17.0), "black should be from -16 to 64"),
                          ((-0.9, 0.0), "darken or brighten the image by more than 80 %"),
                          ((0.5, 0.4), "darken or brighten the image by more than 80 %"),
                          ((float("nan"), 0.0), "k1 should be a finite number"),
                          ((0.0, float("inf")), "k2 should be a finite number"),
                          ((0.0, 0.0, "12"), "black should be a finite number")):
        with pytest.raises(CalibrationValueError, match=words):
            LensShading(*values)
    lens = LensShading(-0.3, 0.0)
    assert PairShading(lens, lens, 800, 40).side("right") is lens
    with pytest.raises(CalibrationValueError, match="samples should be a whole number >= 0"):
        PairShading(lens, lens, -1, 40)
    with pytest.raises(CalibrationValueError, match="images should be a whole number >= 0"):
        PairShading(lens, lens, 800, 2.5)


def test_the_images_scales_and_black_level_are_the_least_squares_ones():
    """The per-image brightness S and the black level c of b = S[image] a + c, solved by the
    normal equations' structure, are the dense least-squares solution (an image without samples
    gets S = 0, as the dense solver's minimum-norm answer gives it)."""
    from stereo_gui.core.shading import _scales_and_black

    rng = np.random.default_rng(4)
    n = 9
    image = rng.integers(0, n - 1, 400)  # image n - 1 has no samples
    a = rng.uniform(0.1, 1.0, 400)
    b = rng.uniform(50, 200, n)[image] * a + 7.0 + rng.normal(0, 1, 400)
    design = np.zeros((400, n + 1))
    design[np.arange(400), image] = a
    design[:, n] = 1.0
    dense = np.linalg.lstsq(design, b, rcond=None)[0]
    scale, black = _scales_and_black(a, b, image, n)
    assert black == pytest.approx(dense[n], abs=1e-9)
    np.testing.assert_allclose(scale, dense[:n], atol=1e-9)
    assert scale[n - 1] == 0.0
