"""Widgets the screens are built from: image panels with markers and colour bars, coverage
guidance, the matcher parameters panel, the playback bar, small layout helpers."""
