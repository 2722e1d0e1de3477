"""Fit files: JSON round trip, errors that name the file, atomic writes."""

import json

import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.core.regression import fit_cubic, fit_inverse
from stereo_gui.files.fit_file import load_fit, save_fit

SAMPLES = [(d, 82500.0 / (d - 0.3) + e) for d, e in
           ((20.0, 1.0), (27.5, -2.0), (41.0, 0.5), (55.0, 1.5), (82.0, -1.0), (110.0, 0.2))]


def test_save_and_load_round_trip(tmp_path):
    for f in (fit_inverse(SAMPLES), fit_cubic(SAMPLES)):
        path = save_fit(f, tmp_path / f"{f.model}.json")
        g = load_fit(path)
        assert (g.model, g.coefficients, g.samples) == (f.model, f.coefficients, f.samples)
        assert g.r2 == pytest.approx(f.r2) and g.residuals_mm == pytest.approx(f.residuals_mm)
        assert json.loads(path.read_text())["formula"] == f.formula()
    assert not list(tmp_path.glob(".*"))  # no temporary files left


def test_load_errors_name_the_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="bad.json is not valid JSON"):
        load_fit(bad)
    bad.write_text("[1, 2]")
    with pytest.raises(InputError, match="bad.json does not hold a JSON object"):
        load_fit(bad)
    bad.write_text(json.dumps({"model": "inverse", "coefficients": [1.0]}))
    with pytest.raises(InputError, match="bad.json is not usable: .*coefficients"):
        load_fit(bad)
    with pytest.raises(InputError, match="missing.json"):
        load_fit(tmp_path / "missing.json")
    with pytest.raises(InputError, match="does not exist"):
        save_fit(fit_inverse(SAMPLES), tmp_path / "no" / "x.json")


def test_failed_save_keeps_the_old_file(tmp_path, monkeypatch):
    path = save_fit(fit_inverse(SAMPLES), tmp_path / "fit.json")
    before = path.read_text()

    def boom(*a, **k):
        raise OSError(28, "No space left on device")

    from stereo_gui.files import atomic

    monkeypatch.setattr(atomic.syscalls, "replace", boom)
    with pytest.raises(InputError, match="(?i)no space"):
        save_fit(fit_cubic(SAMPLES), path)
    assert path.read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["fit.json"]
