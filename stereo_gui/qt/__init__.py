"""The Qt application: main window, tabs, widgets and the workers that run core/ off the UI thread."""
