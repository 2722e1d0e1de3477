"""Dialogs: About and the choice of frame source."""
