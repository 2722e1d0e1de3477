# Replaces the pyqtgraph hook of pyinstaller-hooks-contrib (hooks in the spec's hookspath take
# precedence). It does what that hook does, except that it does not look into the subpackages
# that cannot be imported here: pyqtgraph.jupyter (needs jupyter_rfb, never used by us) and, while
# PyOpenGL is not installed, pyqtgraph.opengl. The contrib hook imports them to list their
# modules and warns "Failed to collect submodules for 'pyqtgraph.opengl'" on every build.
# The spec excludes pyqtgraph.opengl under the same condition (WITH_OPENGL), so the two stay in
# step: installing PyOpenGL (the 3D view of issue 12 would need it) brings pyqtgraph.opengl back.

import importlib.util

from PyInstaller.utils.hooks import collect_data_files, collect_submodules

WITH_OPENGL = importlib.util.find_spec("OpenGL") is not None
_SKIPPED = {"pyqtgraph.examples", "pyqtgraph.jupyter"}
if not WITH_OPENGL:
    _SKIPPED.add("pyqtgraph.opengl")

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
