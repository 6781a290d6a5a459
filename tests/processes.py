"""What the tests that stop processes ask of /proc: whether a process still runs."""

from pathlib import Path
import time


def running(pid: int) -> bool:
    """Whether a process exists and is not a zombie (dead, its parent not told yet)."""
    try:
        state = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0]
    except OSError:
        return False
    return state != 'Z'


def gone_within(pid: int, seconds: float) -> bool:
    """Wait up to ``seconds`` for a process to stop running; return whether it did."""
    deadline = time.monotonic() + seconds
    while running(pid):
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)
    return True
