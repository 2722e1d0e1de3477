"""Property tests of every loader with hypothesis: any damaged copy of a valid file gives our
clean error or a result that passes validation, never another exception.

Each loader gets a valid file made here, then EXAMPLES damaged copies (tests/files/mutations.py:
bytes cut, flipped, repeated; JSON values replaced by hostile ones). Hypothesis runs
derandomized, so a failure repeats, and shrinks it to a small damage.
`STEREO_GUI_FUZZ_EXAMPLES=5000` runs a longer campaign.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from stereo_gui.core.errors import StereoGuiError

from mutations import damaged

EXAMPLES = int(os.environ.get("STEREO_GUI_FUZZ_EXAMPLES", "100"))
FUZZ = settings(max_examples=EXAMPLES, derandomize=True, database=None, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _fuzz(path, valid: bytes, doc, load, check) -> list[bool]:
    """Write each damaged copy of `valid` (`doc`: its JSON document) to `path` and load it: our
    clean error, or a result `check` accepts. Returns, per copy, whether it loaded."""
    loaded: list[bool] = []

    @FUZZ
    @given(data=damaged(valid, doc))
    def refused_or_valid(data: bytes) -> None:
        path.write_bytes(data)
        try:
            result = load(path)
        except StereoGuiError:
            loaded.append(False)
            return
        check(result)
        loaded.append(True)

    refused_or_valid()
    return loaded


# ---- the loaders ----------------------------------------------------------------------------
def test_calibration_files(tmp_path):
    from factories import make_calibration

    from stereo_gui.core.plausibility import check_plausible
    from stereo_gui.files.calibration_file import load_calibration, save_calibration

    good = save_calibration(make_calibration(), tmp_path / "good.yaml").read_bytes()
    loaded = _fuzz(tmp_path / "c.yaml", good, None, load_calibration,
                   lambda c: check_plausible(c, "fuzzed"))
    assert not all(loaded)  # the damage does reach the validation


def test_ros_camera_info(tmp_path):
    from factories import make_calibration

    from stereo_gui.files.calibration_file import export_ros, import_ros

    left, right = export_ros(make_calibration(), tmp_path)
    good = left.read_bytes()

    def load(path):
        return import_ros(path, right)

    def check(calib):
        assert np.all(np.isfinite(calib.Q))

    _fuzz(tmp_path / "l.yaml", good, None, load, check)


def test_sessions(tmp_path):
    import cv2

    from stereo_gui.files.session import CaptureSession

    folder = tmp_path / "s"
    s = CaptureSession.create(folder, resolution=(16, 12))
    img = np.zeros((12, 16, 3), np.uint8)
    s.add_pair(img, img)
    s.add_pair(img, img)
    good = s.manifest_path.read_bytes()
    doc = json.loads(good)
    outside = tmp_path.resolve()
    assert cv2  # images are read by the session's size probe

    def load(path):
        for p in folder.glob("session.json.unreadable*"):
            p.unlink()
        return CaptureSession.open(folder)

    def check(session):
        numbers = [p.number for p in session.pairs]
        assert len(set(numbers)) == len(numbers)
        for p in session.pairs:
            for f in (p.left, p.right):
                assert f.resolve().is_relative_to(folder.resolve()), f
                assert f.resolve() != outside

    _fuzz(folder / "session.json", good, doc, load, check)


def test_recordings(tmp_path):
    from stereo_gui.files.recording import RecordingWriter, open_recording
    from stereo_gui.sources.base import StereoFrame

    folder = tmp_path / "rec"
    with RecordingWriter(folder, background=False) as w:
        for i in range(3):
            img = np.full((8, 8, 3), i * 40, np.uint8)
            w.write(StereoFrame(img, img, 10.0 + i / 30, 10.0 + i / 30, i))
    header = (folder / "recording.json").read_bytes()
    frames = (folder / "frames.csv").read_bytes()

    def check(rec):
        idx = [f.index for f in rec.frames]
        assert idx == sorted(set(idx)) and all(i >= 0 for i in idx)
        for f in rec.frames:
            assert math.isfinite(f.t_left) and math.isfinite(f.t_right)
            for p in (f.left, f.right):
                assert p is None or p.resolve().is_relative_to(folder.resolve())
        assert math.isfinite(rec.fps) and rec.fps > 0

    def load(_path):
        return open_recording(folder)

    _fuzz(folder / "recording.json", header, json.loads(header), load, check)
    (folder / "recording.json").write_bytes(header)
    _fuzz(folder / "frames.csv", frames, None, load, check)


def test_fits(tmp_path):
    from stereo_gui.core.regression import fit_inverse
    from stereo_gui.files.fit_file import load_fit, save_fit

    samples = [(d, 82500.0 / d) for d in np.linspace(30, 90, 12)]
    good = save_fit(fit_inverse(samples), tmp_path / "good.json").read_bytes()

    def check(fit):
        assert all(math.isfinite(c) for c in fit.coefficients)
        assert all(math.isfinite(d) and math.isfinite(z) and z > 0 for d, z in fit.samples)
        fit.predict(50.0)

    _fuzz(tmp_path / "f.json", good, json.loads(good), load_fit, check)


def test_presets(tmp_path):
    from stereo_gui.core.preset import Preset
    from stereo_gui.files.presets import load_preset
    from stereo_gui.resources import resource_path

    good = resource_path("presets", "live.json").read_bytes()

    def check(params):
        assert isinstance(params, Preset)
        Preset.from_dict(params.to_dict())  # what was accepted passes validation again

    _fuzz(tmp_path / "p.json", good, json.loads(good), lambda p: load_preset(str(p)), check)


def test_settings(tmp_path):
    from stereo_gui.files.settings import Settings, load_settings, save_settings, settings_from_dict

    good = save_settings(Settings(recent_files=("/a.yaml",), last_session="/s"),
                         tmp_path / "good.json").read_bytes()

    def load(path):
        settings, warnings = load_settings(path)  # never raises
        return settings

    def check(settings):
        assert isinstance(settings, Settings)
        back, problems = settings_from_dict(json.loads(json.dumps(
            {k: list(v) if isinstance(v, tuple) else v for k, v in settings.__dict__.items()})))
        assert problems == []
        assert settings.window_geometry.isascii()

    loaded = _fuzz(tmp_path / "settings.json", good, json.loads(good), load, check)
    assert all(loaded)  # loading settings never refuses: it warns and goes on


def test_sim_truth(tmp_path):
    from stereo_gui.sources.sim import SimRig, load_truth

    good = json.dumps(SimRig(seed=0).truth.to_json()).encode()

    def check(truth):
        assert truth.baseline_mm > 0 and np.all(np.isfinite(truth.M1))

    _fuzz(tmp_path / "truth.json", good, json.loads(good), load_truth, check)


@pytest.mark.parametrize("what", ["calibration", "json"])
def test_hundred_thousand_deep_and_huge_fields(tmp_path, what):
    from stereo_gui.files.calibration_file import load_calibration
    from stereo_gui.files.fit_file import load_fit

    path = tmp_path / "x"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(StereoGuiError):
        (load_calibration if what == "calibration" else load_fit)(path)
