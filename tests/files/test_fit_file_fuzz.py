"""Fit files fuzzed with hypothesis (seeded): whatever a damaged fit file holds, loading it gives
our clean error or a fit that turns every disparity of its range into a positive distance that
falls as the disparity grows, and that still describes its own samples.

The checks here are made independently of the loader's: on a dense grid of disparities rather
than from the roots of the cubic's slope.
"""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.regression import fit_cubic, fit_inverse, fit_to_dict
from stereo_gui.files.fit_file import load_fit

A, D0 = 82500.0, 0.3  # px mm, px
DISPARITIES = (30.0, 38.0, 47.0, 55.0, 68.0, 82.0, 96.0, 110.0)
NOISE = (2.0, -3.0, 1.0, 0.5, -1.5, 2.5, -0.5, 1.0)
SAMPLES = [(d, A / (d - D0) + e) for d, e in zip(DISPARITIES, NOISE, strict=True)]
GOOD = {"inverse": fit_to_dict(fit_inverse(SAMPLES)), "cubic": fit_to_dict(fit_cubic(SAMPLES))}


def _paths(doc, prefix=()):
    """Every place in a JSON document a value sits (key paths)."""
    out = [prefix] if prefix else []
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += _paths(v, prefix + (i,))
    return out


PATHS = {model: [p for p in _paths(doc) if p[0] != "formula"] for model, doc in GOOD.items()}
NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**400), max_value=10**400),
    st.sampled_from([0, -1, 1, 2147483647, 10**30, 1e-300, -0.0]),
)
VALUES = st.one_of(NUMBERS, st.none(), st.booleans(), st.text(max_size=4),
                   st.lists(st.floats(-1e4, 1e4), max_size=5))


@st.composite
def damaged_fit(draw):
    """A saved fit with one to three values replaced, scaled or removed."""
    model = draw(st.sampled_from(sorted(GOOD)))
    doc = copy.deepcopy(GOOD[model])
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(PATHS[model]))
        parent = doc
        try:
            for key in path[:-1]:
                parent = parent[key]
            old = parent[path[-1]]
        except (KeyError, IndexError, TypeError):
            continue  # an earlier change removed this place
        how = draw(st.sampled_from(["replace", "scale", "remove"]))
        if how == "remove" and isinstance(parent, dict):
            del parent[path[-1]]
        elif how == "scale" and isinstance(old, float):
            parent[path[-1]] = old * draw(st.sampled_from([-1.0, 0.0, 0.04, 0.5, 1.01, 2.0, 25.0,
                                                           1e6]))
        else:
            parent[path[-1]] = draw(VALUES)
    return json.dumps(doc, allow_nan=True)


def _check_usable(fit) -> None:
    """What a loaded fit must be, checked on a dense grid of its range."""
    assert fit.samples or fit.model == "inverse"
    lo, hi = fit.disparity_span
    if not fit.samples:  # an inverse model without samples: used wherever d > d0
        a, d0 = fit.coefficients
        lo, hi = d0 + 1.0, d0 + 1000.0
    grid = np.linspace(lo, hi, 2001)
    z = np.asarray(fit.predict(grid), np.float64)
    assert np.all(np.isfinite(z)) and np.all(z > 0), "a distance that is not positive"
    assert np.all(np.diff(z) < 0), "a distance that does not fall as the disparity grows"
    for i, (d, true_mm) in enumerate(fit.samples):
        pred = float(fit.predict(d))
        assert abs(pred - true_mm) <= 0.5 * true_mm, "a fit that misses its samples"
        if fit.residuals_mm:
            assert math.isclose(true_mm - pred, fit.residuals_mm[i], rel_tol=1e-6, abs_tol=1e-3)


@settings(max_examples=200, derandomize=True, database=None, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(text=damaged_fit())
def test_a_damaged_fit_file_is_refused_or_usable(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("fit") / "fit.json"
    path.write_text(text)
    try:
        fit = load_fit(path)
    except StereoGuiError:
        return
    _check_usable(fit)


def test_the_good_files_load_and_are_usable(tmp_path):
    for model, doc in GOOD.items():
        path = tmp_path / f"{model}.json"
        path.write_text(json.dumps(doc))
        _check_usable(load_fit(path))


@pytest.mark.parametrize(("model", "change", "words"), [
    # the probe's cases: a negative distance (Z = -8856 mm) and readings changed 25 times
    ("inverse", {"coefficients": [-82500.0, 0.3]}, "must be positive"),
    ("inverse", {"coefficients": [82500.0, 45.0]}, "not below its smallest sample"),
    ("cubic", {"normalisation": {"offset_px": 2.0, "span_px": 5.12}}, "must be positive"),
    ("inverse", {"coefficients": [82500.0 * 25, 0.3]}, "does not describe its samples"),
    ("cubic", {"residuals_mm": [0.0] * len(SAMPLES)}, "coefficients or samples were changed"),
    ("cubic", {"samples": []}, "without samples"),
])
def test_the_probes_fits_are_refused_naming_why(tmp_path, model, change, words):
    path = tmp_path / "fit.json"
    doc = {**GOOD[model], **change}
    if change.get("samples") == []:
        doc["residuals_mm"] = []
    path.write_text(json.dumps(doc))
    with pytest.raises(StereoGuiError, match=words):
        load_fit(path)


def test_a_cubic_that_turns_within_its_samples_is_not_fitted():
    """Over 20..160 px the cubic cannot follow 1/d without rising again: two disparities would
    give one distance. It is not offered, as it could not be loaded again once saved."""
    samples = [(d, A / (d - D0)) for d in (20.0, 27.5, 41.0, 55.0, 82.0, 110.0, 160.0)]
    with pytest.raises(StereoGuiError, match="does not fall steadily"):
        fit_cubic(samples)
    assert fit_inverse(samples).predict(160.0) > 0


def test_a_fit_file_holding_ten_to_the_400_is_refused_in_one_line(tmp_path):
    doc = dict(GOOD["inverse"])
    path = tmp_path / "fit.json"
    path.write_text(json.dumps(doc).replace(repr(doc["coefficients"][0]), "1" + "0" * 400, 1))
    with pytest.raises(StereoGuiError, match="coefficient 1 is an integer beyond 1e308"):
        load_fit(path)
