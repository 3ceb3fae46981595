"""A job run beside the caller's work in a forked child: its files, its errors, its end."""

import errno
import os
import time

import pytest

from esail_opt import processes


def test_a_job_beside_writes_its_file_while_the_body_writes_its_own(tmp_path):
    with processes.beside(lambda: (tmp_path / "child").write_text(str(os.getpid()))):
        (tmp_path / "parent").write_text(str(os.getpid()))
    child, parent = ((tmp_path / n).read_text() for n in ("child", "parent"))
    assert parent == str(os.getpid()) and child != parent


def test_the_jobs_error_is_raised_in_the_caller_with_its_errno(tmp_path):
    def full_disk():
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "x.png"))

    with pytest.raises(OSError) as caught:
        with processes.beside(full_disk):
            pass
    assert caught.value.errno == errno.ENOSPC and caught.value.filename.endswith("x.png")


def test_an_error_in_the_body_kills_the_child_before_it_is_raised(tmp_path):
    pid_file = tmp_path / "pid"

    def linger():
        pid_file.write_text(str(os.getpid()))
        time.sleep(60)

    started = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        with processes.beside(linger):
            while not pid_file.exists():
                time.sleep(0.01)
            raise KeyboardInterrupt
    assert time.monotonic() - started < 30
    assert not processes.alive(int(pid_file.read_text()))
