"""Scene lists, PFM and integer ground truths (files made in the test)."""

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.files.scenes import (
    load_scene, read_pfm, read_scene_list, read_seen_mask, read_truth)


def _write_pfm(path, image: np.ndarray, little_endian: bool = True) -> None:
    h, w = image.shape
    with open(path, "wb") as fh:
        fh.write(b"Pf\n" + f"{w} {h}\n".encode() + (b"-1.0\n" if little_endian else b"1.0\n"))
        data = np.flipud(image).astype("<f4" if little_endian else ">f4")
        fh.write(data.tobytes())


def test_pfm_is_read_top_row_first_in_either_byte_order(tmp_path):
    image = np.arange(12, dtype=np.float32).reshape(3, 4)
    image[1, 2] = np.inf
    for little in (True, False):
        path = tmp_path / f"d{little}.pfm"
        _write_pfm(path, image, little)
        got = read_pfm(path)
        assert got.dtype == np.float32 and got.shape == (3, 4)
        assert np.array_equal(got, image)  # (inf == inf)


def test_truths_come_out_in_pixels_with_zero_for_unknown(tmp_path):
    pfm = np.array([[1.5, np.inf], [np.nan, 4.0]], np.float32)
    _write_pfm(tmp_path / "t.pfm", pfm)
    assert np.array_equal(read_truth(tmp_path / "t.pfm", 1.0), [[1.5, 0.0], [0.0, 4.0]])
    png = np.array([[0, 256], [512, 1024]], np.uint16)
    cv2.imwrite(str(tmp_path / "t.png"), png)
    assert np.array_equal(read_truth(tmp_path / "t.png", 256.0), [[0, 1], [2, 4]])


def test_a_cut_pfm_and_a_bad_header_are_refused_with_the_file_named(tmp_path):
    path = tmp_path / "cut.pfm"
    _write_pfm(path, np.ones((4, 4), np.float32))
    path.write_bytes(path.read_bytes()[:-8])
    with pytest.raises(InputError, match="cut short"):
        read_pfm(path)
    (tmp_path / "bad.pfm").write_bytes(b"P6\n4 4\n255\n")
    with pytest.raises(InputError, match="not a PFM"):
        read_pfm(tmp_path / "bad.pfm")


def test_scene_list_resolves_paths_and_skips_comments(tmp_path):
    img = np.full((4, 6, 3), 100, np.uint8)
    cv2.imwrite(str(tmp_path / "l.png"), img)
    cv2.imwrite(str(tmp_path / "r.png"), img)
    cv2.imwrite(str(tmp_path / "gt.png"), np.full((4, 6), 12, np.uint8))
    (tmp_path / "list.tsv").write_text(
        "# scene\tleft\tright\tground_truth\tdivide_by\n\n"
        "one\tl.png\tr.png\tgt.png\t4\n")
    specs = read_scene_list(tmp_path / "list.tsv")
    assert [s.name for s in specs] == ["one"] and specs[0].left == tmp_path / "l.png"
    scene = load_scene(specs[0])
    assert scene.size == (6, 4) and np.all(scene.truth_px == 3.0)


@pytest.mark.parametrize("line, message", [
    ("one\tl.png\tr.png\tgt.png", "5 to 7 tab-separated"),
    ("one\tl.png\tr.png\tgt.png\tzero", "positive number"),
    ("one\tl.png\tr.png\tgt.png\t-2", "positive number"),
])
def test_malformed_lines_are_refused_with_the_line_number(tmp_path, line, message):
    (tmp_path / "list.tsv").write_text("# header\n" + line + "\n")
    with pytest.raises(InputError, match=f"line 2: .*{message}"):
        read_scene_list(tmp_path / "list.tsv")


def test_images_and_truth_of_other_sizes_are_refused(tmp_path):
    cv2.imwrite(str(tmp_path / "l.png"), np.zeros((4, 6, 3), np.uint8))
    cv2.imwrite(str(tmp_path / "r.png"), np.zeros((4, 6, 3), np.uint8))
    cv2.imwrite(str(tmp_path / "gt.png"), np.ones((5, 6), np.uint8))
    (tmp_path / "list.tsv").write_text("s\tl.png\tr.png\tgt.png\t1\n")
    with pytest.raises(InputError, match="differ in size"):
        load_scene(read_scene_list(tmp_path / "list.tsv")[0])


def test_a_scene_names_its_calibration_and_mask_or_finds_them_beside_its_images(tmp_path):
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "calib.txt").write_text("cam0=[1 0 0; 0 1 0; 0 0 1]\n")
    cv2.imwrite(str(tmp_path / "m" / "mask0nocc.png"), np.full((4, 6), 255, np.uint8))
    cv2.imwrite(str(tmp_path / "own-mask.png"), np.full((4, 6), 128, np.uint8))
    (tmp_path / "list.tsv").write_text(
        "beside\tm/l.png\tm/r.png\tgt.png\t1\n"
        "own\tl.png\tr.png\tgt.png\t1\tcam.yaml\town-mask.png\n"
        "rect\tl.png\tr.png\tgt.png\t1\trectified:700,120\n"
        "none\tm/l.png\tm/r.png\tgt.png\t1\t-\t-\n")
    beside, own, rect, none = read_scene_list(tmp_path / "list.tsv")
    assert beside.calib == str(tmp_path / "m" / "calib.txt")
    assert beside.mask == tmp_path / "m" / "mask0nocc.png"
    assert read_seen_mask(beside).all()
    assert own.calib == str(tmp_path / "cam.yaml") and own.mask == tmp_path / "own-mask.png"
    assert not read_seen_mask(own).any()  # 128: occluded
    assert rect.calib == "rectified:700,120" and rect.mask is None
    assert none.calib is None and none.mask is None and read_seen_mask(none) is None
