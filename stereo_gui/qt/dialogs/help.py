"""The Help menu: the technician's guide in a window of its own (the Markdown shipped with the
application, with its pictures), the keyboard shortcuts, and where the settings and data are
kept.

`add_help_actions(window, menu, ctx)` puts them into the main window's Help menu.
"""

from __future__ import annotations

import logging
import re
import shutil
import subprocess
import sys
from pathlib import Path

from PySide6.QtCore import Qt, QUrl
from PySide6.QtGui import (
    QAction,
    QDesktopServices,
    QGuiApplication,
    QImage,
    QKeySequence,
    QTextCursor,
    QTextImageFormat,
)
from PySide6.QtWidgets import (
    QDialog,
    QDialogButtonBox,
    QGridLayout,
    QLabel,
    QMenu,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QTextBrowser,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.files.measurement_log import data_dir
from stereo_gui.files.presets import user_preset_dir
from stereo_gui.files.settings import Settings, settings_path
from stereo_gui.qt.context import AppContext
from stereo_gui.qt.workers.recorder import recordings_dir
from stereo_gui.resources import guide_path

log = logging.getLogger(__name__)

GUIDE_SHORTCUT = QKeySequence.StandardKey.HelpContents  # F1
GUIDE_IMAGE_WIDTH_PX = 860  # the guide's screenshots, shrunk to read beside the text

# what has no QAction of its own to read a shortcut from: (keys, what they do)
OTHER_SHORTCUTS: tuple[tuple[str, str], ...] = (
    ("Ctrl+1 … Ctrl+4", "Capture, Calibration, Live, Measurements tab"),
    ("Space", "Live tab: pause or resume (a recording played back: play or pause)"),
    ("S", "Capture tab: save the pair under review"),
    ("C", "Capture tab: cancel the pair under review"),
    ("Del", "Capture tab, saved pairs: delete the pair shown"),
    ("↑ ↓", "Capture tab, saved pairs: review the previous or next pair"),
    ("Double-click", "Live tab: measure there (and log it); Measurements tab: edit a true "
                     "distance or a note"),
    ("Mouse wheel, drag", "Live tab and rectification check: zoom, pan"),
)


def heading_slug(text: str) -> str:
    """The anchor a Markdown renderer (GitHub's) gives a heading: "3. Capture a set" ->
    "3-capture-a-set"."""
    slug = re.sub(r"[^\w\- ]", "", text.strip().lower())
    return slug.replace(" ", "-")


class GuideWindow(QDialog):
    """The guide, rendered from its Markdown, with its pictures; the contents' links move to
    their section, links to the web or to other files open outside."""

    def __init__(self, path: Path, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Stereo GUI: the technician's guide")
        self.path = Path(path)
        self.browser = QTextBrowser()
        self.browser.setOpenLinks(False)
        self.browser.anchorClicked.connect(self._link_clicked)
        self.browser.setSearchPaths([str(self.path.parent)])
        self.browser.document().setBaseUrl(QUrl.fromLocalFile(str(self.path.parent) + "/"))
        self.browser.setMarkdown(self.path.read_text(encoding="utf-8"))
        self._fit_images()
        folder = QPushButton("Show the guide's folder")
        folder.clicked.connect(lambda: open_folder(self.path.parent))
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close)
        buttons.addButton(folder, QDialogButtonBox.ButtonRole.ActionRole)
        buttons.rejected.connect(self.close)
        lay = QVBoxLayout(self)
        lay.addWidget(self.browser, 1)
        lay.addWidget(buttons)
        self.resize(980, 700)

    def _fit_images(self) -> None:
        """Screenshots as wide as a reading column, not the screen they were taken on."""
        doc = self.browser.document()
        block = doc.begin()
        while block.isValid():
            it = block.begin()
            while not it.atEnd():
                frag = it.fragment()
                fmt = frag.charFormat()
                if fmt.isImageFormat():
                    img_fmt = fmt.toImageFormat()
                    image = QImage(str(self.path.parent / img_fmt.name()))
                    if not image.isNull() and image.width() > GUIDE_IMAGE_WIDTH_PX:
                        scaled = QTextImageFormat(img_fmt)
                        scaled.setWidth(GUIDE_IMAGE_WIDTH_PX)
                        scaled.setHeight(GUIDE_IMAGE_WIDTH_PX * image.height() / image.width())
                        cursor = QTextCursor(doc)
                        cursor.setPosition(frag.position())
                        cursor.setPosition(frag.position() + frag.length(),
                                           QTextCursor.MoveMode.KeepAnchor)
                        cursor.setCharFormat(scaled)
                it += 1
            block = block.next()

    def headings(self) -> list[str]:
        """The text of every heading, in order."""
        out = []
        block = self.browser.document().begin()
        while block.isValid():
            if block.blockFormat().headingLevel() > 0:
                out.append(block.text())
            block = block.next()
        return out

    def show_section(self, slug: str) -> bool:
        """Scroll to the heading whose anchor is `slug`; False when there is none."""
        block = self.browser.document().begin()
        while block.isValid():
            if block.blockFormat().headingLevel() > 0 and heading_slug(block.text()) == slug:
                cursor = QTextCursor(block)
                self.browser.setTextCursor(cursor)
                # the heading at the top of the view, not merely somewhere in it
                bar = self.browser.verticalScrollBar()
                bar.setValue(bar.maximum())
                self.browser.ensureCursorVisible()
                return True
            block = block.next()
        return False

    def _link_clicked(self, url: QUrl) -> None:
        if url.scheme() in ("http", "https", "mailto"):
            QDesktopServices.openUrl(url)
            return
        if url.hasFragment() and (not url.path() or url.path().endswith(self.path.name)):
            self.show_section(url.fragment())
            return
        target = (self.path.parent / url.path()).resolve() if not url.isLocalFile() \
            else Path(url.toLocalFile())
        if target.exists():
            QDesktopServices.openUrl(QUrl.fromLocalFile(str(target)))
        else:
            log.info("guide: %s is not shipped with this installation", url.toString())


def shortcut_rows(window: QWidget) -> list[tuple[str, str]]:
    """(keys, what they do) of the window's menu actions with a shortcut, then the others."""
    rows = []
    for action in window.findChildren(QAction):
        keys = action.shortcut().toString(QKeySequence.SequenceFormat.NativeText)
        if keys and action.text():
            rows.append((keys, action.text().replace("&", "").rstrip("…").rstrip(".")))
    return sorted(set(rows)) + list(OTHER_SHORTCUTS)


class ShortcutsDialog(QDialog):
    """The keyboard shortcuts, in a table."""

    def __init__(self, rows: list[tuple[str, str]], parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Keyboard shortcuts")
        self.table = QTableWidget(len(rows), 2)
        self.table.setHorizontalHeaderLabels(["Keys", "What they do"])
        self.table.verticalHeader().hide()
        self.table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        for r, (keys, what) in enumerate(rows):
            self.table.setItem(r, 0, QTableWidgetItem(keys))
            self.table.setItem(r, 1, QTableWidgetItem(what))
        self.table.resizeColumnsToContents()
        self.table.horizontalHeader().setStretchLastSection(True)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close)
        buttons.rejected.connect(self.close)
        lay = QVBoxLayout(self)
        lay.addWidget(self.table, 1)
        lay.addWidget(buttons)
        self.resize(620, 420)

    def rows(self) -> list[tuple[str, str]]:
        return [(self._text(r, 0), self._text(r, 1)) for r in range(self.table.rowCount())]

    def _text(self, row: int, col: int) -> str:
        item = self.table.item(row, col)
        return item.text() if item is not None else ""


def kept_folders(settings: Settings) -> list[tuple[str, Path]]:
    """(what, folder) of everything the application keeps between runs."""
    return [("Settings (settings.json)", settings_path().parent),
            ("Your presets", user_preset_dir()),
            ("The measurement log kept between runs (measurement-log.json)", data_dir()),
            ("New recordings", recordings_dir(settings))]


def file_manager_missing() -> bool:
    """Whether this Linux desktop has nothing to open a folder with (no xdg-open, or no
    application for folders): Qt's openUrl then fails where only the terminal sees it."""
    if not sys.platform.startswith("linux"):
        return False
    if shutil.which("xdg-open") is None:
        return True
    mime = shutil.which("xdg-mime")
    if mime is None:
        return False  # (cannot tell: let xdg-open try)
    try:
        found = subprocess.run([mime, "query", "default", "inode/directory"],
                               capture_output=True, text=True, timeout=3).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return False
    return not found


def open_folder(folder: Path) -> bool:
    """Show `folder` in the system's file manager (False when it cannot)."""
    if file_manager_missing():
        return False
    return QDesktopServices.openUrl(QUrl.fromLocalFile(str(folder)))


class FoldersDialog(QDialog):
    """Where the settings, presets, measurement log and recordings are, each with Open."""

    def __init__(self, folders: list[tuple[str, Path]], parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Where files are kept")
        grid = QGridLayout()
        self.paths: dict[str, Path] = {}
        for r, (what, folder) in enumerate(folders):
            self.paths[what] = folder
            grid.addWidget(QLabel(f"<b>{what}</b>"), 2 * r, 0, 1, 2)
            path = QLabel(str(folder) + ("" if folder.is_dir() else "   (not made yet)"))
            path.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
            grid.addWidget(path, 2 * r + 1, 0)
            button = QPushButton("Open")
            button.setEnabled(folder.is_dir())
            button.clicked.connect(lambda _c=False, f=folder: self.open_in_file_manager(f))
            grid.addWidget(button, 2 * r + 1, 1)
            copy = QPushButton("Copy path")
            copy.clicked.connect(lambda _c=False, f=folder: self.copy(f))
            grid.addWidget(copy, 2 * r + 1, 2)
        note = QLabel("Calibrations, sessions, fits and exports go where you choose. Deleting "
                      "the settings folder resets the application.")
        note.setWordWrap(True)
        self.said = QLabel()  # what Open or Copy did
        self.said.setWordWrap(True)
        self.said.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close)
        buttons.rejected.connect(self.close)
        lay = QVBoxLayout(self)
        lay.addLayout(grid)
        lay.addWidget(note)
        lay.addWidget(self.said)
        lay.addWidget(buttons)

    def open_in_file_manager(self, folder: Path) -> bool:  # (open() is QDialog's own)
        """Open `folder` in the file manager; where there is none, say so and copy its path."""
        if open_folder(folder):
            self.said.setText(f"Opening {folder} in the file manager…")
            return True
        QGuiApplication.clipboard().setText(str(folder))
        self.said.setText(f"No file manager could open {folder} on this computer: its path is "
                          "copied, paste it where you need it.")
        return False

    def copy(self, folder: Path) -> None:
        QGuiApplication.clipboard().setText(str(folder))
        self.said.setText(f"Copied {folder}")


def add_help_actions(window: QWidget, menu: QMenu, ctx: AppContext) -> dict[str, QAction]:
    """The Help menu's guide, shortcuts and folders (before About); returns them by name."""
    acts: dict[str, QAction] = {}
    guide = QAction("Technician's &guide", window)
    guide.setShortcut(QKeySequence(GUIDE_SHORTCUT))
    guide.triggered.connect(lambda: show_guide(window, ctx))
    keys = QAction("&Keyboard shortcuts", window)
    keys.triggered.connect(lambda: ShortcutsDialog(shortcut_rows(window), window).exec())
    folders = QAction("&Where files are kept", window)
    folders.triggered.connect(
        lambda: FoldersDialog(kept_folders(ctx.settings), window).exec())
    for name, act in (("guide", guide), ("shortcuts", keys), ("folders", folders)):
        menu.addAction(act)
        acts[name] = act
    menu.addSeparator()
    return acts


def show_guide(parent: QWidget, ctx: AppContext) -> GuideWindow | None:
    """Open the guide (the Markdown shipped with the application) in a window of its own."""
    path = guide_path()
    if not path.is_file():
        ctx.report_error(f"The guide is not installed with this copy ({path} is missing).")
        return None
    window = GuideWindow(path, parent)
    window.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
    window.show()
    return window
