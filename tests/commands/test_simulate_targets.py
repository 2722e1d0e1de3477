"""`stereo-gui simulate` with another target and wide-angle cameras: the set calibrates."""

from __future__ import annotations

import json

from stereo_gui.cli import main


def test_a_charuco_set_from_fisheye_cameras(tmp_path, capsys):
    out = tmp_path / "set"
    code = main(["simulate", str(out), "--pairs", "3", "--target", "charuco", "--board", "7x5",
                 "--square-mm", "30", "--marker-mm", "22", "--lens", "fisheye"])
    text = capsys.readouterr().out
    assert code == 0 and "ChArUco 7x5" in text and "fisheye lenses" in text
    truth = json.loads((out / "truth.json").read_text())
    assert truth["model"] == "fisheye" and len(truth["D1"]) == 4
    assert truth["board"] == {"cols": 7, "rows": 5, "square_mm": 30.0, "target": "charuco",
                              "marker_mm": 22.0, "dictionary": "DICT_4X4_50"}
    assert len(list(out.glob("chessboard-*.png"))) == 6


def test_a_bad_target_exits_2(tmp_path, capsys):
    code = main(["simulate", str(tmp_path / "x"), "--target", "charuco", "--board", "2x2"])
    assert code == 2 and "at least 3x3" in capsys.readouterr().err
