"""Choose a folder, or a file to save, in a folder that may not exist yet: a folder typed in the
dialog that is no folder yet is offered for creation (Qt's own folder dialog only says "Directory
not found", and its save dialog accepts the path and leaves the writer to fail)."""

from __future__ import annotations

import logging
from pathlib import Path

from PySide6.QtWidgets import QFileDialog, QMessageBox, QWidget

from stereo_gui.files.atomic import os_error_text

log = logging.getLogger(__name__)


class FolderDialog(QFileDialog):
    """A folder dialog (Qt's own, the same on every system) whose OK, for a path that does not
    exist yet, asks whether to create that folder, creates it and accepts it."""

    def __init__(self, parent: QWidget | None, title: str, start: str = "") -> None:
        super().__init__(parent, title, start)
        self.setFileMode(QFileDialog.FileMode.Directory)
        self.setOption(QFileDialog.Option.ShowDirsOnly, True)
        self.setOption(QFileDialog.Option.DontUseNativeDialog, True)
        self.created: Path | None = None  # the folder this dialog made, if any

    def chosen(self) -> str:
        """The folder chosen or typed (an absolute path), "" when none."""
        files = self.selectedFiles()
        return files[0] if files else ""

    def accept(self) -> None:
        typed = self.chosen()
        if typed and not Path(typed).exists():
            folder = Path(typed)
            if not _create_folder(self, folder):
                return
            self.created = folder
        super().accept()


def choose_folder(parent: QWidget | None, title: str, start: str = "") -> str:
    """Ask for a folder, existing or new (created after asking); "" when cancelled."""
    dialog = FolderDialog(parent, title, start)
    return dialog.chosen() if dialog.exec() else ""


def _create_folder(parent: QWidget | None, folder: Path) -> bool:
    """Ask whether to create `folder` and do so; False when the person says no or it fails
    (said in a message box)."""
    answer = QMessageBox.question(
        parent, "Create the folder", f"There is no folder {folder} yet. Create it?",
        QMessageBox.StandardButton.Yes | QMessageBox.StandardButton.No,
        QMessageBox.StandardButton.Yes)
    if answer != QMessageBox.StandardButton.Yes:
        return False
    try:
        folder.mkdir(parents=True)
    except OSError as exc:
        QMessageBox.warning(parent, "Create the folder",
                            f"Cannot create {folder}: {os_error_text(exc)}")
        return False
    log.info("created the folder %s", folder)
    return True


def save_file_name(parent: QWidget | None, title: str, start: str = "",
                   filters: str = "") -> tuple[str, str]:
    """QFileDialog.getSaveFileName, and a file in a folder that does not exist yet has that
    folder offered for creation: ("", "") when cancelled or declined."""
    path, chosen = QFileDialog.getSaveFileName(parent, title, start, filters)
    if path and not Path(path).parent.exists() and not _create_folder(parent,
                                                                        Path(path).parent):
        return "", ""
    return path, chosen
