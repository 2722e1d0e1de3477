"""`stereo-gui measure ... --xlsx FILE`: measurements appended to a workbook, earlier rows kept."""

from __future__ import annotations

import json

import cv2
import numpy as np
import openpyxl
import pytest

from stereo_gui.cli import main
from stereo_gui.files.calibration_file import save_calibration
from stereo_gui.files.spreadsheet import XLSX_HEADERS, read_measurements
from stereo_gui.sources.sim import Scene, SimRig

WALL_MM = 1000.0


@pytest.fixture(scope="module")
def wall_pair(tmp_path_factory):
    """A rendered textured wall at 1 m and the rig's true calibration, as files."""
    folder = tmp_path_factory.mktemp("wall")
    rig = SimRig(seed=7)
    left, right = rig.render_scene(Scene.wall(WALL_MM, seed=11), np.random.default_rng(11))
    cv2.imwrite(str(folder / "left.png"), left)
    cv2.imwrite(str(folder / "right.png"), right)
    calib = folder / "calib.yaml"
    save_calibration(rig.true_calibration(alpha=0.0), calib)
    return folder


def _measure(folder, capsys, *extra):
    code = main(["measure", "--calib", str(folder / "calib.yaml"), str(folder / "left.png"),
                 str(folder / "right.png"), "--at", "320,240", "--at", "200,150", "--json",
                 *map(str, extra)])
    out, err = capsys.readouterr()
    return code, out, err


def test_measure_appends_to_a_workbook(wall_pair, tmp_path, capsys):
    book = tmp_path / "log.xlsx"
    code, out, err = _measure(wall_pair, capsys, "--xlsx", book)
    assert code == 0, err
    first = json.loads(out)["points"]
    code, out, err = _measure(wall_pair, capsys, "--xlsx", book)
    assert code == 0, err
    second = json.loads(out)["points"]

    records = read_measurements(book)
    assert len(records) == 4  # the second run kept the first run's rows
    for rec, point in zip(records, first + second, strict=True):
        assert (rec.x_px, rec.y_px) == (point["x"], point["y"])
        assert rec.valid is point["valid"] is True
        assert rec.Z_mm == pytest.approx(point["Z_mm"], rel=1e-12)
        assert rec.disparity_px == pytest.approx(point["disparity_px"], rel=1e-12)
        assert rec.range_mm == pytest.approx(point["range_mm"], rel=1e-12)
        assert rec.valid_fraction == pytest.approx(point["valid_fraction"])
        assert rec.method == "triangulation" and rec.true_mm is None
        assert rec.calibration_file.endswith("calib.yaml")
        assert rec.Z_mm == pytest.approx(WALL_MM, rel=0.02)  # a wall at 1 m, seen at these points
    wb = openpyxl.load_workbook(book)
    assert tuple(c.value for c in wb["Measurements"][1]) == XLSX_HEADERS  # with the errors
    figures = {r[0]: r[1] for r in wb["Calibration"].iter_rows(min_row=3, max_col=2,
                                                                 values_only=True) if r[0]}
    assert figures["Baseline (mm)"] == pytest.approx(110.0, rel=0.01)


def test_a_file_that_is_not_our_workbook_exits_2_untouched(wall_pair, tmp_path, capsys):
    book = tmp_path / "other.xlsx"
    wb = openpyxl.Workbook()
    wb.active.append(["Budget", 12])
    wb.save(book)
    before = book.read_bytes()
    code, out, err = _measure(wall_pair, capsys, "--xlsx", book)
    assert code == 2
    assert out == ""  # nothing printed: the command failed as a whole
    assert "other.xlsx" in err and len(err.strip().splitlines()) == 1
    assert book.read_bytes() == before


def test_xlsx_name_is_checked(wall_pair, tmp_path, capsys):
    code, out, err = _measure(wall_pair, capsys, "--xlsx", tmp_path / "log.csv")
    assert code == 2 and ".xlsx" in err
