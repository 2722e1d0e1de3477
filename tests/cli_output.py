"""What a command that refuses its input must print: one line, no traceback, exit status 2."""

from __future__ import annotations


def one_line(err: str, code: int, *words: str) -> str:
    """Check that `code` is 2 and `err` (what the terminal got on stderr) is one line holding
    every one of `words`, without a traceback; return that line."""
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def stop_with_signal(argv, ready, signum=None, timeout: float = 120.0, **popen):
    """Start `argv`, wait until `ready(proc)` says it is at work (it may read the process's
    output), send `signum` (SIGTERM) and wait for the end: (returncode, rest of stdout,
    stderr). The process is killed if anything goes wrong on the way."""
    import signal
    import subprocess
    import time

    popen = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, "text": True, **popen}
    proc = subprocess.Popen(argv, **popen)
    try:
        deadline = time.monotonic() + timeout
        while not ready(proc):
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM if signum is None else signum)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, out, err
