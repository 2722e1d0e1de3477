#!/usr/bin/env bash
# Build the one-folder PyInstaller bundle of Stereo GUI into dist/stereo-gui/.
#
#   packaging/build.sh                 make (or reuse) build/package-venv, install '.[package]', build
#   packaging/build.sh --venv PATH     use (or make) the venv at PATH instead
#   PYTHON=python3.12 packaging/build.sh   choose the interpreter that makes the venv
#
# The bundle is built from this checkout; run it as dist/stereo-gui/stereo-gui. It runs on
# machines like the one it was built on (same OS family, same or newer glibc): build on the
# oldest Linux you want to support, and build Windows/macOS bundles on those systems.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${STEREO_GUI_BUILD_VENV:-$ROOT/build/package-venv}"
PYTHON="${PYTHON:-python3.11}"

while [[ $# -gt 0 ]]; do
    case "$1" in
        --venv) VENV="$(realpath -m "$2")"; shift 2 ;;
        -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
        *) echo "build.sh: unknown option: $1" >&2; exit 2 ;;
    esac
done

cd "$ROOT"
start=$(date +%s)

if [[ ! -x "$VENV/bin/python" ]]; then
    echo "build.sh: creating the build venv $VENV with $PYTHON"
    "$PYTHON" -m venv "$VENV"
fi
echo "build.sh: installing '.[package]' into $VENV"
"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet "$ROOT[package]"

# The PNG icons are committed and bundled as they are: after editing stereo-gui.svg, run
# packaging/make_icons.py and commit the PNGs. (Comparing file times here re-rendered them in a
# fresh clone, whose checkout order decides which file is newer, and left the clone modified.)

echo "build.sh: running PyInstaller"
"$VENV/bin/python" -m PyInstaller --noconfirm --clean --log-level WARN \
    --distpath "$ROOT/dist" --workpath "$ROOT/build/pyinstaller" \
    "$ROOT/packaging/stereo-gui.spec"

BUNDLE="$ROOT/dist/stereo-gui"
"$BUNDLE/stereo-gui" --version
echo "build.sh: bundle ready in $(( $(date +%s) - start )) s: $BUNDLE ($(du -sh "$BUNDLE" | cut -f1), $(find "$BUNDLE" -type f | wc -l) files)"
echo "build.sh: run it with $BUNDLE/stereo-gui"
