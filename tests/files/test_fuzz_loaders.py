"""Seeded mutation fuzzing of every loader: any input gives our clean error or a result that
passes validation, never another exception (issue 13, item 5).

Each loader gets a valid file made here, then FUZZ_EXAMPLES mutated copies (bytes flipped,
cut, repeated; JSON and YAML values replaced by hostile ones: NaN, -1, 1e308, huge integers,
lists where objects belong, deep nesting, 128 KiB strings). Seeds are fixed, so a failure
repeats. `STEREO_GUI_FUZZ_EXAMPLES=5000` runs a longer campaign.
"""

from __future__ import annotations

import json
import math
import os
import random

import numpy as np
import pytest

from stereo_gui.core.errors import StereoGuiError

EXAMPLES = int(os.environ.get("STEREO_GUI_FUZZ_EXAMPLES", "120"))
HOSTILE = [float("nan"), float("inf"), -1, 0, -0.0, 1e308, -1e308, 1e-300, 10**30, 99999999999,
           True, None, "", "x" * 131_073, [], {}, [[1]], {"a": 1}, "../../etc/passwd", "NaN"]
HOSTILE_TEXT = ["nan", ".nan", "-1", "0", "1e308", "-1e308", "1e-300", "99999999999", "[]",
                "{}", "[" * 200, "x" * 140_000, "\x00", "é€", "!!opencv-matrix", "rows: 4"]


def _mutate_bytes(data: bytes, rng: random.Random) -> bytes:
    b = bytearray(data)
    kind = rng.randrange(6)
    if kind == 0 and b:  # truncation
        return bytes(b[: rng.randrange(len(b))])
    if kind == 1 and b:  # flip bytes
        for _ in range(rng.randint(1, 8)):
            b[rng.randrange(len(b))] = rng.randrange(256)
        return bytes(b)
    if kind == 2 and b:  # repeat a slice
        i = rng.randrange(len(b))
        j = min(len(b), i + rng.randint(1, 200))
        return bytes(b[:j] + b[i:j] * rng.randint(1, 50) + b[j:])
    if kind == 3:  # a hostile token into the text
        i = rng.randrange(len(b) + 1)
        return bytes(b[:i]) + rng.choice(HOSTILE_TEXT).encode() + bytes(b[i:])
    if kind == 4 and b:  # replace a number by a hostile one
        text = b.decode("utf-8", "replace")
        import re

        nums = list(re.finditer(r"-?\d+(\.\d+)?(e[-+]?\d+)?", text))
        if nums:
            m = rng.choice(nums)
            text = text[: m.start()] + rng.choice(HOSTILE_TEXT[:8]) + text[m.end():]
            return text.encode()
        return bytes(b)
    return bytes(b[::-1]) if rng.random() < 0.1 else bytes(b)


def _mutate_json(doc, rng: random.Random):
    """A copy of `doc` with one value (at any depth) replaced by a hostile one."""
    doc = json.loads(json.dumps(doc))
    if rng.random() < 0.05:
        return rng.choice([[doc], "x", 1, None, {"deep": json.loads("[" * 500 + "]" * 500)}])
    paths = []

    def walk(node, path):
        paths.append(path)
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, path + [k])
        elif isinstance(node, list):
            for i, v in enumerate(node):
                walk(v, path + [i])

    walk(doc, [])
    path = rng.choice(paths[1:] or paths)
    if not path:
        return rng.choice(HOSTILE)
    parent = doc
    for k in path[:-1]:
        parent = parent[k]
    if rng.random() < 0.15 and isinstance(parent, dict):
        del parent[path[-1]]
    else:
        parent[path[-1]] = rng.choice(HOSTILE)
    return doc


def _json_bytes(doc) -> bytes:
    return json.dumps(doc, allow_nan=True).encode()


