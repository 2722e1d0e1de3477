"""Ctrl+C in the terminal that started the window, and SIGTERM, close it as Ctrl+Q does: through
the close path, without a KeyboardInterrupt printed, without hanging."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

READY = "start-up objects frozen"  # what -v logs once the window is shown


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.slow
def test_a_signal_closes_the_window_through_its_close_path(signum, tmp_path):
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    proc = subprocess.Popen([sys.executable, "-m", "stereo_gui", "--source", "sim", "-v"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env=env)
    seen = []
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            line = proc.stderr.readline()
            if not line:
                break
            seen.append(line)
            if READY in line:
                break
        assert any(READY in s for s in seen), "".join(seen[-20:])
        time.sleep(1.0)
        proc.send_signal(signum)
        _out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err[-2000:]
    assert "KeyboardInterrupt" not in err and "Traceback" not in err
    from stereo_gui.files.settings import settings_path

    assert json.loads(settings_path().read_text())["window_geometry"]  # the close path ran
