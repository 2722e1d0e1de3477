"""Exceptions the core raises for problems a user can fix (bad files, bad input, too little data).

The command line turns any `StereoGuiError` into one line on stderr and exit status 2; the GUI
shows its message. Programming errors are not wrapped: they stay ordinary exceptions.
"""


class StereoGuiError(Exception):
    """A problem with the user's input that deserves a clear one-line message."""


class InputError(StereoGuiError):
    """Bad arguments or unusable input files (missing, corrupt, wrong size)."""


class CalibrationError(StereoGuiError):
    """Calibration could not be computed from the given data (no board, too few pairs)."""


class CalibrationFileError(StereoGuiError):
    """A calibration file is missing, corrupt, or holds matrices of the wrong shape."""


class CalibrationValueError(CalibrationFileError):
    """A calibration, or one of its parts, was built with a value no camera has (a matrix of the
    wrong shape or not finite, a focal length that is not positive, an unknown parameter name):
    raised on construction, without saying where the values came from (the file layer adds the
    file's name)."""


class SourceError(StereoGuiError):
    """A frame source could not be opened or stopped delivering frames."""


class SourceUnavailable(SourceError):
    """A source has no frame for now but expects to again (a camera that vanished is being
    opened again): read again later. The message says what is going on, for the user."""
