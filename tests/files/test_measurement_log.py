"""The measurement log kept between runs: round trip, a full disk, files that cannot be used."""

from __future__ import annotations

import json
import math

import pytest
from disk_faults import STEPS, install

from stereo_gui.core.errors import InputError
from stereo_gui.core.regression import fit_inverse
from stereo_gui.files import measurement_log as ml
from stereo_gui.files.spreadsheet import MeasurementRecord


def _rec(d: float, true_mm=None, valid=True) -> MeasurementRecord:
    z = 82500.0 / d if valid else float("nan")
    return MeasurementRecord(time="2026-01-02T10:11:12+00:00", x_px=320.5, y_px=240.25,
                             disparity_px=d if valid else float("nan"), X_mm=-1.5, Y_mm=2.0,
                             Z_mm=z, range_mm=z, valid=valid,
                             reason="" if valid else "not seen by the right camera",
                             valid_fraction=0.875, expected_error_mm=3.25, true_mm=true_mm,
                             calibration_file="/x/calib.yaml", calibration_rms_px=0.21)


def _same(a: MeasurementRecord, b: MeasurementRecord) -> bool:
    for x, y in zip(vars(a).values(), vars(b).values(), strict=True):
        if isinstance(x, float) and math.isnan(x):
            if not (isinstance(y, float) and math.isnan(y)):
                return False
        elif x != y:
            return False
    return True


def test_round_trip_keeps_every_field_and_the_fit(tmp_path):
    recs = (_rec(40.0, 2050.0), _rec(20.0), _rec(0.0, valid=False))
    fit = fit_inverse([(40.0, 2050.0), (20.0, 4100.0), (30.0, 2760.0)])
    kept = ml.KeptLog(recs, (_rec(55.5, 1500.0),), fit)
    path = ml.save_log(kept, tmp_path / "sub" / "log.json")  # the folder is made
    back, warnings = ml.load_log(path)
    assert warnings == []
    assert len(back.records) == 3 and all(map(_same, back.records, recs))
    assert len(back.cleared) == 1 and _same(back.cleared[0], kept.cleared[0])
    assert back.active_fit == fit
    json.loads(path.read_text())  # strict JSON: NaN is written as null


def test_missing_file_is_an_empty_log(tmp_path):
    assert ml.load_log(tmp_path / "none.json") == (ml.KeptLog(), [])


def test_default_path_is_in_the_data_folder(monkeypatch, tmp_path):
    monkeypatch.setenv("STEREO_GUI_DATA_DIR", str(tmp_path))
    assert ml.default_log_path() == tmp_path / ml.LOG_FILE


@pytest.mark.parametrize("step", STEPS)
def test_a_full_disk_leaves_the_earlier_log_byte_for_byte(tmp_path, monkeypatch, step):
    path = ml.save_log(ml.KeptLog((_rec(40.0, 2000.0),)), tmp_path / "log.json")
    before = path.read_bytes()
    install(monkeypatch, step)
    with pytest.raises(InputError, match="cannot write"):
        ml.save_log(ml.KeptLog((_rec(40.0), _rec(20.0))), path)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["log.json"]  # no temporary file left


@pytest.mark.parametrize("text", [
    "", "[]", "{", '{"format_version": 2, "records": []}', '{"format_version": "1"}',
    '{"format_version": 1, "records": {}}', '{"format_version": 1, "records": [3]}',
    '{"format_version": 1, "records": [{"time": "t"}]}',
    # the probe's: 100,000 levels deep, an integer of 5000 digits, 10**400
    "[" * 100_000 + "]" * 100_000,
    '{"format_version": 1, "records": [], "cleared": [], "n": ' + "7" * 5000 + "}",
    '{"format_version": 1, "records": [{"time": "t", "x_px": 1' + "0" * 400 + "}]}",
])
def test_a_log_that_cannot_be_used_is_set_aside_and_reported(tmp_path, text):
    path = tmp_path / "log.json"
    path.write_text(text)
    kept, warnings = ml.load_log(path)
    assert kept == ml.KeptLog() and len(warnings) == 1 and "log.json" in warnings[0]
    assert (tmp_path / "log.json.unreadable").read_text() == text and not path.exists()


