"""The matcher parameter panel: SGBM, closing and WLS settings, presets, save-as-preset.

Labels carry the report's own names (window_size, min_disp, num_disp, lmbda, sigma, ...) so a
reader of the report finds them. Every edit emits `paramsChanged(MatcherParams)`; the Live tab
hands it to the pipeline, which applies it from the next frame on.
"""

from __future__ import annotations

import logging

from PySide6.QtCore import Qt, Signal
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
from stereo_gui.core.matching import COLORMAPS, MODES, MatcherParams

log = logging.getLogger(__name__)

BUILTIN_PRESETS = ("seed", "live", "quality")
MODIFIED = " (modified)"  # a preset's name after an edit: what runs is no longer the preset


# ---- presets (stereo_gui.files.presets when present) -------------------------------------------
def preset_names() -> list[str]:
    """Names of the built-in and user presets, built-ins first."""
    try:
        from stereo_gui.files import presets
    except ImportError:
        return ["seed"]
    try:
        names = list(presets.list_presets())
    except StereoGuiError as exc:
        log.warning("listing presets failed: %s", exc)
        names = list(BUILTIN_PRESETS)
    builtin = [n for n in BUILTIN_PRESETS if n in names]
    return builtin + sorted(n for n in names if n not in BUILTIN_PRESETS)


def load_preset(name: str) -> MatcherParams:
    """The preset's parameters; InputError if it does not exist or is broken."""
    try:
        from stereo_gui.files import presets
    except ImportError:
        if name == "seed":
            return MatcherParams(name="seed")
        raise StereoGuiError(f"preset {name!r}: presets are not available") from None
    return presets.load_preset(name)


def save_user_preset(params: MatcherParams, name: str):
    from stereo_gui.files import presets

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


