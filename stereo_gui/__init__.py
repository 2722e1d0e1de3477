"""Stereo GUI: calibrate a two-webcam stereo camera and read distances off a live depth view.

For programs: `stereo_gui.open_rig(...)` opens a source with a calibration and a preset and
gives its processed frames (see `stereo_gui.pipeline.rig`)."""

TYPE_CHECKING = False  # (not typing's: `import typing` would add ~3 ms to `stereo-gui --help`)
if TYPE_CHECKING:  # what __getattr__ gives, as type checkers should see it
    from stereo_gui.pipeline.rig import Frame, Reading, RegionReading, Rig, open_rig

__version__ = "0.1.0"

__all__ = ["Frame", "Reading", "RegionReading", "Rig", "__version__", "open_rig"]


def __getattr__(name: str) -> object:
    # the API is imported on first use: `import stereo_gui` stays cheap for the command line
    # (pipeline.rig loads OpenCV and the whole pipeline, ~0.5 s; `stereo-gui --help` ~10 ms)
    if name in ("open_rig", "Rig", "Frame", "Reading", "RegionReading"):
        from stereo_gui.pipeline import rig

        return getattr(rig, name)
    raise AttributeError(f"module 'stereo_gui' has no attribute {name!r}")
