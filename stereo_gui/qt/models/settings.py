"""The settings model: the application's frozen `Settings`, replaced only through its methods."""

from __future__ import annotations

import logging
from pathlib import Path

from PySide6.QtCore import QObject, Signal

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.files.settings import Settings, save_settings

log = logging.getLogger(__name__)


class SettingsModel(QObject):
    """Holds the current `stereo_gui.files.settings.Settings` (frozen; read `current`).

    Every change goes through `update` or `remember_recent` and is announced by
    `changed(Settings)`; `save` writes the settings file.
    """

    changed = Signal(Settings)

    def __init__(self, settings: Settings | None = None, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._current = settings if settings is not None else Settings()

    @property
    def current(self) -> Settings:
        return self._current

    def update(self, **changes: object) -> None:
        """Replace settings fields (unknown names raise TypeError, as dataclasses.replace does)."""
        self._set(self._current.with_updates(**changes))

    def remember_recent(self, path: str | Path, **changes: object) -> None:
        """Put `path` first in the recent files (with other `changes` in the same step)."""
        p = str(path)
        if self._current.recent_files[:1] == (p,) and not changes:
            return
        self._set(self._current.with_recent(p).with_updates(**changes))

    def save(self) -> bool:
        """Write the settings file now; False (logged) when it cannot be written."""
        try:
            save_settings(self._current)
        except (StereoGuiError, OSError) as exc:
            log.warning("settings not saved: %s", exc)
            return False
        return True

    def _set(self, settings: Settings) -> None:
        self._current = settings
        self.changed.emit(settings)
