"""The screens of the main window, one module each: capture, calibration, live, measurements."""
