"""A preset and its declarations: validation, the flat file object, derived values."""

import math

import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.core.preset import DisplayParams, MatcherParams, Preset, ThreadParams
from stereo_gui.core.stereo_calibration import StereoCalibration

W, H = 240, 160  # px


def calib(w=W, h=H, f=300.0, b=100.0):
    return StereoCalibration.identity((w, h), f, b)


def test_params_validate_and_round_trip():
    with pytest.raises(InputError, match="block_size"):
        MatcherParams(block_size=4)
    with pytest.raises(InputError, match="num_disparities"):
        MatcherParams(num_disparities=100)
    with pytest.raises(InputError, match="mode"):
        MatcherParams(mode="fast")
    p = Preset("x", matcher=MatcherParams(mode="3way", scale=0.5, z_min_mm=400.0),
               display=DisplayParams(colormap="jet"), threads=ThreadParams(parallel=True))
    assert Preset.from_dict(p.to_dict()) == p
    assert Preset.from_dict({"block_size": 5, "no_such_key": 1}).matcher.block_size == 5
    # the reference loop's own names are understood
    reference = Preset.from_dict({"window_size": 3, "minDisparity": 2, "numDisparities": 128,
                               "lmbda": 80000}).matcher
    assert (reference.block_size, reference.min_disparity, reference.wls_lambda) == (3, 2, 80000)
    with pytest.raises(InputError, match="must be a number"):
        Preset.from_dict({"block_size": "5"})
    with pytest.raises(InputError, match="true or false"):
        Preset.from_dict({"wls": 1})
    with pytest.raises(InputError, match="whole number"):
        Preset.from_dict({"block_size": 3.5})
    assert Preset.from_dict({"block_size": 5.0}).matcher.block_size == 5
    with pytest.raises(InputError, match="color_z_far_mm"):
        Preset.from_dict({"color_z_near_mm": 900, "color_z_far_mm": 800})
    with pytest.raises(InputError, match="cv_threads"):
        Preset.from_dict({"cv_threads": -1})


def test_a_preset_is_a_flat_object_of_its_parts_fields_in_the_files_order():
    """Files hold one flat object: the matcher's, display's and threads' fields after the name,
    as before the parts were split; a flat change goes to the part that declares the field."""
    d = Preset().to_dict()
    assert list(d)[:3] == ["name", "description", "block_size"]
    assert list(d)[-6:] == ["colormap", "color_range", "color_z_near_mm", "color_z_far_mm",
                            "parallel", "cv_threads"]
    p = Preset().replace(name="n", block_size=5, colormap="jet", parallel=True)
    assert (p.name, p.matcher.block_size, p.display.colormap, p.threads.parallel) == \
        ("n", 5, "jet", True)
    assert p.get("colormap") == "jet" and p.get("block_size") == 5
    with pytest.raises(TypeError):
        Preset().replace(no_such_parameter=1)


def test_default_penalties_are_the_reports():
    p = MatcherParams(block_size=3)
    assert (p.p1_value, p.p2_value) == (8 * 3 * 9, 32 * 3 * 9)
    assert MatcherParams(p1=10, p2=99).p2_value == 99


def test_disparity_range_from_working_distances():
    c = calib(f=700.0, b=110.0)  # f*B = 77000 px mm
    lo, num = MatcherParams(z_min_mm=500.0).disparity_range(c)
    assert lo == 0 and num % 16 == 0 and lo + num - 1 >= 154 and num - 16 < 155
    lo, num = MatcherParams(z_min_mm=500.0, z_max_mm=2000.0).disparity_range(c)
    assert lo == math.floor(77000 / 2000) and lo + num - 1 >= 154
    assert MatcherParams(min_disparity=2, num_disparities=128).disparity_range(c) == (2, 128)


def test_new_parameters_validate():
    with pytest.raises(InputError, match="remap_interpolation"):
        MatcherParams(remap_interpolation="nearest")
    with pytest.raises(InputError, match="pre_filter_cap"):
        MatcherParams(pre_filter_cap=64)
    with pytest.raises(InputError, match="true or false"):
        Preset.from_dict({"full_frame": "yes"})
