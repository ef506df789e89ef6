"""Jobs as child processes: they die with their launcher, and inherit the files it passes."""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tests.processes import process_running, wait_until

ROOT = Path(__file__).resolve().parents[3]

#: A launcher process: starts one job that sleeps, prints the job's pid, then waits.
LAUNCHER = textwrap.dedent(
    """
    import sys, time
    from pathlib import Path
    from amaze.runs.launchers import Job, ProcessLauncher

    job = Job([sys.executable, "-c", "import time; time.sleep(60)"], Path(sys.argv[1]))
    process = ProcessLauncher(1).start(job)
    print(process.pid, flush=True)
    time.sleep(60)
    """
)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_a_job_dies_with_its_launcher_killed_outright(tmp_path: Path) -> None:
    launcher = subprocess.Popen(
        [sys.executable, "-c", LAUNCHER, str(tmp_path / "log.txt")],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert launcher.stdout is not None
        job = int(launcher.stdout.readline())
        assert process_running(job)
    finally:
        launcher.send_signal(signal.SIGKILL)
        launcher.communicate()
    wait_until(lambda: not process_running(job), timeout=10)


def test_a_job_inherits_the_files_passed_to_it(tmp_path: Path) -> None:
    from amaze.runs.launchers import Job, ProcessLauncher

    fd = os.open(tmp_path / "lock", os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    # the job holds the same open file: a lock taken through it is the launcher's
    probe = f"import fcntl; fcntl.flock({fd}, fcntl.LOCK_EX | fcntl.LOCK_NB); print('held')"
    job = Job([sys.executable, "-c", probe], tmp_path / "log.txt")
    process = ProcessLauncher(1, pass_fds=(fd,)).start(job)
    assert process.wait(timeout=30) == 0
    os.close(fd)
    assert (tmp_path / "log.txt").read_text().strip() == "held"
