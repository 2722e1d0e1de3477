"""Pair discovery in the three folder layouts, unpaired files, and image loading errors."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.files.pairs import (
    ImagePair,
    check_same_size,
    discover_pairs,
    load_image,
    load_pair,
)


def _img(path: Path, size=(16, 12), value=100) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    ok = cv2.imwrite(str(path), np.full((size[1], size[0], 3), value, np.uint8))
    assert ok
    return path


def test_report_naming(tmp_path):
    for n in (1, 2, 10):
        _img(tmp_path / f"chessboard-L{n}.png")
        _img(tmp_path / f"chessboard-R{n}.png")
    (tmp_path / "truth.json").write_text("{}")  # not an image: ignored
    found = discover_pairs(tmp_path)
    assert found.layout == "names"
    assert [(p.name, p.number) for p in found.pairs] == [
        ("chessboard-1", 1), ("chessboard-2", 2), ("chessboard-10", 10)]
    assert found.pairs[2].left.name == "chessboard-L10.png"
    assert found.pairs[2].right.name == "chessboard-R10.png"
    assert found.unpaired == () and found.warning() is None


def test_left_right_names_any_padding_case_and_extension(tmp_path):
    _img(tmp_path / "left01.jpg")
    _img(tmp_path / "right1.JPG")
    _img(tmp_path / "Left2.TIFF")
    _img(tmp_path / "RIGHT002.bmp")
    _img(tmp_path / "left3.jpeg")
    _img(tmp_path / "right3.tif")
    found = discover_pairs(tmp_path)
    assert [p.number for p in found.pairs] == [1, 2, 3]
    assert [(p.left.name, p.right.name) for p in found.pairs] == [
        ("left01.jpg", "right1.JPG"), ("Left2.TIFF", "RIGHT002.bmp"), ("left3.jpeg", "right3.tif")]


def test_subfolders_paired_by_number(tmp_path):
    for n in (3, 1, 2):
        _img(tmp_path / "left" / f"img_{n:03d}.png")
        _img(tmp_path / "right" / f"frame{n}.png")
    _img(tmp_path / "right" / "frame7.png")
    found = discover_pairs(tmp_path)
    assert found.layout == "subfolders"
    assert [p.number for p in found.pairs] == [1, 2, 3]
    assert found.pairs[0].left.name == "img_001.png" and found.pairs[0].right.name == "frame1.png"
    assert [(u.path.name, u.reason) for u in found.unpaired] == [("frame7.png", "no left image 7")]
    assert "frame7.png (no left image 7)" in found.warning()


def test_unpaired_files_are_listed_not_dropped(tmp_path):
    _img(tmp_path / "left1.png")
    _img(tmp_path / "right1.png")
    _img(tmp_path / "left2.png")
    _img(tmp_path / "holiday.png")
    _img(tmp_path / "left01.jpg")  # same number as left1.png
    found = discover_pairs(tmp_path)
    assert [p.number for p in found.pairs] == [1]
    reasons = {u.path.name: u.reason for u in found.unpaired}
    assert reasons["left2.png"] == "no right image 2"
    assert reasons["holiday.png"] == "not named as a left or right image"
    assert "same number as" in (reasons.get("left01.jpg") or reasons.get("left1.png"))
    assert found.warning().startswith("3 unpaired image file(s) ignored")


def test_missing_folder_empty_folder_and_only_unpaired(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        discover_pairs(tmp_path / "nope")
    f = _img(tmp_path / "a.png")
    with pytest.raises(InputError, match="is not a folder"):
        discover_pairs(f)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="no images"):
        discover_pairs(empty)
    only = tmp_path / "only"
    _img(only / "left1.png")
    _img(only / "right2.png")
    with pytest.raises(InputError, match=r"no image pairs .*left1.png \(no right image 1\), "
                                         r"right2.png \(no left image 2\)"):
        discover_pairs(only)


def test_load_image_errors_name_the_file(tmp_path):
    bad = tmp_path / "left1.png"
    bad.write_bytes(b"this is not a png")
    with pytest.raises(InputError, match=r"image .*left1.png cannot be read as an image"):
        load_image(bad)
    empty = tmp_path / "right1.png"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="right1.png"):
        load_image(empty)
    with pytest.raises(InputError, match="missing.png"):
        load_image(tmp_path / "missing.png")
    good = _img(tmp_path / "ok.png", size=(20, 10))
    assert load_image(good).shape == (10, 20, 3)
    assert load_image(good, grayscale=True).shape == (10, 20)


def test_load_pair_refuses_different_sizes(tmp_path):
    pair = ImagePair("1", 1, _img(tmp_path / "left1.png", (16, 12)), _img(tmp_path / "right1.png", (8, 6)))
    with pytest.raises(InputError, match="left1.png is 16x12 but right1.png is 8x6"):
        load_pair(pair)
    ok = ImagePair("2", 2, _img(tmp_path / "left2.png"), _img(tmp_path / "right2.png"))
    left, right = load_pair(ok)
    assert left.shape == right.shape
    with pytest.raises(InputError, match="the other pairs are 32x24"):
        load_pair(ok, expected_size=(32, 24))


def test_check_same_size_names_the_odd_one():
    assert check_same_size([("a", (4, 3)), ("b", (4, 3))]) == (4, 3)
    with pytest.raises(InputError, match="c.png is 8x6 but the others are 4x3"):
        check_same_size([("a.png", (4, 3)), ("b.png", (4, 3)), ("c.png", (8, 6))])
