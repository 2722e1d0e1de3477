"""ROS camera_info files: the export parses as YAML with ROS's layout and units, the import
rebuilds the calibration, and a bad pair of files is named."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from stereo_gui.core.errors import CalibrationFileError
from stereo_gui.files.ros_camera_info import export_ros, import_ros

from factories import make_calibration


def test_ros_export_parses_with_yaml_and_values_match(tmp_path):
    c = make_calibration()
    lp, rp = export_ros(c, tmp_path)
    assert (lp.name, rp.name) == ("left.yaml", "right.yaml")
    for path, M, D, R, P in ((lp, c.M1, c.D1, c.R1, c.P1), (rp, c.M2, c.D2, c.R2, c.P2)):
        data = yaml.safe_load(path.read_text())
        assert data["image_width"] == 640 and data["image_height"] == 480
        assert data["distortion_model"] == "plumb_bob"
        assert data["camera_name"] in ("left", "right")
        cm = data["camera_matrix"]
        assert (cm["rows"], cm["cols"]) == (3, 3) and cm["data"] == M.reshape(-1).tolist()
        dc = data["distortion_coefficients"]
        assert (dc["rows"], dc["cols"]) == (1, 5) and dc["data"] == D.reshape(-1).tolist()
        assert data["rectification_matrix"]["data"] == R.reshape(-1).tolist()
        pm = data["projection_matrix"]
        assert (pm["rows"], pm["cols"]) == (3, 4)
        expected = P.copy()
        expected[:, 3] /= 1000.0  # ROS wants metres
        assert np.allclose(np.array(pm["data"]).reshape(3, 4), expected, rtol=0, atol=1e-12)


def test_ros_import_rebuilds_the_calibration(tmp_path):
    c = make_calibration()
    back = import_ros(*export_ros(c, tmp_path))
    for name in ("M1", "D1", "M2", "D2", "R1", "R2"):
        assert np.array_equal(getattr(back, name), getattr(c, name)), name
    for name in ("P1", "P2", "Q"):
        assert np.allclose(getattr(back, name), getattr(c, name), rtol=1e-12, atol=1e-9), name
    assert np.allclose(back.R, c.R, atol=1e-12)
    assert np.allclose(back.T, c.T, atol=1e-9)
    F1, F2 = back.F / np.linalg.norm(back.F), c.F / np.linalg.norm(c.F)
    assert np.allclose(F1, F2 * np.sign(F1[2, 2] * F2[2, 2]), atol=1e-9)
    assert back.baseline_mm == pytest.approx(c.baseline_mm, rel=1e-12)


def test_ros_import_errors(tmp_path):
    with pytest.raises(CalibrationFileError, match="does not exist"):
        import_ros(tmp_path / "left.yaml", tmp_path / "right.yaml")
    lp, rp = export_ros(make_calibration(), tmp_path)
    rp.write_text(rp.read_text().replace("rows: 3\n  cols: 4", "rows: 4\n  cols: 3"))
    with pytest.raises(CalibrationFileError, match="projection_matrix should be 3x4, found 4x3"):
        import_ros(lp, rp)
    with pytest.raises(CalibrationFileError, match="no baseline term"):
        import_ros(lp, lp)