def test_wrong_types_in_a_reading_are_named(tmp_path):
    doc = json.loads(ml.log_to_json(ml.KeptLog((_rec(40.0),))))
    for field, value in (("valid", "yes"), ("Z_mm", "far"), ("true_mm", -3), ("time", 5)):
        bad = json.loads(json.dumps(doc))
        bad["records"][0][field] = value
        with pytest.raises(InputError, match=field):
            ml.log_from_json(json.dumps(bad), "log")


def _doc_with(**fields):
    doc = json.loads(ml.log_to_json(ml.KeptLog((_rec(40.0, 2000.0), _rec(20.0)))))
    doc["records"][0].update(fields)
    return json.dumps(doc)


def test_a_reading_of_10_to_the_400_sets_the_log_aside(tmp_path):
    path = tmp_path / "log.json"
    path.write_text(_doc_with(Z_mm=10**400))
    kept, warnings = ml.load_log(path)
    assert kept == ml.KeptLog() and "integer beyond 1e308" in warnings[0]
    assert "kept as log.json.unreadable" in warnings[0]


def test_a_valid_reading_without_a_distance_is_kept_as_invalid_and_said(tmp_path):
    path = tmp_path / "log.json"
    path.write_text(_doc_with(Z_mm=None))
    kept, warnings = ml.load_log(path)
    first = kept.records[0]
    assert not first.valid and first.reason == ml.NO_DISTANCE_KEPT
    assert len(kept.records) == 2 and len(warnings) == 1 and "Z_mm" in warnings[0]
    assert path.exists()  # nothing set aside: the rest of the log is as it was


def test_a_log_whose_active_fit_cannot_be_used_keeps_its_readings(tmp_path):
    path = tmp_path / "log.json"
    doc = json.loads(_doc_with())
    doc["active_fit"] = {"model": "quartic"}
    path.write_text(json.dumps(doc))
    kept, warnings = ml.load_log(path)
    assert len(kept.records) == 2 and kept.active_fit is None
    assert len(warnings) == 1 and "quartic" in warnings[0] and "triangulation" in warnings[0]
    with pytest.raises(InputError, match="quartic"):
        ml.log_from_json(json.dumps(doc), "log")  # without a list for warnings it is refused


def test_a_negative_distance_or_a_reading_off_any_image_is_said(tmp_path):
    """A log "valid" with a negative distance, or a reading at pixel 1e308, is said when it
    loads."""
    import dataclasses

    bad = dataclasses.replace(_rec(40.0), Z_mm=-2000.0, range_mm=-2000.0)
    far = dataclasses.replace(_rec(40.0), x_px=1e308)
    path = ml.save_log(ml.KeptLog((bad, far, _rec(20.0))), tmp_path / "log.json")
    back, warnings = ml.load_log(path)
    assert not back.records[0].valid and back.records[1].valid and back.records[2].valid
    assert any("-2000 mm" in w and "kept as invalid" in w for w in warnings)
    assert any("off any image" in w for w in warnings) and len(warnings) == 2


def test_a_data_folder_that_is_a_file_is_said(tmp_path):
    folder = tmp_path / "data"
    folder.write_text("not a folder")
    kept, warnings = ml.load_log(folder / "measurement-log.json")
    assert kept == ml.KeptLog() and len(warnings) == 1 and "is a file, not a folder" in warnings[0]


def test_a_very_large_log_is_said_and_its_warnings_are_counted_not_listed(tmp_path, monkeypatch):
    """100,000 readings loaded without a word (each save then took seconds); thousands of
    readings each with something to say must not fill the error bar line by line."""
    monkeypatch.setattr(ml, "LARGE_LOG", 50)
    path = tmp_path / "log.json"
    doc = json.loads(ml.log_to_json(ml.KeptLog(tuple(_rec(40.0) for _ in range(60)))))
    for r in doc["records"][:12]:
        r["Z_mm"] = None  # valid without a distance: kept as invalid, said
    path.write_text(json.dumps(doc))
    kept, warnings = ml.load_log(path)
    assert len(kept.records) == 60 and sum(not r.valid for r in kept.records) == 12
    assert len(warnings) == ml.MAX_SAID + 2
    assert "7 more reading(s)" in warnings[ml.MAX_SAID]
    assert "holds 60 readings" in warnings[-1] and "export" in warnings[-1]
    path.write_text(ml.log_to_json(ml.KeptLog(tuple(_rec(40.0) for _ in range(50)))))
    assert ml.load_log(path)[1] == []  # at the limit: nothing to say
