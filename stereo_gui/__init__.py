"""Stereo GUI: calibrate a two-webcam stereo camera and read distances off a live depth view."""

__version__ = "0.1.0"
