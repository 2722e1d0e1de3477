"""The matcher parameter panel: SGBM, closing and WLS settings, presets, save-as-preset.

Each parameter's editor is made from its declaration (`core.preset.PRESET_PARAMS`: type, the
range the panel offers, unit, label and help), so ranges and labels live in one place. Labels
carry the reference loop's own names (window_size, min_disp, num_disp, lmbda, sigma, ...) so a
reader of its code finds them. Every edit emits `paramsChanged(Preset)`; the Live tab hands it to
the pipeline, which applies it from the next frame on.
"""

from __future__ import annotations

import logging
from pathlib import Path

from PySide6.QtCore import Qt, Signal, SignalInstance
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QInputDialog,
    QLabel,
    QPushButton,
    QSlider,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.params import Param
from stereo_gui.core.preset import PRESET_PARAMS, MatcherParams, Preset
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files import presets

log = logging.getLogger(__name__)

BUILTIN_PRESETS = ("seed", "live", "quality")
MODIFIED = " (modified)"  # a preset's name after an edit: what runs is no longer the preset


# ---- presets (stereo_gui.files.presets) -------------------------------------------------------
def preset_names() -> list[str]:
    """Names of the built-in and user presets, built-ins first."""
    try:
        names = list(presets.list_presets())
    except StereoGuiError as exc:
        log.warning("listing presets failed: %s", exc)
        names = list(BUILTIN_PRESETS)
    builtin = [n for n in BUILTIN_PRESETS if n in names]
    return builtin + sorted(n for n in names if n not in BUILTIN_PRESETS)


def load_preset(name: str) -> Preset:
    """The preset's parameters; InputError if it does not exist or is broken."""
    return presets.load_preset(name)


def save_user_preset(params: Preset, name: str) -> Path:
    return presets.save_user_preset(params.replace(name=name), name)


