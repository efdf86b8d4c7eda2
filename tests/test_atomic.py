"""Outputs keep the umask's permissions; in-place rewrites keep the file's mode."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest

from motionlab.atomic import atomic_path, current_umask
from motionlab.errors import InputError
from motionlab.session import SensorStream, Session, load_session, save_session


@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield
    os.umask(old)


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def test_new_output_gets_the_umask_mode(tmp_path, umask_022):
    assert current_umask() == 0o022
    with atomic_path(tmp_path / "a.txt") as tmp:
        tmp.write_text("x")
    assert _mode(tmp_path / "a.txt") == 0o644


def test_session_is_shareable_and_in_place_keeps_mode(tmp_path, umask_022):
    ses = Session(sensors={"s": SensorStream("s", np.arange(3) / 100.0, acc=np.zeros((3, 3)))})
    path = tmp_path / "session.h5"
    save_session(ses, path)
    assert _mode(path) == 0o644
    os.chmod(path, 0o640)
    save_session(load_session(path), path, force=True)
    assert _mode(path) == 0o640


def test_umask_077_stays_private(tmp_path):
    old = os.umask(0o077)
    try:
        with atomic_path(tmp_path / "b.txt") as tmp:
            tmp.write_text("x")
    finally:
        os.umask(old)
    assert _mode(tmp_path / "b.txt") == 0o600


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_force_never_replaces_a_device_or_pipe(tmp_path):
    """``-o /dev/full --force`` as root renamed a session file onto the device node; a path
    that is a pipe, socket or device (or a link to one) is refused, force or not."""
    from motionlab.errors import InputError

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    os.symlink(fifo, tmp_path / "link")
    for name in ("pipe", "link"):
        with pytest.raises(InputError, match="output is a named pipe .FIFO., not a regular file"):
            with atomic_path(tmp_path / name, force=True) as tmp:
                tmp.write_bytes(b"x")
    assert stat.S_ISFIFO(os.stat(fifo).st_mode) and os.path.islink(tmp_path / "link")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "pipe"]


def test_output_names_the_file_system_cannot_hold_or_that_name_a_folder(tmp_path):
    """A 300-character output name was an internal error (ENAMETOOLONG), a dangling link was
    replaced without force, and 'new.h5/' wrote a file called new.h5."""
    from motionlab.atomic import check_name_length, check_output

    with pytest.raises(InputError, match="a name of 303 bytes: too long for the file system"):
        check_output(tmp_path / ("x" * 300 + ".h5"), force=True)
    with pytest.raises(InputError, match="too long"):  # a folder on the way, not created yet
        check_name_length(tmp_path / ("y" * 300) / "session.h5")
    check_name_length(tmp_path / ("y" * 200) / "session.h5")
    link = tmp_path / "dangling.h5"
    link.symlink_to(tmp_path / "nowhere" / "x.h5")
    with pytest.raises(InputError, match="output exists"):
        check_output(link, force=False)
    assert check_output(link, force=True) == link
    with pytest.raises(InputError, match="ends in a separator: a folder, expected a file"):
        check_output(f"{tmp_path}/new.h5/", force=True)
