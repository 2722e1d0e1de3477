"""MCAP recordings of the depth stream's topics (pipeline.stream), written atomically: the
Foxglove SDK writes chunked, zstd-compressed MCAP (level ZSTD_LEVEL) to a temporary file beside
the target, and
only a file that reads back whole (the `mcap` reader finds its summary and every message it
counts) is renamed into place. A recording that cannot be finished leaves the earlier file as
it was."""

from __future__ import annotations

import contextlib
import logging
import os
from pathlib import Path

import foxglove
from foxglove.mcap import MCAPCompression, MCAPWriteOptions, MCAPWriter
from mcap.reader import make_reader

from stereo_gui.core.errors import InputError
from stereo_gui.files.atomic import atomic_path

log = logging.getLogger(__name__)

# zstd's fastest level: 545 kB a frame of the live preset at 640x480 for 6.6 ms of CPU, where
# the default level gives 500 kB for 8.3 ms, lz4 637 kB for 6.0 ms and no compression 1146 kB
# for 4.1 ms (all topics; scripts/bench_stream.py's machine)
ZSTD_LEVEL = 1


def verify_mcap(path: Path) -> None:
    """Raise InputError unless `path` is an MCAP file whose summary the reader finds."""
    try:
        with open(path, "rb") as f:
            summary = make_reader(f).get_summary()
    except Exception as exc:  # the reader's own errors for a cut or corrupt file
        raise InputError(f"the recording {path.name} does not read back as MCAP: {exc}") from exc
    if summary is None:
        raise InputError(f"the recording {path.name} has no summary: it was not closed whole")


def read_topics(path: str | os.PathLike[str]) -> dict[str, int]:
    """How many messages each topic of an MCAP file holds (from its statistics)."""
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    if summary is None or summary.statistics is None:
        raise InputError(f"{path} has no statistics to count its messages by")
    counts = summary.statistics.channel_message_counts
    return {ch.topic: int(counts.get(cid, 0)) for cid, ch in summary.channels.items()}


class McapRecording:
    """An MCAP file being written by the SDK for `context`'s channels; `close` finishes it and
    renames it into place (InputError when it cannot be written or read back)."""

    def __init__(self, path: Path, context: foxglove.Context) -> None:
        self.path = Path(path)
        if self.path.suffix.lower() != ".mcap":
            raise InputError(f"a recording's name must end in .mcap, not {self.path.name}")
        if not self.path.parent.is_dir():
            raise InputError(f"cannot record to {self.path}: its folder does not exist")
        self._stack = contextlib.ExitStack()
        tmp = self._stack.enter_context(atomic_path(self.path, verify=verify_mcap))
        try:
            options = MCAPWriteOptions(compression=MCAPCompression.Zstd,
                                       compression_level=ZSTD_LEVEL)
            self._writer: MCAPWriter | None = foxglove.open_mcap(
                str(tmp), allow_overwrite=True, context=context, writer_options=options)
        except Exception as exc:
            self._stack.__exit__(type(exc), exc, exc.__traceback__)
            raise InputError(f"cannot record to {self.path}: {exc}") from exc

    def close(self) -> Path:
        """Finish the file and move it into place; its path."""
        writer, self._writer = self._writer, None
        if writer is None:
            return self.path
        try:
            writer.close()
        except Exception as exc:
            self._stack.__exit__(type(exc), exc, exc.__traceback__)
            raise InputError(f"cannot finish the recording {self.path}: {exc}") from exc
        self._stack.close()  # checks the file and renames it
        log.info("recorded %s", self.path)
        return self.path
