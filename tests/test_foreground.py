"""The foreground commands' stop (``robogym_ray.foreground``), in real child processes: a stop
signal is taken whichever thread the kernel hands it to, and a stop that hangs still ends the
process, with its stacks on stderr."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from robogym_ray import children

# A child that waits for its stop, then does what the test gives it (``AFTER``).
CHILD = textwrap.dedent(
    """
    import signal, sys, threading, time
    from robogym_ray.foreground import StopSignals

    stop = StopSignals()
    if sys.argv[1] == "from-a-thread":
        # The signal lands in another thread: the main thread's wait must still wake.
        threading.Thread(
            target=lambda: signal.pthread_kill(threading.get_ident(), signal.SIGTERM)
        ).start()
    print("ready", flush=True)
    got = stop.wait(deadline_s=1.0)
    print(f"stopping on {got.name}", flush=True)
    if sys.argv[2] == "hang":
        time.sleep(120)  # a shutdown that never ends
    """
)


def run(where: str, after: str, stderr: Path, send: int | None = None) -> tuple[int, str, str]:
    """Start the child, send it ``send`` once it is ready; its exit status, stdout and stderr.
    (Its output is a few lines: it fits the pipe, so waiting before reading cannot block it.)"""
    with stderr.open("w") as err:
        proc = children.popen(
            [sys.executable, "-c", CHILD, where, after], stdout=subprocess.PIPE, stderr=err,
            text=True,
        )  # fmt: skip
    assert proc.stdout is not None and proc.stdout.readline() == "ready\n"
    if send is not None:
        proc.send_signal(send)
    proc.wait(timeout=60)  # the deadline is 1 s; the hang 120 s
    return proc.returncode, proc.stdout.read(), stderr.read_text()


def test_a_signal_taken_by_another_thread_still_stops_the_main_thread(tmp_path: Path) -> None:
    code, out, err = run("from-a-thread", "exit", tmp_path / "err")
    assert (code, out) == (0, "stopping on SIGTERM\n"), err


def test_sigint_stops_cleanly(tmp_path: Path) -> None:
    code, out, err = run("outside", "exit", tmp_path / "err", send=signal.SIGINT)
    assert (code, out) == (0, "stopping on SIGINT\n"), err


def test_a_stop_that_hangs_ends_at_its_deadline_with_its_stacks_on_stderr(tmp_path: Path) -> None:
    code, out, err = run("outside", "hang", tmp_path / "err", send=signal.SIGTERM)
    assert (code, out) == (1, "stopping on SIGTERM\n"), err
    assert err.startswith("Timeout (0:00:01)!"), err  # faulthandler's report, then the stacks
    sleep_line = 1 + next(i for i, line in enumerate(CHILD.splitlines()) if "time.sleep" in line)
    assert f'File "<string>", line {sleep_line}' in err, err  # where it hung
