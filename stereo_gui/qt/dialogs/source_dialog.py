"""The source chooser: automatic, simulated rig, two cameras, one side-by-side camera, a recording.

The dialog edits a `SourceChoice`; its `spec` is the same string `--source` takes
(auto, sim[:MODE], cams:L,R, sbs:N, a folder or a video), so the command line and the settings
agree. The simulated rig can look at the demo scene, the chessboard, or a painted wall rendered
under one of the conditions `stereo-gui bench --accuracy` measures (weak texture, webcam effects).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QButtonGroup,
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QFileDialog,
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QRadioButton,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.errors import InputError
from stereo_gui.sources import cameras as camera_devices
from stereo_gui.sources.cameras import CameraInfo
from stereo_gui.sources.open import parse_source_spec
from stereo_gui.sources.sim.conditions import CONDITIONS
from stereo_gui.sources.sim.live import SimSource

log = logging.getLogger(__name__)

# what the simulated rig can look at: (label, spec); a wall's spec takes ":METRES" after it
SIM_VIEWS: tuple[tuple[str, str], ...] = (
    ("the demo scene, with a chessboard moving in front", "sim"),
    ("the demo scene alone", "sim:scene"),
    ("the chessboard alone", "sim:board"),
    *((c.label, f"sim:wall:{name}") for name, c in CONDITIONS.items()),
)

RESOLUTIONS: tuple[tuple[int, int], ...] = ((640, 480), (320, 240), (800, 600), (1280, 720),
                                             (1280, 960), (1920, 1080))


@dataclass(frozen=True)
class SourceChoice:
    """What the user chose: a source spec (as --source takes it), size (w, h) px, swap L/R."""

    spec: str = "auto"
    size: tuple[int, int] = (640, 480)
    swap: bool = False


def describe_spec(spec: str) -> str:
    """A short human description of a source spec, for menus and the status bar."""
    if spec in ("", "auto"):
        return "Automatic"
    if spec == "sim" or spec.startswith("sim:"):
        try:
            s = parse_source_spec(spec)
        except InputError:
            return f"Simulated rig ({spec})"
        if s.mode == "wall":
            return f"Simulated rig: a wall ({s.condition}) at {s.wall_mm / 1000:g} m"
        return {"board": "Simulated rig: the chessboard",
                "scene": "Simulated rig: the demo scene"}.get(s.mode, "Simulated rig")
    if spec.startswith("cams:"):
        return f"Cameras {spec[5:]}"
    if spec.startswith("sbs:"):
        return f"Side-by-side camera {spec[4:]}"
    return f"Playback of {spec}"


def _list_cameras() -> list[CameraInfo]:
    """[CameraInfo(index, name, path)], or [] when listing them fails."""
    try:
        return list(camera_devices.list_cameras())
    except Exception as exc:  # noqa: BLE001 - listing devices must never stop the dialog
        log.warning("listing cameras failed: %s", exc)
        return []


class SourceDialog(QDialog):
    """Choose where frames come from. `choice()` is the result after `exec()` accepted."""

    def __init__(self, current: SourceChoice, cameras: list[CameraInfo] | None = None,
                 parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Choose the frame source")
        self._cameras = _list_cameras() if cameras is None else list(cameras)
        self._build_choices()
        browse, browse_video = self._build_path()
        self.resolution = QComboBox()
        for w, h in RESOLUTIONS:
            self.resolution.addItem(f"{w} x {h}", (w, h))
        self.swap = QCheckBox("Swap left and right")
        grid = self._build_grid(browse, browse_video)
        opts = self._build_options_row()
        buttons = self._build_buttons()

        layout = QVBoxLayout(self)
        layout.addLayout(grid)
        layout.addLayout(opts)
        layout.addWidget(buttons)
        self._group.buttonToggled.connect(self._update_enabled)
        self.set_choice(current)

    def _build_choices(self) -> None:
        """A radio button per kind of source, and what each kind asks: the cameras, what the
        simulated rig looks at and the wall's distance."""
        self.auto = QRadioButton("Automatic: two cameras if found, otherwise the simulated rig")
        self.sim = QRadioButton("Simulated stereo rig (no cameras needed)")
        self.cams = QRadioButton("Two cameras")
        self.sbs = QRadioButton("One side-by-side stereo camera (frame split in half)")
        self.folder = QRadioButton("A recording, a folder of pairs, or a side-by-side video "
                                   "(with play, pause, step and loop)")
        self._group = QButtonGroup(self)
        for b in (self.auto, self.sim, self.cams, self.sbs, self.folder):
            self._group.addButton(b)

        self.left_cam = self._camera_combo()
        self.right_cam = self._camera_combo()
        self.sbs_cam = self._camera_combo()
        if self.right_cam.count() > 1:
            self.right_cam.setCurrentIndex(1)
        self.sim_view = QComboBox()
        for label, spec in SIM_VIEWS:
            self.sim_view.addItem(label, spec)
            if spec.startswith("sim:wall:"):
                condition = CONDITIONS[spec.split(":")[2]]
                self.sim_view.setItemData(self.sim_view.count() - 1, condition.description,
                                          Qt.ItemDataRole.ToolTipRole)
        self.sim_view.setSizeAdjustPolicy(
            QComboBox.SizeAdjustPolicy.AdjustToMinimumContentsLengthWithIcon)
        self.sim_view.setMinimumContentsLength(36)
        self.sim_view.setToolTip("What the simulated cameras see. The walls are the ones "
                                 "stereo-gui bench --accuracy measures: a smooth painted wall at "
                                 "lower contrast, and what two cheap webcams add")
        lo, hi = (v / 1000.0 for v in SimSource.WALL_MM)
        self.wall_distance = QDoubleSpinBox()
        self.wall_distance.setRange(lo, hi)
        self.wall_distance.setDecimals(2)
        self.wall_distance.setSingleStep(0.1)
        self.wall_distance.setValue(1.0)
        self.wall_distance.setSuffix(" m")
        self.wall_distance.setToolTip("How far the wall is from the cameras")
        self.sim_view.currentIndexChanged.connect(self._update_enabled)

    def _build_path(self) -> tuple[QPushButton, QPushButton]:
        """The recording's path, and its Folder… and Video… buttons (returned)."""
        self.path_edit = QLineEdit()
        self.path_edit.setPlaceholderText("recording or folder of image pairs, or a video file")
        browse = QPushButton("Folder…")
        browse.setToolTip("A recording made with Record, or any folder of left/right image pairs")
        browse.clicked.connect(self._browse)
        browse_video = QPushButton("Video…")
        browse_video.setToolTip("A side-by-side stereo video (left half | right half)")
        browse_video.clicked.connect(self._browse_video)
        return browse, browse_video

    def _build_grid(self, browse: QPushButton, browse_video: QPushButton) -> QGridLayout:
        """The kinds of source, each with what it asks under it."""
        grid = QGridLayout()
        grid.addWidget(self.auto, 0, 0, 1, 4)
        grid.addWidget(self.sim, 1, 0, 1, 4)
        grid.addWidget(QLabel("    Looking at:"), 2, 0)
        grid.addWidget(self.sim_view, 2, 1, 1, 2)
        grid.addWidget(self.wall_distance, 2, 3)
        grid.addWidget(self.cams, 3, 0, 1, 4)
        grid.addWidget(QLabel("    Left:"), 4, 0)
        grid.addWidget(self.left_cam, 4, 1, 1, 3)
        grid.addWidget(QLabel("    Right:"), 5, 0)
        grid.addWidget(self.right_cam, 5, 1, 1, 3)
        grid.addWidget(self.sbs, 6, 0, 1, 4)
        grid.addWidget(QLabel("    Camera:"), 7, 0)
        grid.addWidget(self.sbs_cam, 7, 1, 1, 3)
        grid.addWidget(self.folder, 8, 0, 1, 4)
        grid.addWidget(self.path_edit, 9, 1)
        grid.addWidget(browse, 9, 2)
        grid.addWidget(browse_video, 9, 3)
        if not self._cameras:
            note = QLabel("No cameras were found on this computer.")
            note.setStyleSheet("color: #a05000")
            grid.addWidget(note, 10, 0, 1, 4)
        return grid

    def _build_options_row(self) -> QHBoxLayout:
        """Resolution and Swap left and right."""
        opts = QHBoxLayout()
        opts.addWidget(QLabel("Resolution:"))
        opts.addWidget(self.resolution)
        opts.addSpacing(20)
        opts.addWidget(self.swap)
        opts.addStretch(1)
        return opts

    def _build_buttons(self) -> QDialogButtonBox:
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok
                                   | QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        return buttons

    def _camera_combo(self) -> QComboBox:
        combo = QComboBox()
        for cam in self._cameras:  # "0: HD Webcam C270 [046d:0825]"
            combo.addItem(cam.label(), int(cam.index))
        if not self._cameras:
            for i in range(4):  # still let the user try an index the system did not list
                combo.addItem(f"{i}: (not listed)", i)
        return combo

    def _browse(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "A recording or a folder of pairs")
        if path:
            self.path_edit.setText(path)
            self.folder.setChecked(True)

    def _browse_video(self) -> None:
        path, _ = QFileDialog.getOpenFileName(
            self, "A side-by-side stereo video", "",
            "Videos (*.avi *.mp4 *.mkv *.mov *.m4v *.webm);;All files (*)")
        if path:
            self.path_edit.setText(path)
            self.folder.setChecked(True)

    def _update_enabled(self, *_args: object) -> None:
        self.sim_view.setEnabled(self.sim.isChecked())
        self.wall_distance.setEnabled(self.sim.isChecked()
                                      and str(self.sim_view.currentData()).startswith("sim:wall"))
        self.left_cam.setEnabled(self.cams.isChecked())
        self.right_cam.setEnabled(self.cams.isChecked())
        self.sbs_cam.setEnabled(self.sbs.isChecked())
        self.path_edit.setEnabled(self.folder.isChecked())

    @staticmethod
    def _select(combo: QComboBox, index: int) -> None:
        i = combo.findData(index)
        if i < 0:
            combo.addItem(f"{index}: (not listed)", index)
            i = combo.count() - 1
        combo.setCurrentIndex(i)

    def set_choice(self, choice: SourceChoice) -> None:
        spec = choice.spec or "auto"
        try:
            if spec == "auto":
                self.auto.setChecked(True)
            elif spec == "sim" or spec.startswith("sim:"):
                self._set_sim_view(spec)
            elif spec.startswith("cams:"):
                left, right = (int(v) for v in spec[5:].split(","))
                self.cams.setChecked(True)
                self._select(self.left_cam, left)
                self._select(self.right_cam, right)
            elif spec.startswith("sbs:"):
                self.sbs.setChecked(True)
                self._select(self.sbs_cam, int(spec[4:]))
            else:
                self.folder.setChecked(True)
                self.path_edit.setText(spec)
        except ValueError:
            self.auto.setChecked(True)
        i = self.resolution.findData(tuple(choice.size))
        if i < 0:
            self.resolution.addItem(f"{choice.size[0]} x {choice.size[1]}", tuple(choice.size))
            i = self.resolution.count() - 1
        self.resolution.setCurrentIndex(i)
        self.swap.setChecked(choice.swap)
        self._update_enabled()

    def _set_sim_view(self, spec: str) -> None:
        try:
            s = parse_source_spec(spec)
        except InputError:
            s = parse_source_spec("sim")
        view = f"sim:wall:{s.condition}" if s.mode == "wall" else (
            "sim" if s.mode == "mixed" else f"sim:{s.mode}")
        self.sim_view.setCurrentIndex(max(0, self.sim_view.findData(view)))
        if s.mode == "wall":
            self.wall_distance.setValue(s.wall_mm / 1000.0)
        self.sim.setChecked(True)

    def choice(self) -> SourceChoice:
        if self.sim.isChecked():
            spec = str(self.sim_view.currentData())
            if spec.startswith("sim:wall"):
                spec += f":{self.wall_distance.value():g}"
        elif self.cams.isChecked():
            spec = f"cams:{self.left_cam.currentData()},{self.right_cam.currentData()}"
        elif self.sbs.isChecked():
            spec = f"sbs:{self.sbs_cam.currentData()}"
        elif self.folder.isChecked() and self.path_edit.text().strip():
            spec = self.path_edit.text().strip()
        else:
            spec = "auto"
        return SourceChoice(spec, tuple(self.resolution.currentData()), self.swap.isChecked())
