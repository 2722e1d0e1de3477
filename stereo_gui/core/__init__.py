"""Computation on numpy arrays with OpenCV: boards, calibration, matching, measurement. No Qt."""
