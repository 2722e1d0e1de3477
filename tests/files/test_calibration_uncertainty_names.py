"""A calibration file whose uncertainty names a parameter the calibration does not have, or
whose two cameras have different distortion models, is refused on load with the name (it used to
load and end in KeyError at the first distance)."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.errors import CalibrationFileError
from stereo_gui.core.measure import measure_map
from stereo_gui.core.uncertainty import CalibrationUncertainty, parameter_names
from stereo_gui.files.calibration_file import load_calibration, save_calibration
from stereo_gui.sources.sim import SimRig


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """A calibration with a full covariance saved as YAML: (path, its text)."""
    calib = SimRig(seed=0).true_calibration()
    names = parameter_names(calib.model, calib.D1.size)
    rng = np.random.default_rng(0)
    a = rng.normal(size=(len(names), len(names)))
    cov = a @ a.T * 1e-8
    calib = calib.with_updates(uncertainty=CalibrationUncertainty(names, cov, 0.04, "jacobian",
                                                                  calib.model))
    path = tmp_path_factory.mktemp("calib") / "calib.yaml"
    save_calibration(calib, path)
    return path, path.read_text()


def test_a_whole_covariance_loads_and_a_distance_is_read_with_it(saved):
    path, _ = saved
    calib = load_calibration(path)
    assert calib.uncertainty is not None
    disp = np.full((calib.height, calib.width), 40.0, np.float32)
    m = measure_map(disp, 320, 240, calibration=calib)
    assert m.valid and m.expected_error_mm > 0


@pytest.mark.parametrize("old, new, words", [
    ("right.k3", "right.k3null", ["'right.k3null'", "not a parameter", "remove uncertainty_names"]),
    ("rvec.z", "r!!opencv-matrixvec.z", ["not a parameter"]),
    ("T.z", "T.x", ["T.x twice"]),
])
def test_a_covariance_naming_what_is_not_there_is_refused(saved, tmp_path, old, new, words):
    _, text = saved
    bad = tmp_path / "bad.yaml"
    assert f'"{old}"' in text or f" {old}\n" in text or old in text
    bad.write_text(text.replace(old, new, 1))
    with pytest.raises(CalibrationFileError) as err:
        load_calibration(bad)
    for w in words:
        assert w in str(err.value)


def test_two_cameras_with_different_distortion_counts_are_refused(tmp_path):
    import cv2

    calib = SimRig(seed=0).true_calibration()
    path = tmp_path / "calib.yaml"
    save_calibration(calib, path)
    # the file as another program might leave it: D2 with 8 coefficients, D1 with 5
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    nodes = {n: fs.getNode(n) for n in fs.root().keys()}
    out = cv2.FileStorage(str(tmp_path / "mixed.yaml"), cv2.FILE_STORAGE_WRITE)
    for name, node in nodes.items():
        mat = node.mat() if node.isMap() else None
        if name == "D2":
            out.write(name, np.concatenate([mat.reshape(-1), np.zeros(3)]).reshape(1, -1))
        elif mat is not None:
            out.write(name, mat)
        elif node.isMap() or node.isSeq():
            continue  # (the board, the pairs: not needed to load the matrices)
        elif node.isString():
            out.write(name, node.string())
        elif node.isInt():
            out.write(name, int(node.real()))
        elif node.isReal():
            out.write(name, node.real())
    out.release()
    fs.release()
    with pytest.raises(CalibrationFileError, match="D1 has 5 coefficients and D2 8"):
        load_calibration(tmp_path / "mixed.yaml")
