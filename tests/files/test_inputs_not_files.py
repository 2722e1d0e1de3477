"""Files a person names that are no files: a device that never ends, a pipe that waits for
ever, a name the system cannot take. Each is refused by name at once."""

from __future__ import annotations

import os

import pytest

from stereo_gui.core.errors import InputError


@pytest.fixture
def fifo(tmp_path):
    path = tmp_path / "pipe.json"
    os.mkfifo(path)
    return path


def test_a_fit_from_a_device_or_a_pipe_is_refused(fifo):
    from stereo_gui.files.fit_file import load_fit

    for path in ("/dev/zero", fifo):
        with pytest.raises(InputError, match="not a regular file"):
            load_fit(path)


def test_a_preset_from_a_pipe_and_a_name_too_long(fifo):
    from stereo_gui.files.presets import load_preset

    with pytest.raises(InputError, match="not a regular file"):
        load_preset(str(fifo))
    with pytest.raises(InputError, match="unknown preset"):
        load_preset("p" * 300)


def test_a_scene_list_from_a_pipe(fifo):
    from stereo_gui.files.scenes import read_scene_list

    with pytest.raises(InputError, match="not a regular file"):
        read_scene_list(fifo)


def test_settings_that_are_a_pipe_start_with_the_defaults():
    from stereo_gui.files.settings import Settings, load_settings, settings_path

    settings_path().parent.mkdir(parents=True, exist_ok=True)
    os.mkfifo(settings_path())
    settings, warnings = load_settings()
    assert settings == Settings() and any("not a regular file" in w for w in warnings)
