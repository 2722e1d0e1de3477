"""The Live tab's depth stream for robots' programs: the Stream switch (and File menu's), the
line saying where it is served and to how many clients, and the MCAP recording of the same
topics. The frames are published by the processor in the frame worker's lanes
(`LiveProcessor.set_stream`); here the stream is started, stopped and shown. The readings a
person takes (double-clicks, the ruler) are published as they are logged."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from PySide6.QtCore import QObject, Qt, QTimer, Signal
from PySide6.QtWidgets import QLabel, QPushButton, QSizePolicy, QWidget

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.files.measurement_record import MeasurementRecord
from stereo_gui.pipeline.live import LiveProcessor
from stereo_gui.pipeline.stream import DepthStream, StreamStats, record_message
from stereo_gui.qt.widgets import folder_dialog

if TYPE_CHECKING:
    from stereo_gui.qt.context import AppContext

log = logging.getLogger(__name__)

HOST = "127.0.0.1"  # the window serves this machine only (`stereo-gui serve --host` for more)
LINE_EVERY_MS = 1000


class LiveStream(QObject):
    """Owns the Stream button, its line and the DepthStream (made when first switched on).
    `processor` returns the LiveProcessor in use (or None)."""

    changed = Signal(bool)  # streaming on or off (the File menu's action follows)
    # the MCAP file being recorded (Path), None when none: object, as a Signal(Path) would
    # promise a Path every time
    recordingChanged = Signal(object)

    def __init__(self, ctx: AppContext, owner: QWidget,
                 processor: Callable[[], LiveProcessor | None]) -> None:
        super().__init__(owner)
        self.ctx = ctx
        self._processor = processor
        self._stream: DepthStream | None = None  # while serving or recording
        self.button = QPushButton("Stream")
        self.button.setCheckable(True)
        self.button.setToolTip("Serve the depth to robots' programs and Foxglove on this machine "
                               "(Foxglove WebSocket; File > Record MCAP… records the same)")
        self.button.toggled.connect(self._toggled)
        self.label = QLabel()
        self.label.setTextFormat(Qt.TextFormat.PlainText)
        self.label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.label.hide()
        self._timer = QTimer(self)
        self._timer.setInterval(LINE_EVERY_MS)
        self._timer.timeout.connect(self._update_line)

    # ---- state -------------------------------------------------------------------------------
    @property
    def serving(self) -> bool:
        return self._stream is not None and self._stream.address is not None

    @property
    def recording(self) -> Path | None:
        st = self._stream.stats() if self._stream is not None else None
        return Path(st.recording) if st is not None and st.recording else None

    def address(self) -> str | None:
        return self._stream.address if self._stream is not None else None

    def stats(self) -> StreamStats | None:
        return self._stream.stats() if self._stream is not None else None

    def restore(self) -> None:
        """Stream again when the last run did (the settings)."""
        s = self.ctx.settings
        if s is not None and s.stream_on:
            self.button.setChecked(True)

    # ---- switching ---------------------------------------------------------------------------
    def set_on(self, on: bool) -> None:
        self.button.setChecked(on)

    def _toggled(self, on: bool) -> None:
        if on:
            on = self._start_server()
            if not on:
                self.button.blockSignals(True)
                self.button.setChecked(False)
                self.button.blockSignals(False)
        else:
            self._stop_server()
        if self.ctx.settings is not None and self.ctx.settings.stream_on != on:
            self.ctx.settings_model.update(stream_on=on)
        self._update_line()
        self.changed.emit(on)

    def _ensure_stream(self) -> DepthStream:
        if self._stream is None:
            self._stream = stream = DepthStream()
            self.apply()
            return stream
        return self._stream

    def _start_server(self) -> bool:
        port = self.ctx.settings.stream_port if self.ctx.settings is not None else 8765
        try:
            address = self._ensure_stream().serve(HOST, port)
        except StereoGuiError as exc:
            self._drop_if_idle()
            self.ctx.report_error(f"Cannot stream the depth: {exc}")
            return False
        self.ctx.show_status(f"Streaming the depth on {address} (Foxglove: Open connection, "
                             "Foxglove WebSocket)")
        return True

    def _stop_server(self) -> None:
        if self._stream is None:
            return
        server_only = self.recording is None
        if server_only:
            self._close_stream()
        else:  # the recording goes on: only the server stops
            self._stream.stop_server()

    def toggle_recording(self, parent: QWidget, path: str | None = None) -> Path | None:
        """Start an MCAP recording (asks for the file without `path`), or stop the one
        running; the file being recorded, None when none."""
        if self.recording is not None:
            self.stop_recording()
            return None
        if not path:
            settings = self.ctx.settings
            start = Path((settings.recordings_dir if settings else None) or Path.home())
            path, _ = folder_dialog.save_file_name(parent, "Record the depth as MCAP",
                                                  str(start / "stereo-depth.mcap"),
                                                  "MCAP recordings (*.mcap)")
            if not path:
                return None
            if not path.lower().endswith(".mcap"):
                path += ".mcap"
        return self.start_recording(path)

    def start_recording(self, path: str | Path) -> Path | None:
        """Record the stream's topics to the MCAP file `path` (None when it cannot be made: the
        window says why)."""
        try:
            made = self._ensure_stream().record(path)
        except StereoGuiError as exc:
            self._drop_if_idle()
            self.ctx.report_error(f"Cannot record MCAP: {exc}")
            return None
        self._update_line()
        self.recordingChanged.emit(made)
        return made

    def stop_recording(self) -> Path | None:
        """Finish the MCAP file (renamed into place once whole); its path."""
        if self._stream is None:
            return None
        try:
            done = self._stream.stop_recording()
        except StereoGuiError as exc:
            self.ctx.report_error(f"The MCAP recording could not be finished: {exc}")
            done = None
        self._drop_if_idle()
        self._update_line()
        self.recordingChanged.emit(None)
        if done is not None:
            self.ctx.show_status(f"Recorded {done}")
        return done

    def _drop_if_idle(self) -> None:
        if self._stream is not None and self._stream.address is None and self.recording is None:
            self._close_stream()

    def _close_stream(self) -> None:
        stream, self._stream = self._stream, None
        self.apply()
        if stream is not None:
            try:
                stream.close()
            except StereoGuiError as exc:
                self.ctx.report_error(f"The MCAP recording could not be finished: {exc}")

    def apply(self) -> None:
        """Hand the stream to the processor in use (called again when the processor changes)."""
        processor = self._processor()
        if processor is not None:
            processor.set_stream(self._stream)

    def shutdown(self) -> None:
        """The window closes: stop serving, finish the recording (the setting is kept)."""
        self._timer.stop()
        self._close_stream()

    # ---- what it shows -----------------------------------------------------------------------
    def _update_line(self) -> None:
        st = self.stats()
        active = st is not None and (st.address is not None or st.recording is not None)
        self.label.setVisible(active)
        if st is None or not active:
            self._timer.stop()
            return
        if not self._timer.isActive():
            self._timer.start()
        parts = []
        if st.address is not None:
            clients = f"{st.clients} client" + ("" if st.clients == 1 else "s")
            parts.append(f"Streaming on {st.address}: {clients}")
        if st.recording is not None:
            parts.append(f"recording {Path(st.recording).name}")
        rate = f"{st.fps:.0f} frames/s" if st.fps else "no frames yet (the Live tab publishes)"
        self.label.setText(", ".join(parts) + f" · {rate}")

    def publish_record(self, record: MeasurementRecord) -> None:
        """Publish a reading just logged (a files.measurement_record.MeasurementRecord)."""
        if self._stream is None:
            return
        self._stream.publish_reading(record_message(record), time.monotonic())
