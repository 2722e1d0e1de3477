"""OpenCV's stereo sample files, written with cv2.FileStorage as samples/cpp/stereo_calib.cpp
writes them (intrinsics.yml: M1 D1 M2 D2; extrinsics.yml: R T R1 R2 P1 P2 Q; no image size),
in YAML and XML, as a pair and as one file."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import CalibrationFileError
from stereo_gui.files.any_calibration import load_any_calibration
from stereo_gui.files.opencv_calibration import partner_file, read_opencv_stereo
from stereo_gui.sources.sim import SimRig

SIZE = (640, 480)


@pytest.fixture(scope="module")
def sample():
    """The simulated rig's true calibration rectified as the sample does (alpha 1)."""
    calib = SimRig(seed=3).true_calibration()
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(calib.M1, calib.D1, calib.M2, calib.D2, SIZE,
                                                calib.R, calib.T,
                                                flags=cv2.CALIB_ZERO_DISPARITY, alpha=1)
    return {"M1": calib.M1, "D1": calib.D1, "M2": calib.M2, "D2": calib.D2, "R": calib.R,
            "T": calib.T, "R1": R1, "R2": R2, "P1": P1, "P2": P2, "Q": Q}


def write_storage(path, values: dict, names) -> None:
    """fs << "M1" << M1 << ... as the sample does (cv2.FileStorage picks YAML or XML by suffix)."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    assert fs.isOpened()
    for name in names:
        fs.write(name, np.asarray(values[name]))
    fs.release()


def write_sample_pair(folder, values, suffix=".yml", prefix=""):
    write_storage(folder / f"{prefix}intrinsics{suffix}", values, ("M1", "D1", "M2", "D2"))
    write_storage(folder / f"{prefix}extrinsics{suffix}", values,
                  ("R", "T", "R1", "R2", "P1", "P2", "Q"))
    return folder / f"{prefix}intrinsics{suffix}", folder / f"{prefix}extrinsics{suffix}"


@pytest.mark.parametrize("suffix", [".yml", ".xml"])
@pytest.mark.parametrize("given", ["intrinsics", "extrinsics"])
def test_the_samples_pair_is_read_from_either_file(tmp_path, sample, suffix, given):
    intr, extr = write_sample_pair(tmp_path, sample, suffix)
    if suffix == ".xml":
        assert intr.read_text().lstrip().startswith("<?xml")
    got = read_opencv_stereo(intr if given == "intrinsics" else extr, image_size=SIZE)
    c = got.calibration
    assert set(got.files) == {intr, extr}
    for name, m in sample.items():
        np.testing.assert_allclose(getattr(c, name), np.asarray(m).reshape(
            getattr(c, name).shape), rtol=0, atol=0, err_msg=name)
    assert got.computed == ("E", "F")
    assert c.image_size == SIZE and not got.size_from_file
    # E and F computed from R and T agree with the epipolar geometry: x2^T F x1 = 0
    p = np.array([[100.0], [50.0], [1500.0]])
    x1 = c.M1 @ p / p[2]
    q = c.R @ p + c.T
    x2 = c.M2 @ q / q[2]
    assert abs((x2.T @ c.F @ x1).item()) < 1e-6


def test_one_file_with_only_m_d_r_t_gets_its_rectification_computed(tmp_path, sample):
    path = tmp_path / "stereo.yml"
    write_storage(path, sample, ("M1", "D1", "M2", "D2", "R", "T"))
    got = read_opencv_stereo(path, image_size=SIZE)
    assert set(got.computed) == {"R1", "R2", "P1", "P2", "Q", "E", "F"}
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(sample["M1"], sample["D1"], sample["M2"],
                                                sample["D2"], SIZE, sample["R"], sample["T"],
                                                flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
    np.testing.assert_allclose(got.calibration.P2, P2)
    np.testing.assert_allclose(got.calibration.Q, Q)
    assert got.calibration.baseline_mm == pytest.approx(np.linalg.norm(sample["T"]))


def test_q_is_computed_from_p1_p2_when_only_q_is_missing(tmp_path, sample):
    path = tmp_path / "stereo.xml"
    write_storage(path, sample, ("M1", "D1", "M2", "D2", "R", "T", "R1", "R2", "P1", "P2"))
    got = read_opencv_stereo(path, image_size=SIZE)
    assert "Q" in got.computed
    np.testing.assert_allclose(got.calibration.Q, sample["Q"], atol=1e-9)


@pytest.mark.parametrize("form", ["width_height", "imageSize"])
def test_image_size_in_the_file_wins(tmp_path, sample, form):
    path = tmp_path / "stereo.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    if form == "width_height":
        fs.write("image_width", 640)
        fs.write("image_height", 480)
    else:  # fs << "imageSize" << cv::Size, as some copies of the sample write it: [640, 480]
        fs.startWriteStruct("imageSize", cv2.FileNode_SEQ | cv2.FileNode_FLOW)
        fs.write("", 640)
        fs.write("", 480)
        fs.endWriteStruct()
    for name in ("M1", "D1", "M2", "D2", "R", "T"):
        fs.write(name, np.asarray(sample[name]))
    fs.release()
    got = read_opencv_stereo(path, image_size=(320, 240))
    assert got.calibration.image_size == SIZE and got.size_from_file


def test_without_a_size_from_anywhere_the_error_says_so(tmp_path, sample):
    intr, _ = write_sample_pair(tmp_path, sample)
    with pytest.raises(CalibrationFileError, match="image size"):
        read_opencv_stereo(intr)
    # the size is only asked for when the file has none
    asked = []
    read_opencv_stereo(intr, image_size=lambda: asked.append(1) or SIZE)
    assert asked == [1]


def test_intrinsics_without_extrinsics_names_what_is_missing(tmp_path, sample):
    write_storage(tmp_path / "intrinsics.yml", sample, ("M1", "D1", "M2", "D2"))
    with pytest.raises(CalibrationFileError, match=r"R, T missing.*extrinsics\.yml"):
        read_opencv_stereo(tmp_path / "intrinsics.yml", image_size=SIZE)


@pytest.mark.parametrize("change,message", [
    ({"M1": np.zeros((3, 3))}, "M1 has no positive focal length"),
    ({"T": np.zeros((3, 1))}, "T is zero"),
    ({"T": np.ones((4, 1))}, "T should hold 3 numbers"),
    ({"D1": np.ones((1, 3))}, "D1 should have"),
    ({"M2": np.ones((2, 3))}, "M2 should be 3x3"),
])
def test_bad_matrices_are_named(tmp_path, sample, change, message):
    path = tmp_path / "stereo.yml"
    write_storage(path, sample | change, ("M1", "D1", "M2", "D2", "R", "T"))
    with pytest.raises(CalibrationFileError, match=message):
        read_opencv_stereo(path, image_size=SIZE)


def test_partner_names_keep_prefix_case_and_suffix(tmp_path, sample):
    write_sample_pair(tmp_path, sample, ".xml", prefix="rig2_")
    assert partner_file(tmp_path / "rig2_intrinsics.xml") == tmp_path / "rig2_extrinsics.xml"
    (tmp_path / "Intrinsics.yml").write_text("%YAML:1.0\n")
    (tmp_path / "Extrinsics.yml").write_text("%YAML:1.0\n")
    assert partner_file(tmp_path / "Extrinsics.yml") == tmp_path / "Intrinsics.yml"
    assert partner_file(tmp_path / "calib.yml") is None


def test_dispatch_reads_the_sample_and_says_what_it_was(tmp_path, sample):
    intr, _ = write_sample_pair(tmp_path, sample)
    loaded = load_any_calibration(intr, SIZE)
    assert loaded.kind == "opencv" and loaded.path == intr
    assert "intrinsics.yml + extrinsics.yml" in loaded.description
    assert "640x480 from the images or source" in loaded.description


def test_a_byte_that_is_no_text_in_a_matrix_header_is_refused_by_name(tmp_path):
    """An OpenCV-sample file whose matrix `dt` holds the byte 0xAA ended in UnicodeDecodeError."""
    import cv2
    import numpy as np

    from stereo_gui.core.errors import CalibrationFileError
    from stereo_gui.files.any_calibration import load_any_calibration

    good = tmp_path / "calib.yml"
    fs = cv2.FileStorage(str(good), cv2.FILE_STORAGE_WRITE)
    for name, m in (("M1", np.eye(3)), ("D1", np.zeros((1, 5))), ("M2", np.eye(3)),
                    ("D2", np.zeros((1, 5))), ("R", np.eye(3)), ("T", np.array([[-60.0], [0],
                                                                                  [0]]))):
        fs.write(name, m)
    fs.release()
    bad = tmp_path / "bad.yml"
    bad.write_bytes(good.read_bytes().replace(b"dt: d", b"dt: \xaa", 1))
    import pytest

    with pytest.raises(CalibrationFileError, match="not UTF-8"):
        load_any_calibration(bad, (640, 480))
