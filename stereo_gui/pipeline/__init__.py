"""Frame processing below Qt: what the frame worker runs on each frame and the jobs the tabs
start, from a source's StereoFrame to the arrays and results a screen draws. No Qt here."""