# ---- a slider joined to a spin box ----------------------------------------------------------
class SliderSpin(QWidget):
    """An integer slider with a spin box showing the same value (step-aware)."""

    valueChanged = Signal(int)

    def __init__(self, lo: int, hi: int, step: int = 1, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._step = step
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(lo // step, hi // step)
        self.spin = QSpinBox()
        self.spin.setRange(lo, hi)
        self.spin.setSingleStep(step)
        self.spin.setMinimumWidth(70)
        row = QHBoxLayout(self)
        row.setContentsMargins(0, 0, 0, 0)
        row.addWidget(self.slider, 1)
        row.addWidget(self.spin)
        self.slider.valueChanged.connect(lambda v: self.spin.setValue(v * self._step))
        self.spin.valueChanged.connect(self._spin_changed)

    def _spin_changed(self, v: int) -> None:
        snapped = round(v / self._step) * self._step
        if snapped != v:
            self.spin.setValue(snapped)
            return
        self.slider.blockSignals(True)
        self.slider.setValue(v // self._step)
        self.slider.blockSignals(False)
        self.valueChanged.emit(v)

    def value(self) -> int:
        return self.spin.value()

    def setValue(self, v: int) -> None:  # noqa: N802 - Qt naming
        self.spin.setValue(int(v))

    def minimum(self) -> int:
        return self.spin.minimum()

    def maximum(self) -> int:
        return self.spin.maximum()

    def setMaximum(self, v: int) -> None:  # noqa: N802 - Qt naming
        """Offer values up to `v` (a derived value may lie beyond the declared panel range)."""
        self.spin.setMaximum(int(v))
        self.slider.setMaximum(int(v) // self._step)


# ---- an editor made from a parameter's declaration -------------------------------------------
WholeEditor = SliderSpin | QSpinBox
Editor = QCheckBox | QComboBox | WholeEditor | QDoubleSpinBox
EditorValue = bool | str | int | float


def _runs_at_text(p: MatcherParams, width: int, height: int) -> str:
    """Why frames of the calibration's size are matched at another scale than the preset's
    ("" when they are matched at the preset's)."""
    runs = p.effective_scale(width, height)
    if runs == p.scale:
        return ""
    by_width = p.replace(max_match_pixels=None).effective_scale(width, height)
    why = []
    if by_width != p.scale:
        why.append(f"at most {p.max_match_width} px wide")
    if runs != by_width:
        why.append(f"on at most {p.max_match_pixels:,} pixels")
    return f"runs at {runs:g}: {width}x{height} px frames are matched {' and '.join(why)}"


def make_editor(spec: Param) -> Editor:
    """The widget that edits one parameter: a check box, a list of its choices, a slider with a
    spin box (whole numbers), a spin box (large whole numbers) or a decimal spin box, offering
    the declaration's panel range and step, its unit as a suffix of decimals, its help as the
    tool tip."""
    tp = spec.base
    w: Editor
    if tp is bool:
        w = QCheckBox(spec.label or spec.name)
    elif spec.choices:
        w = QComboBox()
        w.addItems(list(spec.choices))
    else:
        if spec.panel is not None:
            lo, hi, step = spec.panel
        elif spec.lo is not None and spec.hi is not None:
            lo, hi, step = spec.lo, spec.hi, 1
        else:
            raise ValueError(f"{spec.name}: a number's editor needs its range declared")
        if tp is int and hi - lo <= 10_000:
            w = SliderSpin(int(lo), int(hi), int(step))
        elif tp is int:
            w = QSpinBox()
            w.setRange(int(lo), int(hi))
        else:
            w = QDoubleSpinBox()
            w.setRange(lo, hi)
            w.setDecimals(0 if step >= 1 else 2)
            w.setSingleStep(step)
            if spec.unit:
                w.setSuffix(f" {spec.unit}")
    w.setToolTip(spec.help)
    return w


def editor_value(w: Editor) -> EditorValue:
    """The value an editor of `make_editor` shows."""
    if isinstance(w, QCheckBox):
        return w.isChecked()
    if isinstance(w, QComboBox):
        return w.currentText()
    return w.value()


def show_value(w: Editor, value: EditorValue) -> None:
    """Show `value` in an editor of `make_editor`."""
    if isinstance(w, QCheckBox):
        w.setChecked(bool(value))
    elif isinstance(w, QComboBox):
        w.setCurrentText(str(value))
    elif isinstance(w, QDoubleSpinBox):
        w.setValue(float(value))
    else:
        w.setValue(int(value))


def editor_changed(w: Editor) -> SignalInstance:
    """The signal an editor of `make_editor` emits on an edit."""
    if isinstance(w, QCheckBox):
        return w.toggled
    if isinstance(w, QComboBox):
        return w.currentIndexChanged
    return w.valueChanged


# the parameters the panel edits, group by group (the rest keep the preset's values)
SGBM_KEYS = ("block_size", "min_disparity", "num_disparities", "z_min_mm", "z_max_mm",
             "range_from_scene", "uniqueness_ratio", "speckle_window_size", "speckle_range", "disp12_max_diff",
             "pre_filter_cap", "p1", "p2", "mode", "parallel")
CLOSING_KEYS = ("closing_kernel",)
# the colour ranges the panel offers (core.preset.COLOR_RANGES), as it names them
COLOR_RANGE_CHOICES = (("view", "follows the view"), ("fixed", "fixed (near to far)"),
                       ("minmax", "each frame's min-max"))
WLS_KEYS = ("wls", "wls_lambda", "wls_sigma", "colormap", "color_z_near_mm", "color_z_far_mm")
Z_UNSET_MM = 450.0  # what the nearest-distance box shows for a preset without one


class ParamsPanel(QWidget):
    """Edits a Preset. `params()` is the current value; `set_params()` shows one. `editors` maps
    each edited parameter's name (a key of PRESET_PARAMS) to its widget."""

    paramsChanged = Signal(Preset)
    presetSaved = Signal(str)

    def __init__(self, params: Preset | None = None, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._params = params or Preset()
        self._calibration: StereoCalibration | None = None  # see set_calibration
        self._updating = False
        self.error_label = QLabel()
        self.error_label.setStyleSheet("color: #ff6e6e")
        self.error_label.setWordWrap(True)
        self.error_label.hide()
        prow = self._build_preset_row()
        self._build_editors()
        sgbm_box = self._build_sgbm_box()
        closing_box = self._build_closing_box()
        wls_box = self._build_wls_box()

        col = QVBoxLayout(self)
        col.addLayout(prow)
        col.addWidget(self.error_label)
        col.addWidget(sgbm_box)
        col.addWidget(closing_box)
        col.addWidget(wls_box)
        col.addStretch(1)

        self._show(self._params)
        self._connect_editors()

    # ---- building ----------------------------------------------------------------------------
    def _build_preset_row(self) -> QHBoxLayout:
        """The preset chooser and Save as…."""
        self.preset = QComboBox()
        self.preset.setToolTip("seed: the reference loop's parameters; live: fast; quality: "
                               "most accurate")
        self.save_preset = QPushButton("Save as…")
        self.save_preset.setToolTip("save these parameters as a preset of your own")
        self.save_preset.clicked.connect(self._save_as)
        prow = QHBoxLayout()
        prow.addWidget(QLabel("Preset:"))
        prow.addWidget(self.preset, 1)
        prow.addWidget(self.save_preset)
        self.reload_presets()
        self.preset.activated.connect(self._preset_activated)
        return prow

    def _build_editors(self) -> None:
        """An editor per declared parameter, and the choices the declarations do not make."""
        self.editors: dict[str, Editor] = {
            key: make_editor(PRESET_PARAMS[key]) for key in SGBM_KEYS + CLOSING_KEYS + WLS_KEYS}
        self._decimal("z_max_mm").setSpecialValueText("∞ (infinity)")
        self.range_from_z = QCheckBox("range from working distances")
        self.range_from_z.setToolTip("derive min_disp and num_disp from the nearest and farthest "
                                     "distance through d = f·B/Z")
        self.p_auto = QCheckBox("P1 = 8·3·w², P2 = 32·3·w²")
        self.p_auto.setToolTip("the reference loop's smoothness penalties, from window_size w")
        self.scale = QComboBox()
        for s in (1.0, 0.75, 0.5, 0.25):
            self.scale.addItem(f"{s:g}" + ("  (full)" if s == 1.0 else ""), s)
        self.scale.setToolTip(PRESET_PARAMS["scale"].help)
        self.color_range = QComboBox()
        for value, text in COLOR_RANGE_CHOICES:
            self.color_range.addItem(text, value)
        self.color_range.setToolTip(
            "follows the view: round distances around what is in view, changed only when the "
            "view leaves them (near and far below while nothing is in view); fixed: a colour "
            "always means the same distance, from near to far; each frame's min-max (the seed "
            "preset's): colours drift from frame to frame")
        self.scale_note = QLabel("")  # the scale that runs when a large frame lowers it
        self.scale_note.setStyleSheet("color: gray")
        self.scale_note.setWordWrap(True)  # (unwrapped, its width would widen the whole panel)
        self.scale_note.hide()

    def _add_rows(self, form: QFormLayout, keys: tuple[str, ...]) -> None:
        """A row per parameter in `keys`: a check box alone, other editors after a label."""
        for key in keys:
            editor = self.editors[key]
            if isinstance(editor, QCheckBox):
                form.addRow(editor)
            else:
                form.addRow(PRESET_PARAMS[key].label or key, editor)

    def _build_sgbm_box(self) -> QGroupBox:
        rows = self._add_rows
        sgbm = QFormLayout()
        rows(sgbm, ("block_size", "min_disparity", "num_disparities"))
        sgbm.addRow(self.range_from_z)
        rows(sgbm, ("z_min_mm", "z_max_mm", "range_from_scene", "uniqueness_ratio",
                    "speckle_window_size",
                    "speckle_range", "disp12_max_diff", "pre_filter_cap"))
        sgbm.addRow(self.p_auto)
        rows(sgbm, ("p1", "p2", "mode"))
        sgbm.addRow(PRESET_PARAMS["scale"].label, self.scale)
        sgbm.addRow("", self.scale_note)
        rows(sgbm, ("parallel",))
        sgbm_box = QGroupBox("SGBM matcher")
        sgbm_box.setLayout(sgbm)
        return sgbm_box

    def _build_closing_box(self) -> QGroupBox:
        closing = QFormLayout()
        self._add_rows(closing, CLOSING_KEYS)
        closing_box = QGroupBox("Closing filter")
        closing_box.setLayout(closing)
        return closing_box

    def _build_wls_box(self) -> QGroupBox:
        wls = QFormLayout()
        self._add_rows(wls, ("wls", "wls_lambda", "wls_sigma", "colormap"))
        wls.addRow("colour range", self.color_range)
        self._add_rows(wls, ("color_z_near_mm", "color_z_far_mm"))
        wls_box = QGroupBox("WLS filter and colours")
        wls_box.setLayout(wls)
        return wls_box

    def _connect_editors(self) -> None:
        """Every edit goes through `_edited`."""
        for w in self.editors.values():
            editor_changed(w).connect(self._edited)
        self.scale.currentIndexChanged.connect(self._edited)
        self.color_range.currentIndexChanged.connect(self._edited)
        for b in (self.p_auto, self.range_from_z):
            b.toggled.connect(self._edited)

    # ---- presets -----------------------------------------------------------------------------
    def reload_presets(self, select: str | None = None) -> None:
        current = select or self.preset.currentText() or self._params.name
        self.preset.blockSignals(True)
        self.preset.clear()
        self.preset.addItems(preset_names())
        if self.preset.findText(current) < 0 and current:
            self.preset.addItem(current)
        self.preset.setCurrentText(current)
        self.preset.blockSignals(False)

    def _preset_activated(self, _index: int) -> None:
        name = self.preset.currentText()
        if not name.endswith(MODIFIED):  # the parameters running now: nothing to apply
            self.apply_preset(name)

    def apply_preset(self, name: str) -> bool:
        """Show and emit the named preset's parameters; False (and a message) if it fails."""
        try:
            params = load_preset(name)
        except StereoGuiError as exc:
            self._show_error(str(exc))
            return False
        self.set_params(params.replace(name=name))
        self.paramsChanged.emit(self._params)
        return True

    def _save_as(self) -> None:
        name, ok = QInputDialog.getText(self, "Save preset", "Name of the new preset:")
        if ok and name.strip():
            self.save_as(name.strip())

    def save_as(self, name: str) -> bool:
        if name in BUILTIN_PRESETS:
            self._show_error(f"{name!r} is a built-in preset; choose another name")
            return False
        try:
            save_user_preset(self._params, name)
        except (StereoGuiError, OSError) as exc:
            self._show_error(f"Preset not saved: {exc}")
            return False
        self._params = self._params.replace(name=name)
        self.reload_presets(select=name)
        self.presetSaved.emit(name)
        return True

    # ---- values ------------------------------------------------------------------------------
    def params(self) -> Preset:
        return self._params

    def set_params(self, params: Preset) -> None:
        """Show `params` without emitting paramsChanged."""
        self._params = params
        self._show(params)

    @property
    def calibration(self) -> StereoCalibration | None:
        """The calibration the parameters are shown for (`set_calibration`)."""
        return self._calibration

    def set_calibration(self, calibration: StereoCalibration | None) -> None:
        """The calibration the parameters apply to: a range from working distances is shown
        as the min_disp / num_disp it gives (d = f·B/Z) with it."""
        self._calibration = calibration
        self._show_effective(self._params)

    def _show_effective(self, preset: Preset) -> None:
        """Show the values that run where the panel derives them: an odd window (SGBM's), the
        P1/P2 that follow it, the disparity range from working distances, and "(modified)"
        in the preset box after an edit."""
        p, ed = preset.matcher, self.editors
        self._updating = True
        try:
            self._whole("block_size").setValue(p.block_size)
            if p.p1 is None and p.p2 is None:
                self._whole("p1").setValue(p.p1_value)
                self._whole("p2").setValue(p.p2_value)
            if p.z_min_mm is not None and self._calibration is not None:
                lo, num = p.disparity_range(self._calibration)
                for key, v in (("min_disparity", lo), ("num_disparities", num)):
                    box = self._whole(key)
                    if v > box.maximum():
                        box.setMaximum(int(v))
                    box.setValue(int(v))
                tip = (f"from the working distances: {lo} .. {lo + num - 1} px "
                       f"for this calibration")
            else:
                tip = ""
            for key in ("min_disparity", "num_disparities"):
                ed[key].setToolTip(tip or PRESET_PARAMS[key].help)
            width, height = (self._calibration.image_size if self._calibration is not None
                             else (0, 0))
            note = _runs_at_text(p, width, height)
            self.scale_note.setText(note)
            self.scale_note.setVisible(bool(note))
            self._show_preset_name(preset.name)
        finally:
            self._updating = False

    def _show_preset_name(self, name: str) -> None:
        """The preset box shows `name`; a modified preset's name is an entry of its own."""
        self.preset.blockSignals(True)
        for i in reversed(range(self.preset.count())):
            if self.preset.itemText(i).endswith(MODIFIED) and self.preset.itemText(i) != name:
                self.preset.removeItem(i)
        if name and self.preset.findText(name) < 0:
            self.preset.insertItem(0, name)
        if name:
            self.preset.setCurrentText(name)
        self.preset.blockSignals(False)

    def _show(self, preset: Preset) -> None:
        p = preset.matcher
        self._updating = True
        try:
            for key, w in self.editors.items():
                value = preset.get(key)
                if value is not None:
                    show_value(w, value)
            # what a box shows for a parameter left unset (the check boxes say it is unset)
            self._decimal("z_min_mm").setValue(p.z_min_mm if p.z_min_mm is not None
                                               else Z_UNSET_MM)
            self._decimal("z_max_mm").setValue(p.z_max_mm if p.z_max_mm is not None else 0.0)
            self._whole("p1").setValue(p.p1_value)
            self._whole("p2").setValue(p.p2_value)
            self.range_from_z.setChecked(p.z_min_mm is not None)
            self.p_auto.setChecked(p.p1 is None and p.p2 is None)
            i = self.scale.findData(p.scale)
            if i < 0:
                self.scale.addItem(f"{p.scale:g}", p.scale)
                i = self.scale.count() - 1
            self.scale.setCurrentIndex(i)
            self.color_range.setCurrentIndex(max(0, self.color_range.findData(
                preset.display.color_range)))
            self._sync_enabled()
        finally:
            self._updating = False
        self._show_effective(preset)
        self.error_label.hide()

    def _sync_enabled(self) -> None:
        ed = self.editors
        from_z = self.range_from_z.isChecked()
        for key in ("min_disparity", "num_disparities"):
            ed[key].setEnabled(not from_z)
        for key in ("z_min_mm", "z_max_mm", "range_from_scene"):
            ed[key].setEnabled(from_z)
        for key in ("p1", "p2"):
            ed[key].setEnabled(not self.p_auto.isChecked())
        for key in ("wls_lambda", "wls_sigma"):
            ed[key].setEnabled(self._check("wls").isChecked())
        for key in ("color_z_near_mm", "color_z_far_mm"):
            # (a range that follows the view starts from them, and keeps to them while
            # nothing is in view)
            ed[key].setEnabled(self.color_range.currentData() != "minmax")

    def _read(self) -> Preset:
        values: dict[str, EditorValue | None] = {
            key: editor_value(w) for key, w in self.editors.items()}
        block = values["block_size"]
        if isinstance(block, int) and block % 2 == 0:
            values["block_size"] = block + 1  # SGBM needs an odd window
        if not self.range_from_z.isChecked():
            values["z_min_mm"] = values["z_max_mm"] = None
        else:
            values["z_max_mm"] = values["z_max_mm"] or None  # 0: infinity
        if self.p_auto.isChecked():
            values["p1"] = values["p2"] = None
        values["scale"] = float(self.scale.currentData())
        values["color_range"] = self.color_range.currentData()
        name = self._params.name
        return self._params.replace(
            name=name if name.endswith(MODIFIED) else f"{name}{MODIFIED}", **values)

    def _edited(self, *_args: object) -> None:
        if self._updating:
            return
        self._sync_enabled()
        try:
            params = self._read()
        except StereoGuiError as exc:
            self._show_error(str(exc))
            return
        self.error_label.hide()
        # what runs, even when the edit changed nothing (an even window runs as the odd one)
        self._show_effective(params if params != self._params else self._params)
        if params != self._params:
            self._params = params
            self.paramsChanged.emit(params)

    # the editors the panel sets by name, as what they are (make_editor made them so)
    def _whole(self, key: str) -> WholeEditor:
        w = self.editors[key]
        if not isinstance(w, (SliderSpin, QSpinBox)):
            raise TypeError(f"{key}'s editor holds no whole number")
        return w

    def _decimal(self, key: str) -> QDoubleSpinBox:
        w = self.editors[key]
        if not isinstance(w, QDoubleSpinBox):
            raise TypeError(f"{key}'s editor holds no decimal number")
        return w

    def _check(self, key: str) -> QCheckBox:
        w = self.editors[key]
        if not isinstance(w, QCheckBox):
            raise TypeError(f"{key}'s editor is no check box")
        return w

    def _show_error(self, text: str) -> None:
        self.error_label.setText(text)
        self.error_label.show()
