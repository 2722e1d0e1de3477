"""The Live tab's 3D point-cloud window: the cloud of the frame shown, made on a thread of its own
a few times a second while the window is open."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from PySide6.QtCore import QObject, Qt, QTimer, Signal
from PySide6.QtWidgets import QVBoxLayout, QWidget

from stereo_gui.pipeline.cloud import CloudPoints, cloud_points
from stereo_gui.pipeline.live import LiveOutput
from stereo_gui.qt.widgets.cloud_view import CloudView
from stereo_gui.qt.workers.job_runner import JobRunner

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext

CLOUD_INTERVAL_MS = 400  # the 3D view follows the frames at most this often


class LiveCloud(QObject):
    """Owns the 3D window (made on first use), its timer and its job thread. `output` returns
    the LiveOutput shown (or None)."""

    shown = Signal(CloudPoints)  # after the 3D view drew them

    def __init__(self, ctx: AppContext, owner: QWidget,
                 output: Callable[[], LiveOutput | None]) -> None:
        super().__init__(owner)
        self._owner = owner
        self._output = output
        self.window: QWidget | None = None
        self.view: CloudView | None = None  # once the window exists
        self._jobs = JobRunner("cloud", self)  # its own thread: clicks do not wait on it
        ctx.workers.register(self._jobs)
        self._jobs.finished.connect(self._done)
        self._jobs.failed.connect(self._failed)
        self._job: int | None = None
        # (output, colouring) the cloud shown was made from
        self._made_of: tuple[LiveOutput, str] | None = None
        self._timer = QTimer(self)
        self._timer.setInterval(CLOUD_INTERVAL_MS)
        self._timer.timeout.connect(self.update)

    def show(self) -> QWidget:
        """Open (or raise) the 3D view of the frame shown."""
        if self.window is None:
            win = QWidget(self._owner, Qt.WindowType.Window)
            win.setWindowTitle("Stereo GUI – 3D point cloud of the frame shown")
            self.view = view = CloudView(win)
            view.colouringChanged.connect(lambda _c: self.update())
            lay = QVBoxLayout(win)
            lay.setContentsMargins(0, 0, 0, 0)
            lay.addWidget(view)
            win.resize(720, 540)
            self.window = win
        self.window.show()
        self.window.raise_()
        self._timer.start()
        self.update()
        return self.window

    def update(self) -> None:
        """While the window is open: the newest frame's cloud, made on the cloud thread; one at
        a time (a frame that arrives meanwhile waits for the next tick)."""
        win = self.window
        if win is None or not win.isVisible():
            self._timer.stop()
            return
        out, view = self._output(), self.view  # (the window holds its view)
        if out is None or view is None or self._job is not None or view.problem:
            return
        colouring = view.colouring
        if self._made_of == (out, colouring):
            return
        result = out.result
        self._made_of = (out, colouring)
        self._job = self._jobs.submit(lambda _control: cloud_points(result, colouring)).id

    def _done(self, job_id: int, cloud: CloudPoints) -> None:
        if job_id != self._job:
            return
        self._job = None
        if self.view is not None:
            self.view.show_points(cloud)
            self.shown.emit(cloud)

    def _failed(self, job_id: int, message: str) -> None:
        if job_id == self._job:
            self._job = None
            if self.view is not None:
                self.view.show_problem(f"No point cloud: {message}")

    def shutdown(self) -> None:
        self._timer.stop()
        if self.window is not None:
            self.window.close()
