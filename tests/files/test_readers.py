"""The shared JSON and CSV readers: contents, and errors that name the file."""

import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.files.readers import read_csv_rows, read_json_object


def test_read_json_object(tmp_path):
    path = tmp_path / "a.json"
    path.write_text('{"x": 1}')
    assert read_json_object(path, "thing") == {"x": 1}
    path.write_bytes(b"\xff\xfe{")
    with pytest.raises(InputError, match="thing .*a.json is not valid JSON"):
        read_json_object(path, "thing")
    with pytest.raises(InputError, match="cannot read thing .*b.json"):
        read_json_object(tmp_path / "b.json", "thing")


def test_read_csv_rows(tmp_path):
    path = tmp_path / "a.csv"
    path.write_text("a,b\n1,2\n3,4\n")
    assert read_csv_rows(path, ("a", "b"), "a list") == [["1", "2"], ["3", "4"]]
    with pytest.raises(InputError, match="a.csv is not a list .*first row is not a, c"):
        read_csv_rows(path, ("a", "c"), "a list")
    path.write_text("")
    with pytest.raises(InputError, match="a.csv is not a list"):
        read_csv_rows(path, ("a", "b"), "a list")
    with pytest.raises(InputError, match="cannot read .*b.csv"):
        read_csv_rows(tmp_path / "b.csv", ("a",), "a list")
