"""Measurement logs as CSV: round trip, numbers rounded to what they mean, older files, files
that are not ours."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import astuple, replace

import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.files import measurement_csv
from stereo_gui.files.measurement_csv import read_csv, write_csv
from stereo_gui.files.measurement_record import MeasurementRecord
from stereo_gui.files.sheet_columns import HEADERS

from factories import make_record, make_records


def test_csv_round_trip(tmp_path):
    recs = make_records()
    write_csv(tmp_path / "log.csv", recs)
    text = (tmp_path / "log.csv").read_text(encoding="utf-8")
    assert text.splitlines()[0].startswith("Time (ISO 8601),x (px),y (px),Disparity (px)")
    back = read_csv(tmp_path / "log.csv")
    assert len(back) == len(recs)
    for a, b in zip(back, recs, strict=True):
        names = [f.name for f in dataclasses.fields(MeasurementRecord)]
        for name, x, y in zip(names, astuple(a), astuple(b), strict=True):
            if isinstance(y, float) and math.isnan(y):
                assert math.isnan(x), name
            elif isinstance(y, float):
                # rounded to its meaning: 0.1 mm, 0.001 px, 0.1 % of a fraction
                assert x == pytest.approx(y, abs=0.5 * 10.0 ** -measurement_csv.csv_decimals(name)), name
            else:
                assert x == y, name
    import csv

    rows = list(csv.reader(text.splitlines()))
    assert rows[-1][HEADERS.index("Z (mm)")] == ""  # NaN is an empty field


def test_csv_numbers_are_rounded_to_their_meaning(tmp_path):
    rec = replace(make_record(1), x_px=100.123456789, disparity_px=47.123456789,
                  Z_mm=1750.987654321, X_mm=-0.0123, valid_fraction=0.87654321,
                  calibration_rms_px=0.2134567)
    write_csv(tmp_path / "log.csv", [rec])
    import csv

    lines = list(csv.reader((tmp_path / "log.csv").read_text().splitlines()))
    row = dict(zip(lines[0], lines[1], strict=True))
    assert row["x (px)"] == "100.123"
    assert row["Disparity (px)"] == "47.123"
    assert row["Z (mm)"] == "1751.0"
    assert row["X (mm)"] == "0.0"  # not "-0.0"
    assert row["Valid fraction"] == "0.877"
    assert row["Calibration RMS (px)"] == "0.213"
    assert row["Time (ISO 8601)"] == rec.time


def test_a_csv_written_before_the_error_columns_still_reads(tmp_path):
    recs = make_records(2)
    text = measurement_csv.records_to_csv(recs).splitlines()
    n = len(measurement_csv.ERROR_HEADERS) + 1  # and the note
    old = "\n".join(",".join(line.split(",")[:-n]) for line in text) + "\n"
    (tmp_path / "old.csv").write_text(old, encoding="utf-8")
    assert len(read_csv(tmp_path / "old.csv")) == len(recs)


def test_csv_of_something_else_is_refused(tmp_path):
    (tmp_path / "x.csv").write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="x.csv"):
        read_csv(tmp_path / "x.csv")


def test_csv_keeps_an_error_in_percent_to_what_it_means(tmp_path):
    """An error of -0.6 mm at 2 m is -0.03 %: the CSV wrote 0.0 (rounded to 0.1 %); it keeps
    as many decimals as the error's 0.1 mm asks at that distance."""
    import csv

    rec = dataclasses.replace(make_record(1), Z_mm=1999.4, range_mm=1999.4, true_mm=2000.0)
    near = dataclasses.replace(make_record(2), Z_mm=499.6, range_mm=499.6, true_mm=500.0)
    rows = list(csv.reader(measurement_csv.records_to_csv([rec, near]).splitlines()))
    col = rows[0].index("Error (%)")
    assert rows[1][col] == "-0.030" and rows[1][rows[0].index("Error Z - true (mm)")] == "-0.6"
    assert rows[2][col] == "-0.08"
    assert measurement_csv.pct_decimals(None) == 1 and measurement_csv.pct_decimals(3000.0) == 3
