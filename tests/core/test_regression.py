"""Distance-from-disparity fits: the reference program's cubic, the inverse model, R^2,
residuals."""

import json

import numpy as np
import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.core.regression import (
    FitResult,
    fit,
    fit_cubic,
    fit_from_dict,
    fit_inverse,
    fit_to_dict,
    reference_cubic,
)

A, D0 = 82500.0, 0.3  # px mm, px


def inverse_samples(noise_mm=0.0, seed=0):
    rng = np.random.default_rng(seed)
    ds = np.array([20.0, 27.5, 41.0, 55.0, 82.0, 110.0, 160.0])
    zs = A / (ds - D0) + rng.normal(0, noise_mm, ds.size)
    return list(zip(ds.tolist(), zs.tolist()))


def test_inverse_fit_recovers_the_model():
    f = fit_inverse(inverse_samples())
    assert f.model == "inverse"
    assert f.coefficients == pytest.approx((A, D0), rel=1e-6, abs=1e-6)
    assert f.r2 == pytest.approx(1.0)
    assert max(abs(r) for r in f.residuals_mm) < 1e-6
    assert f.predict(82.0) == pytest.approx(A / (82.0 - D0))
    assert f.formula().startswith("Z = 82500 / (d - 0.3")
    assert np.isnan(f.predict(0.1))  # at or below d0 there is no distance


def test_inverse_formula_writes_a_negative_offset_as_an_addition():
    f = FitResult("inverse", (82893.2, -0.2254), 1.0, (), ())
    assert f.formula() == "Z = 82893.2 / (d + 0.2254) mm"
    assert "- -" not in f.formula()
    assert FitResult("inverse", (82893.2, 0.2254), 1.0, (), ()).formula() == \
        "Z = 82893.2 / (d - 0.2254) mm"


def test_noisy_fits_report_residuals_in_sample_order():
    # up to 110 px: over 20..160 px a cubic cannot follow 1/d without turning (refused below)
    for samples, f in ((s, fn(s)) for fn in (fit_inverse, fit_cubic)
                       for s in [inverse_samples(noise_mm=3.0, seed=1)[:-1]]):
        assert len(f.residuals_mm) == len(samples) and f.samples == tuple(samples)
        pred = f.predict(np.array([d for d, _ in samples]))
        np.testing.assert_allclose(f.residuals_mm, [z for _, z in samples] - pred, atol=1e-6)
        assert 0.9 < f.r2 <= 1.0


def test_cubic_fit_uses_the_reference_loops_normalisation():
    coef = (-5939.7, 15068.0, -13731.0, 5220.6)  # the reference program's cubic, in mm
    ds = np.linspace(30, 120, 8)
    x = (ds - 2.0) / 128.0
    samples = list(zip(ds, np.polyval(coef, x)))
    f = fit_cubic(samples)
    assert f.coefficients == pytest.approx(coef, rel=1e-6)
    assert f.r2 == pytest.approx(1.0)
    assert "x = (d - 2) / 128" in f.formula()


def test_reference_cubic_in_millimetres():
    # d = 66 px -> x = 0.5 -> -593.97/8 + 1506.8/4 - 1373.1/2 + 522.06 = 137.96 cm
    assert reference_cubic().predict(66.0) == pytest.approx(1379.6, abs=0.1)


def test_too_few_or_bad_samples():
    with pytest.raises(InputError, match="at least 4"):
        fit_cubic([(10, 1000), (20, 500), (30, 333)])
    with pytest.raises(InputError, match="at least 2"):
        fit_inverse([(10, 1000)])
    with pytest.raises(InputError, match="positive"):
        fit_inverse([(10, 1000), (20, -5)])
    with pytest.raises(InputError, match="shrink"):
        fit_inverse([(10, 500), (20, 1000)])
    with pytest.raises(InputError, match="unknown model"):
        fit("quartic", inverse_samples())


def test_fewer_true_distances_than_parameters_are_refused_not_fitted_exactly():
    # two walls, two clicks each: four different disparities, but only two true distances; a
    # cubic through them showed R^2 1.00000 and RMS 0.0 mm
    two_walls = [(40.0, 1500.0), (40.6, 1500.0), (20.0, 3000.0), (20.3, 3000.0)]
    with pytest.raises(InputError, match="4 or more different distances, got 2"):
        fit_cubic(two_walls)
    with pytest.raises(InputError, match="2 or more different distances, got 1"):
        fit_inverse([(40.0, 1500.0), (40.6, 1500.0)])
    f = fit_inverse(two_walls)  # two parameters, two distances: a fit, with residuals
    assert not f.exactly_determined
    assert fit_inverse([(40.0, 1500.0), (20.0, 3000.0)]).exactly_determined


def test_dict_round_trip_and_errors_name_the_place():
    for f in (fit_inverse(inverse_samples(1.0)), fit_cubic(inverse_samples(1.0)[:-1])):
        g = fit_from_dict(json.loads(json.dumps(fit_to_dict(f))), where="x")
        assert isinstance(g, FitResult)
        assert (g.model, g.coefficients, g.samples) == (f.model, f.coefficients, f.samples)
        assert g.r2 == pytest.approx(f.r2) and g.residuals_mm == pytest.approx(f.residuals_mm)
        assert g.predict(50.0) == pytest.approx(f.predict(50.0))
    with pytest.raises(InputError, match="fit file a.json is not usable: .*coefficients"):
        fit_from_dict({"model": "inverse", "coefficients": [1.0]}, where="fit file a.json")
    with pytest.raises(InputError, match="newer"):
        fit_from_dict({**fit_to_dict(fit_inverse(inverse_samples())), "format_version": 99}, "x")