class ParamsPanel(QWidget):
    """Edits a MatcherParams. `params()` is the current value; `set_params()` shows one."""

    paramsChanged = Signal(object)  # MatcherParams
    presetSaved = Signal(str)

    def __init__(self, params: MatcherParams | None = None, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._params = params or MatcherParams()
        self._calibration = None  # see set_calibration
        self._updating = False
        self.error_label = QLabel()
        self.error_label.setStyleSheet("color: #ff6e6e")
        self.error_label.setWordWrap(True)
        self.error_label.hide()

        # presets
        self.preset = QComboBox()
        self.preset.setToolTip("seed: the report's parameters; live: fast; quality: most accurate")
        self.save_preset = QPushButton("Save as…")
        self.save_preset.setToolTip("save these parameters as a preset of your own")
        self.save_preset.clicked.connect(self._save_as)
        prow = QHBoxLayout()
        prow.addWidget(QLabel("Preset:"))
        prow.addWidget(self.preset, 1)
        prow.addWidget(self.save_preset)
        self.reload_presets()
        self.preset.activated.connect(self._preset_activated)

        # SGBM
        self.block_size = SliderSpin(1, 21)
        self.block_size.setToolTip("SGBM blockSize, odd (the report: window_size = 3)")
        self.min_disparity = SliderSpin(0, 64)
        self.num_disparities = SliderSpin(16, 256, 16)
        self.range_from_z = QCheckBox("range from working distances")
        self.range_from_z.setToolTip("derive min_disp and num_disp from the nearest and farthest "
                                     "distance through d = f·B/Z")
        self.z_min = QDoubleSpinBox()
        self.z_min.setRange(50, 50000)
        self.z_min.setDecimals(0)
        self.z_min.setSingleStep(50)
        self.z_min.setSuffix(" mm")
        self.z_max = QDoubleSpinBox()
        self.z_max.setRange(0, 100000)
        self.z_max.setDecimals(0)
        self.z_max.setSingleStep(500)
        self.z_max.setSuffix(" mm")
        self.z_max.setSpecialValueText("∞ (infinity)")
        self.uniqueness = SliderSpin(0, 50)
        self.speckle_window = SliderSpin(0, 300)
        self.speckle_range = SliderSpin(0, 64)
        self.disp12 = SliderSpin(-1, 50)
        self.pre_filter_cap = SliderSpin(0, 63)
        self.p_auto = QCheckBox("P1 = 8·3·w², P2 = 32·3·w²")
        self.p_auto.setToolTip("the report's smoothness penalties, from window_size w")
        self.p1 = QSpinBox()
        self.p1.setRange(0, 100000)
        self.p2 = QSpinBox()
        self.p2.setRange(0, 400000)
        self.mode = QComboBox()
        self.mode.addItems(list(MODES))
        self.scale = QComboBox()
        for s in (1.0, 0.75, 0.5, 0.25):
            self.scale.addItem(f"{s:g}" + ("  (full)" if s == 1.0 else ""), s)
        self.parallel = QCheckBox("use two CPU cores")
        self.parallel.setToolTip("Live: two frames processed at once, one on each core (about "
                                 "1.4x the frames of one frame split over both cores)")
        sgbm = QFormLayout()
        sgbm.addRow("window_size", self.block_size)
        sgbm.addRow("min_disp (px)", self.min_disparity)
        sgbm.addRow("num_disp (px)", self.num_disparities)
        sgbm.addRow(self.range_from_z)
        sgbm.addRow("nearest Z", self.z_min)
        sgbm.addRow("farthest Z", self.z_max)
        sgbm.addRow("uniquenessRatio", self.uniqueness)
        sgbm.addRow("speckleWindowSize", self.speckle_window)
        sgbm.addRow("speckleRange", self.speckle_range)
        sgbm.addRow("disp12MaxDiff", self.disp12)
        sgbm.addRow("preFilterCap", self.pre_filter_cap)
        sgbm.addRow(self.p_auto)
        sgbm.addRow("P1", self.p1)
        sgbm.addRow("P2", self.p2)
        sgbm.addRow("mode", self.mode)
        sgbm.addRow("match at scale", self.scale)
        self.scale_note = QLabel("")  # the scale that runs when a large frame lowers it
        self.scale_note.setStyleSheet("color: gray")
        self.scale_note.hide()
        sgbm.addRow("", self.scale_note)
        sgbm.addRow(self.parallel)
        sgbm_box = QGroupBox("SGBM matcher")
        sgbm_box.setLayout(sgbm)

        # closing
        self.closing = SliderSpin(0, 15)
        self.closing.setToolTip("side of the square closing kernel, px (report: 3); 0 = off")
        closing = QFormLayout()
        closing.addRow("kernel (px)", self.closing)
        closing_box = QGroupBox("Closing filter")
        closing_box.setLayout(closing)

        # WLS and colour
        self.wls = QCheckBox("WLS filter")
        self.wls.setToolTip("right matcher + cv2.ximgproc.createDisparityWLSFilter, as the report")
        self.wls_lambda = QDoubleSpinBox()
        self.wls_lambda.setRange(0, 1e6)
        self.wls_lambda.setDecimals(0)
        self.wls_lambda.setSingleStep(1000)
        self.wls_sigma = QDoubleSpinBox()
        self.wls_sigma.setRange(0.0, 10.0)
        self.wls_sigma.setSingleStep(0.1)
        self.colormap = QComboBox()
        self.colormap.addItems(sorted(COLORMAPS))
        self.color_fixed = QCheckBox("fixed colour range")
        self.color_fixed.setToolTip("a colour always means the same distance (the report "
                                    "normalised every frame, so colours drifted)")
        self.z_near = QDoubleSpinBox()
        self.z_near.setRange(50, 50000)
        self.z_near.setSuffix(" mm")
        self.z_near.setDecimals(0)
        self.z_far = QDoubleSpinBox()
        self.z_far.setRange(100, 100000)
        self.z_far.setSuffix(" mm")
        self.z_far.setDecimals(0)
        wls = QFormLayout()
        wls.addRow(self.wls)
        wls.addRow("lmbda", self.wls_lambda)
        wls.addRow("sigma", self.wls_sigma)
        wls.addRow("colour map", self.colormap)
        wls.addRow(self.color_fixed)
        wls.addRow("near", self.z_near)
        wls.addRow("far", self.z_far)
        wls_box = QGroupBox("WLS filter and colours")
        wls_box.setLayout(wls)

        col = QVBoxLayout(self)
        col.addLayout(prow)
        col.addWidget(self.error_label)
        col.addWidget(sgbm_box)
        col.addWidget(closing_box)
        col.addWidget(wls_box)
        col.addStretch(1)

        self._show(self._params)
        for w in (self.block_size, self.min_disparity, self.num_disparities, self.uniqueness,
                  self.speckle_window, self.speckle_range, self.disp12, self.pre_filter_cap,
                  self.closing, self.p1, self.p2, self.wls_lambda, self.wls_sigma, self.z_near,
                  self.z_far, self.z_min, self.z_max):
            w.valueChanged.connect(self._edited)
        for c in (self.mode, self.scale, self.colormap):
            c.currentIndexChanged.connect(self._edited)
        for b in (self.p_auto, self.wls, self.color_fixed, self.parallel, self.range_from_z):
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
        except (StereoGuiError, OSError, ImportError) as exc:
            self._show_error(f"Preset not saved: {exc}")
            return False
        self._params = self._params.replace(name=name)
        self.reload_presets(select=name)
        self.presetSaved.emit(name)
        return True

    # ---- values ------------------------------------------------------------------------------
    def params(self) -> MatcherParams:
        return self._params

    def set_params(self, params: MatcherParams) -> None:
        """Show `params` without emitting paramsChanged."""
        self._params = params
        self._show(params)

    def set_calibration(self, calibration) -> None:
        """The calibration the parameters apply to: a range from working distances is shown
        as the min_disp / num_disp it gives (d = f·B/Z) with it."""
        self._calibration = calibration
        self._show_effective(self._params)

    def _show_effective(self, p: MatcherParams) -> None:
        """Show the values that run where the panel derives them: an odd window (SGBM's), the
        P1/P2 that follow it, the disparity range from working distances, and "(modified)"
        in the preset box after an edit."""
        self._updating = True
        try:
            self.block_size.setValue(p.block_size)
            if p.p1 is None and p.p2 is None:
                self.p1.setValue(p.p1_value)
                self.p2.setValue(p.p2_value)
            if p.z_min_mm is not None and self._calibration is not None:
                lo, num = p.disparity_range(self._calibration)
                for spin, v in ((self.min_disparity, lo), (self.num_disparities, num)):
                    if v > spin.spin.maximum():
                        spin.spin.setMaximum(int(v))
                        spin.slider.setMaximum(int(v) // spin._step)
                    spin.setValue(int(v))
                tip = (f"from the working distances: {lo} .. {lo + num - 1} px "
                       f"for this calibration")
            else:
                tip = ""
            for spin in (self.min_disparity, self.num_disparities):
                spin.setToolTip(tip)
            width = self._calibration.width if self._calibration is not None else 0
            runs = p.effective_scale(width)
            self.scale_note.setText(f"runs at {runs:g}: {width} px frames are matched at most "
                                    f"{p.max_match_width} px wide" if runs != p.scale else "")
            self.scale_note.setVisible(runs != p.scale)
            self._show_preset_name(p.name)
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

    def _show(self, p: MatcherParams) -> None:
        self._updating = True
        try:
            self.block_size.setValue(p.block_size)
            self.min_disparity.setValue(p.min_disparity)
            self.num_disparities.setValue(p.num_disparities)
            self.range_from_z.setChecked(p.z_min_mm is not None)
            self.z_min.setValue(p.z_min_mm if p.z_min_mm is not None else 450.0)
            self.z_max.setValue(p.z_max_mm if p.z_max_mm is not None else 0.0)
            self.uniqueness.setValue(p.uniqueness_ratio)
            self.speckle_window.setValue(p.speckle_window_size)
            self.speckle_range.setValue(p.speckle_range)
            self.disp12.setValue(p.disp12_max_diff)
            self.pre_filter_cap.setValue(p.pre_filter_cap)
            self.p_auto.setChecked(p.p1 is None and p.p2 is None)
            self.p1.setValue(p.p1_value)
            self.p2.setValue(p.p2_value)
            self.mode.setCurrentText(p.mode)
            i = self.scale.findData(p.scale)
            if i < 0:
                self.scale.addItem(f"{p.scale:g}", p.scale)
                i = self.scale.count() - 1
            self.scale.setCurrentIndex(i)
            self.parallel.setChecked(p.parallel)
            self.closing.setValue(p.closing_kernel)
            self.wls.setChecked(p.wls)
            self.wls_lambda.setValue(p.wls_lambda)
            self.wls_sigma.setValue(p.wls_sigma)
            self.colormap.setCurrentText(p.colormap)
            self.color_fixed.setChecked(p.color_range == "fixed")
            self.z_near.setValue(p.color_z_near_mm)
            self.z_far.setValue(p.color_z_far_mm)
            self._sync_enabled()
        finally:
            self._updating = False
        self._show_effective(p)
        self.error_label.hide()

    def _sync_enabled(self) -> None:
        from_z = self.range_from_z.isChecked()
        self.min_disparity.setEnabled(not from_z)
        self.num_disparities.setEnabled(not from_z)
        self.z_min.setEnabled(from_z)
        self.z_max.setEnabled(from_z)
        self.p1.setEnabled(not self.p_auto.isChecked())
        self.p2.setEnabled(not self.p_auto.isChecked())
        for w in (self.wls_lambda, self.wls_sigma):
            w.setEnabled(self.wls.isChecked())
        for w in (self.z_near, self.z_far):
            w.setEnabled(self.color_fixed.isChecked())

    def _read(self) -> MatcherParams:
        auto = self.p_auto.isChecked()
        block = self.block_size.value()
        if block % 2 == 0:
            block += 1  # SGBM needs an odd window
        return self._params.replace(
            name=self._params.name if self._params.name.endswith(MODIFIED)
            else f"{self._params.name}{MODIFIED}",
            block_size=block,
            min_disparity=self.min_disparity.value(),
            num_disparities=self.num_disparities.value(),
            z_min_mm=float(self.z_min.value()) if self.range_from_z.isChecked() else None,
            z_max_mm=(float(self.z_max.value()) or None) if self.range_from_z.isChecked() else None,
            uniqueness_ratio=self.uniqueness.value(),
            speckle_window_size=self.speckle_window.value(),
            speckle_range=self.speckle_range.value(),
            disp12_max_diff=self.disp12.value(),
            pre_filter_cap=self.pre_filter_cap.value(),
            p1=None if auto else self.p1.value(),
            p2=None if auto else self.p2.value(),
            mode=self.mode.currentText(),
            scale=float(self.scale.currentData()),
            parallel=self.parallel.isChecked(),
            closing_kernel=self.closing.value(),
            wls=self.wls.isChecked(),
            wls_lambda=float(self.wls_lambda.value()),
            wls_sigma=float(self.wls_sigma.value()),
            colormap=self.colormap.currentText(),
            color_range="fixed" if self.color_fixed.isChecked() else "minmax",
            color_z_near_mm=float(self.z_near.value()),
            color_z_far_mm=float(self.z_far.value()),
        )

    def _edited(self, *_args) -> None:
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

    def _show_error(self, text: str) -> None:
        self.error_label.setText(text)
        self.error_label.show()