def _cases(valid: bytes, doc, seed: int):
    rng = random.Random(seed)
    for i in range(EXAMPLES):
        if doc is not None and i % 2 == 0:
            yield _json_bytes(_mutate_json(doc, rng))
        else:
            yield _mutate_bytes(valid, rng)


def _fuzz(path, valid: bytes, doc, load, check, seed: int) -> int:
    """Run the loader on every mutation; return how many loaded (and passed `check`)."""
    loaded = 0
    for data in _cases(valid, doc, seed):
        path.write_bytes(data)
        try:
            result = load(path)
        except StereoGuiError:
            continue
        check(result)
        loaded += 1
    return loaded


# ---- the loaders ----------------------------------------------------------------------------
def test_calibration_files(tmp_path):
    from test_calibration_file import make_calibration

    from stereo_gui.files.calibration_file import check_calibration, load_calibration, save_calibration

    good = save_calibration(make_calibration(), tmp_path / "good.yaml").read_bytes()
    loaded = _fuzz(tmp_path / "c.yaml", good, None, load_calibration,
                   lambda c: check_calibration(c, "fuzzed"), seed=1)
    assert loaded < EXAMPLES  # the mutations do reach the validation


def test_ros_camera_info(tmp_path):
    from test_calibration_file import make_calibration

    from stereo_gui.files.calibration_file import export_ros, import_ros

    left, right = export_ros(make_calibration(), tmp_path)
    good = left.read_bytes()

    def load(path):
        return import_ros(path, right)

    def check(calib):
        assert np.all(np.isfinite(calib.Q))

    _fuzz(tmp_path / "l.yaml", good, None, load, check, seed=2)


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

    _fuzz(folder / "session.json", good, doc, load, check, seed=3)


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

    _fuzz(folder / "recording.json", header, json.loads(header), load, check, seed=4)
    (folder / "recording.json").write_bytes(header)
    _fuzz(folder / "frames.csv", frames, None, load, check, seed=5)


def test_fits(tmp_path):
    from stereo_gui.core.regression import fit_inverse
    from stereo_gui.files.fit_file import load_fit, save_fit

    samples = [(d, 82500.0 / d) for d in np.linspace(30, 90, 12)]
    good = save_fit(fit_inverse(samples), tmp_path / "good.json").read_bytes()

    def check(fit):
        assert all(math.isfinite(c) for c in fit.coefficients)
        assert all(math.isfinite(d) and math.isfinite(z) and z > 0 for d, z in fit.samples)
        fit.predict(50.0)

    _fuzz(tmp_path / "f.json", good, json.loads(good), load_fit, check, seed=6)


def test_presets(tmp_path):
    from stereo_gui.core.matching import Preset
    from stereo_gui.files.presets import load_preset
    from stereo_gui.resources import resource_path

    good = resource_path("presets", "live.json").read_bytes()

    def check(params):
        assert isinstance(params, Preset)
        Preset.from_dict(params.to_dict())  # what was accepted passes validation again

    _fuzz(tmp_path / "p.json", good, json.loads(good), lambda p: load_preset(str(p)), check,
          seed=7)


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

    loaded = _fuzz(tmp_path / "settings.json", good, json.loads(good), load, check, seed=8)
    assert loaded == EXAMPLES


def test_sim_truth(tmp_path):
    from stereo_gui.sources.sim import SimRig, load_truth

    good = json.dumps(SimRig(seed=0).truth.to_json()).encode()

    def check(truth):
        assert truth.baseline_mm > 0 and np.all(np.isfinite(truth.M1))

    _fuzz(tmp_path / "truth.json", good, json.loads(good), load_truth, check, seed=9)


@pytest.mark.parametrize("what", ["calibration", "json"])
def test_hundred_thousand_deep_and_huge_fields(tmp_path, what):
    from stereo_gui.files.calibration_file import load_calibration
    from stereo_gui.files.fit_file import load_fit

    path = tmp_path / "x"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(StereoGuiError):
        (load_calibration if what == "calibration" else load_fit)(path)
