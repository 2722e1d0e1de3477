"""Fixtures for the Qt tests: an app context whose workers are always stopped, small sources."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from stereo_gui.core.board import BoardSpec
from stereo_gui.core.jobs import JobControl
from stereo_gui.pipeline.calibration import calibration_job
from stereo_gui.sources.base import FrameSource, StereoFrame
from stereo_gui.sources.sim import write_calibration_set


class ArraySource(FrameSource):
    """A frame source that repeats one stereo pair (made in the test), optionally paced.

    Sources are real FrameSource implementations; this one exists because tests need a source
    whose every pixel is known, without rendering cost.
    """

    def __init__(self, left: np.ndarray, right: np.ndarray, fps: float = 200.0, truth=None,
                 name: str = "test pair") -> None:
        self.left, self.right = left, right
        self.name = name
        self.nominal_fps = fps
        self.truth = truth
        self._i = 0
        self._next = time.monotonic()
        self.closed = threading.Event()

    def read(self) -> StereoFrame:
        if self.closed.is_set():
            from stereo_gui.core.errors import SourceError

            raise SourceError(f"{self.name} is closed")
        now = time.monotonic()
        if self._next > now:
            # pacing like a camera; short, so a stop request is never held up for long
            time.sleep(self._next - now)
        self._next = max(now, self._next) + 1.0 / self.nominal_fps
        self._i += 1
        t = time.monotonic()
        return StereoFrame(self.left, self.right, t, t, self._i, self.truth)

    def close(self) -> None:
        self.closed.set()


@pytest.fixture
def array_source():
    """A factory of ArraySource: array_source(left=None, right=None, fps=200)."""
    made = []

    def make(left=None, right=None, fps=200.0, truth=None):
        if left is None:
            rng = np.random.default_rng(1)
            left = rng.integers(0, 255, (48, 64, 3), dtype=np.uint8)
        if right is None:
            right = left.copy()
        s = ArraySource(left, right, fps, truth)
        made.append(s)
        return s

    yield make


@pytest.fixture
def ctx(qtbot):
    """An AppContext whose workers are stopped and joined after the test (asserted)."""
    from stereo_gui.qt.context import AppContext

    c = AppContext()
    yield c
    assert c.shutdown(2000), "a worker did not stop within 2 s"
    assert not c.frames.is_running()


@pytest.fixture
def make_tab(qtbot, ctx):
    """make_tab(TabClass): a tab on `ctx`, shut down after the test (its threads joined)."""
    made = []

    def make(cls):
        tab = cls(ctx)
        qtbot.addWidget(tab)
        made.append(tab)
        return tab

    yield make
    for tab in made:
        assert tab.shutdown(timeout_ms=2000), f"{type(tab).__name__} did not stop within 2 s"


@pytest.fixture
def live(qtbot, ctx):
    """The Live tab, shown at 1000x700 and active (its processor installed)."""
    from stereo_gui.qt.tabs.live import LiveTab

    tab = LiveTab(ctx)
    qtbot.addWidget(tab)
    tab.resize(1000, 700)
    tab.show()
    tab.set_active(True)
    return tab


@pytest.fixture
def window(qtbot, ctx):
    """The main window on `ctx`, shown."""
    from stereo_gui.qt.main_window import MainWindow

    w = MainWindow(ctx)
    qtbot.addWidget(w)
    w.show()
    return w


@pytest.fixture(scope="session")
def sim_rig():
    """One simulated rig for the whole session (building its ray maps takes seconds)."""
    from stereo_gui.sources.sim import SimRig

    return SimRig(seed=0)


@pytest.fixture(scope="session")
def wall_pair(sim_rig):
    """(scene, left, right) of a textured wall at 1.5 m rendered by the simulated rig."""
    from stereo_gui.sources.sim import Scene

    scene = Scene.wall(1500.0)
    left, right = sim_rig.render_scene(scene, np.random.default_rng(3))
    return scene, left, right


class Questions:
    """Stands in for QMessageBox.question: answers `reply` (Yes unless set) and keeps the texts
    asked in `asked`."""

    def __init__(self) -> None:
        from PySide6.QtWidgets import QMessageBox

        self.reply = QMessageBox.StandardButton.Yes
        self.asked: list[str] = []

    def __call__(self, _parent, _title, text, *args, **kwargs):
        self.asked.append(text)
        return self.reply


@pytest.fixture
def questions(monkeypatch):
    """Every QMessageBox.question of the test answered by a `Questions` (set `.reply`)."""
    from PySide6.QtWidgets import QMessageBox

    q = Questions()
    monkeypatch.setattr(QMessageBox, "question", q)
    return q


@pytest.fixture(scope="session")
def calibration_run(tmp_path_factory):
    """A CalibrationRun of the simulated rig, made once (as the Calibration tab's job does)."""
    folder = write_calibration_set(tmp_path_factory.mktemp("calset"), n_pairs=8, seed=5)
    gen = calibration_job(folder, BoardSpec(9, 6, 25.0), 0.0, "bouguet")(JobControl())
    while True:
        try:
            next(gen)
        except StopIteration as stop:
            return stop.value
