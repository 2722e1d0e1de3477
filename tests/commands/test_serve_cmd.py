"""`stereo-gui serve`: the headless depth stream, as a robot's start-up script runs it."""

from __future__ import annotations

import sys
import time

import pytest

pytest.importorskip("foxglove")
pytest.importorskip("mcap")

from stereo_gui.cli import main
from stereo_gui.files.mcap_file import read_topics
from stereo_gui.pipeline.stream import TOPICS, DepthStream
from tests.cli_output import one_line, stop_with_signal


def test_serve_records_a_number_of_frames_and_ends(tmp_path, capsys):
    out = tmp_path / "run.mcap"
    code = main(["serve", "--source", "sim:wall:rig:1.5", "--frames", "12", "--mcap", str(out),
                 "--port", "0", "--region", "280,200,80,80", "--alarm-m", "2"])
    text = capsys.readouterr().out
    assert code == 0
    assert "ws://127.0.0.1:" in text and "12 frames" in text and f"recorded {out}" in text
    counts = read_topics(out)
    for key in ("depth", "left_info", "right_info", "tf", "region", "health", "left"):
        assert counts[TOPICS[key]] == 12, key
    assert 1 <= counts[TOPICS["points"]] <= 12  # (at most ten a second)


def test_serve_can_record_without_listening(tmp_path, capsys):
    out = tmp_path / "run.mcap"
    assert main(["serve", "--source", "sim", "--frames", "3", "--mcap", str(out),
                 "--no-server"]) == 0
    assert "ws://" not in capsys.readouterr().out
    assert read_topics(out)[TOPICS["depth"]] == 3


@pytest.mark.parametrize("argv, words", [
    (["--no-server"], ["--no-server", "--mcap"]),
    (["--alarm-m", "1"], ["--region"]),
    (["--region", "1,2,0,4"], ["region"]),
    (["--port", "70000"], ["--port"]),
    (["--mcap", "run.txt", "--frames", "1"], [".mcap"]),
    (["--preset", "nonesuch", "--frames", "1"], ["nonesuch"]),
])
def test_bad_options_are_one_line(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    port = [] if "--port" in argv else ["--port", "0"]
    try:
        code = main(["serve", "--source", "sim", *port, *argv])
    except SystemExit as exc:  # argparse's own refusals
        code = exc.code
    one_line(capsys.readouterr().err, code, *words)


def test_a_taken_port_is_one_line_and_exit_2(capsys):
    with DepthStream() as other:
        port = other.serve(port=0).rsplit(":", 1)[1]
        code = main(["serve", "--source", "sim", "--port", port, "--frames", "1"])
    one_line(capsys.readouterr().err, code, "in use", "--port")


@pytest.mark.slow
def test_sigterm_stops_it_with_the_recording_whole(tmp_path):
    out = tmp_path / "run.mcap"
    started = []

    def serving(proc) -> bool:
        started.append(proc.stdout.readline())
        assert started[-1].startswith("serving"), started
        time.sleep(1.5)
        return True

    code, rest, err = stop_with_signal([sys.executable, "-m", "stereo_gui", "serve", "--source",
                                        "sim", "--port", "0", "--mcap", str(out)], serving)
    assert code == 0, err
    assert "Traceback" not in err and "recorded" in rest
    assert read_topics(out)[TOPICS["depth"]] >= 1
    assert [p.name for p in tmp_path.iterdir()] == ["run.mcap"]  # no temporary file left


@pytest.mark.slow
def test_a_client_that_vanishes_leaves_no_error_on_the_terminal(tmp_path):
    """A robot's terminal shows the stream's own lines, not the SDK's about a client that went
    away without closing (they are the client's, and shown with -v)."""
    import socket

    def dropped_clients(proc) -> bool:
        first = proc.stdout.readline()
        port = int(first.split("ws://127.0.0.1:")[1].split()[0].rstrip(","))
        for _ in range(3):  # a WebSocket handshake, then the connection dropped
            with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
                sock.sendall(b"GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\n"
                             b"Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                             b"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: foxglove.sdk.v1"
                             b"\r\n\r\n")
                sock.recv(4096)
        time.sleep(1.0)
        return True

    code, _out, err = stop_with_signal([sys.executable, "-m", "stereo_gui", "serve", "--source",
                                        "sim", "--port", "0"], dropped_clients)
    assert code == 0 and err.strip() == "", err
