"""The controller's process, segment and signals as a user (or a hostile local
user) meets them, on this host with --can none: a segment name another user
made, a full /dev/shm, attaching to a segment of another user, every stop
signal mid-program, an unprivileged controller. The tests run as root here;
those that need another user or a private mount namespace say so and skip
when they cannot have it."""
import os
import shutil
import signal
import subprocess

import pytest

from conftest import CONFIG, shm_name, status, tool, wait_for

ROOT_ONLY = pytest.mark.skipif(os.geteuid() != 0, reason="needs root (another user, a mount)")
NOBODY = ["setpriv", "--reuid=nobody", "--regid=nogroup", "--clear-groups"]


def rt_cmd(shm, *extra, config=CONFIG / "mill-3axis.ini"):
    return [tool("mlip-rt"), "--config", str(config), "--can", "none", "--shm", shm, *extra]


@ROOT_ONLY
def test_segment_name_made_by_another_user_is_refused():
    """Observed on main: nobody pre-creates /dev/shm/<name> as an empty file,
    a root controller formats it and nobody keeps ownership (could feed and
    override). Now: refused, with the owner named, the file left alone."""
    shm = shm_name()
    path = "/dev/shm" + shm
    subprocess.run(NOBODY + ["touch", path], check=True)
    try:
        p = subprocess.run(rt_cmd(shm), capture_output=True, text=True, timeout=10)
        assert p.returncode == 1, p.stderr
        assert f"{shm} exists and belongs to nobody, not to this controller's user root" \
            in p.stderr
        st = os.stat(path)
        assert st.st_uid == 65534 and st.st_size == 0  # left as it was
    finally:
        os.unlink(path)


@ROOT_ONLY
def test_full_dev_shm_is_a_message_not_sigbus():
    """Observed on main: SIGBUS (exit 135) on a full /dev/shm. Here a 64 KiB
    tmpfs over /dev/shm in a private mount namespace (the segment needs
    656256 bytes): a message at start-up, exit 1."""
    if shutil.which("unshare") is None:
        pytest.skip("no unshare")
    probe = subprocess.run(["unshare", "-m", "true"], capture_output=True)
    if probe.returncode != 0:
        pytest.skip("no private mount namespace here")
    cmd = " ".join(rt_cmd("/mlip-full"))
    p = subprocess.run(["unshare", "-m", "sh", "-c",
                        f"mount -t tmpfs -o size=64k tmpfs /dev/shm && exec {cmd}"],
                       capture_output=True, text=True, timeout=20)
    assert p.returncode == 1, (p.returncode, p.stderr)
    assert "/mlip-full: no room for the segment's 656256 bytes in /dev/shm" in p.stderr
    assert "df -h /dev/shm" in p.stderr
