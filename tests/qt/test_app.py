"""The application shell: start and auto-quit, the Qt binding's soundness, start-up arguments."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from PySide6.QtCore import QObject, Signal


class _Emitter(QObject):
    ping = Signal()
    value = Signal(object)


def test_signal_emit_keeps_bool_references(qapp):
    """PySide6 6.12.0 drops a reference to True on every Python emit(); a live view emits
    thousands of signals and the interpreter aborts ("bool_dealloc"). pyproject excludes it."""
    e = _Emitter()
    e.ping.connect(lambda: None)
    e.value.connect(lambda v: None)
    before = sys.getrefcount(True)
    for _ in range(200):
        e.ping.emit()
        e.value.emit(1)
    assert sys.getrefcount(True) >= before - 5
