# Replaces the pyqtgraph hook of pyinstaller-hooks-contrib (hooks in the spec's hookspath take
# precedence). It does what that hook does, except that it does not look into
# pyqtgraph.jupyter (needs jupyter_rfb, never used by us): the contrib hook imports it to list its
# modules and warns "Failed to collect submodules for 'pyqtgraph.jupyter'" on every build.
# pyqtgraph.opengl (the Live tab's 3D view, with PyOpenGL) is found by the import scan.

from PyInstaller.utils.hooks import collect_data_files, collect_submodules

_SKIPPED = {"pyqtgraph.examples", "pyqtgraph.jupyter"}

datas = collect_data_files("pyqtgraph", excludes=["**/examples/*"])

# pyqtgraph imports its Qt-binding-specific designer templates by name at run time.
_modules = collect_submodules("pyqtgraph", filter=lambda name: name not in _SKIPPED,
                              on_error="warn")
hiddenimports = [name for name in _modules if "Template" in name]
# pyinstaller's pyqtgraph.multiprocess runtime hook runs this module
hiddenimports += ["pyqtgraph.multiprocess.bootstrap"]

# keep PyQt5/PyQt6/PySide2 out, whichever are installed (PyInstaller >= 6.5)
from PyInstaller.utils.hooks.qt import exclude_extraneous_qt_bindings  # noqa: E402

excludedimports = exclude_extraneous_qt_bindings(hook_name="hook-pyqtgraph",
                                                 qt_bindings_order=None)
