"""Reading and writing user data: calibrations, sessions, spreadsheets, exports, settings. No Qt."""
