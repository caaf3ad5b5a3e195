"""The controller's process, segment and signals as a user (or a hostile local
user) meets them, on this host with --can none: a segment name another user
made, a full /dev/shm, attaching to a segment of another user, every stop
signal mid-program, an unprivileged controller. The tests run as root here;
those that need another user or a private mount namespace say so and skip
when they cannot have it."""
import math
import os
import shutil
import signal
import subprocess

import pytest

from conftest import (CONFIG, Proc, braking_tail, program_end, record_checked, record_rows,
                      shm_name, status, tool, wait_for)

ROOT_ONLY = pytest.mark.skipif(os.geteuid() != 0, reason="needs root (another user, a mount)")
NOBODY = ["setpriv", "--reuid=nobody", "--regid=nogroup", "--clear-groups"]


def rt_cmd(shm, *extra, config=CONFIG / "mill-3axis.ini"):
    return [tool("mlip-rt"), "--config", str(config), "--can", "none", "--shm", shm, *extra]


def rt_cmd_sched_other(shm, *extra):
    """An unprivileged controller runs SCHED_OTHER on a shared machine and
    misses periods: where mlip-rt treats a few missed periods as a stall
    (hold until an operator resumes), allow many, since these tests are
    about starting and running, not about timing."""
    usage = subprocess.run([tool("mlip-rt"), "--help"], capture_output=True, text=True).stdout
    more = ["--stall-periods", "100000"] if "--stall-periods" in usage else []
    return rt_cmd(shm, *more, *extra)


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
    some 650 KiB): a message at start-up, exit 1."""
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
    import re
    m = re.search(r"/mlip-full: no room for the segment's (\d+) bytes in /dev/shm", p.stderr)
    assert m and int(m.group(1)) > 64 * 1024, p.stderr  # more than the tmpfs holds
    assert "df -h /dev/shm" in p.stderr


FLOWER_LINES = 6000


@pytest.fixture
def flower(tmp_path):
    from conftest import TOOLPATHS
    prog = tmp_path / "flower.ngc"
    lines = (TOOLPATHS / "flower-spiral-2d.ngc").read_text().splitlines(True)[:FLOWER_LINES]
    prog.write_text("".join(lines))
    return prog


PAPER = CONFIG / "paper-2axis.ini"
T, A = 0.001, 1000.0  # its period and acceleration


def start_moving(controller, flower):
    shm, rt = controller(PAPER, "--record", flower.parent / "rt.csv")
    f = Proc([tool("mlip-feed"), "--shm", shm, "--quiet", str(flower)],
             stderr=subprocess.PIPE, text=True)
    assert wait_for(lambda: (status(shm) or {}).get("exec_seq", 0) > 50), "did not start"
    s = status(shm)
    assert s["state"] == "running", s
    return shm, rt, f


STOP_LINE = r"mlip-rt: stopped on the path: ([0-9.]+) mm in ([0-9]+) periods"


def stopped_on_the_path(rt, flower, tmp_path):
    """Judged by the setpoints mlip-rt sent (--record, complete once it has
    exited): moving when stopped, then a deceleration to rest (the last step
    at most one period of braking from rest) short of the program's end, and
    the whole record within every limit and on the path (mlip-check): a
    machine dropped or jumping fails it. Returns the braking (mm, periods)."""
    assert rt.wait(15) == 0
    rows = record_rows(flower.parent / "rt.csv")
    assert math.dist(rows[-1][1:], rows[-2][1:]) <= A * T * T * (1 + 1e-9), rows[-2:]
    assert math.dist(rows[-1][1:], program_end(PAPER, flower, tmp_path)) > 1.0
    record_checked(PAPER, flower, flower.parent / "rt.csv")
    mm, periods = braking_tail(rows)
    # at the flower's speeds (well above 1 mm/s) braking at <= 1000 mm/s^2
    # takes more than a period and more than a micrometre; a dropped machine
    # would show neither
    assert mm > 0.001 and periods > 1, (mm, periods)
    return mm, periods


@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGTERM, signal.SIGINT, signal.SIGQUIT])
def test_every_stop_signal_to_the_controller_stops_on_the_path(controller, flower, sig, tmp_path):
    """Observed on main: SIGHUP (a closed terminal, a dropped ssh session)
    killed mlip-rt mid-cut with no stop. Now each of the four: a controlled
    stop on the path, judged by the setpoints sent (a deceleration to rest
    within every limit), exit 0, and the feeder says the program stopped on
    the path (exit 4), not complete. mlip-rt's log says the same braking."""
    import re
    shm, rt, f = start_moving(controller, flower)
    rt.send_signal(sig)
    _, err = rt.communicate(timeout=15)
    assert rt.returncode == 0, err
    mm, periods = stopped_on_the_path(rt, flower, tmp_path)
    m = re.search(STOP_LINE, err)
    assert m, err
    # the log's braking is the record's last steps: its millimetres lie
    # between the path of its periods' last steps, give or take two periods
    # (counting conventions), rounded to um by the log; the stop may begin
    # while the speed still rises (the jerk limit), so not only the record's
    # last fall in speed
    log_mm, log_n = float(m.group(1)), int(m.group(2))
    rows = record_rows(flower.parent / "rt.csv")
    step = [math.dist(p[1:], q[1:]) for p, q in zip(rows, rows[1:])]
    lo, hi = sum(step[-max(log_n - 2, 1):]), sum(step[-(log_n + 2):])
    assert log_n > 1 and lo - 0.0005 <= log_mm <= hi + 0.0005, (m.group(0), lo, hi, mm, periods)
    assert f"mlip-rt: {signal.Signals(sig).name}: stopped on the path, exiting" in err
    ferr = f.communicate(timeout=15)[1]
    assert f.returncode == 4, ferr
    assert "program stopped on the path at line" in ferr
    assert "program complete" not in ferr


@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGTERM])
def test_sighup_to_the_feeder_is_sigterm(controller, flower, sig, tmp_path):
    """Observed on main: SIGHUP killed mlip-feed silently (and the machine ran
    on to the end of what it had). Now SIGHUP does what SIGTERM does: the
    controller stops on the path, the feeder reports the line and the block
    to resume from, exit 128 + signal."""
    shm, rt, f = start_moving(controller, flower)
    f.send_signal(sig)
    ferr = f.communicate(timeout=15)[1]
    assert f.returncode == 128 + sig, ferr
    name = signal.Signals(sig).name
    assert f"mlip-feed: {name}: stopping the machine on the path" in ferr
    assert "interrupted: machine stopped on the path at line" in ferr, ferr
    s = wait_for(lambda: (lambda s: s if s and s["state"] == "idle" else None)(status(shm)), 60)
    assert s, status(shm)
    assert s["stops"] >= 1 and s["stop_mm"] > 0.001 and s["stop_periods"] > 1, s
    assert rt.poll() is None  # the controller itself goes on
    rt.send_signal(signal.SIGTERM)  # (at rest: nothing more to record)
    stopped_on_the_path(rt, flower, tmp_path)


UNIT = CONFIG.parent / "tools" / "systemd" / "mlip-rt.service"


def unit_keys():
    keys, section = {}, None
    for line in UNIT.read_text().splitlines():
        line = line.strip()
        if not line or line[0] in "#;":
            continue
        if line.startswith("["):
            section = line.strip("[]")
            continue
        k, v = line.split("=", 1)
        keys[(section, k)] = v
    return keys


def test_systemd_unit_parses_and_brakes_before_the_kill(tmp_path):
    """The shipped unit: systemd's own parser accepts every line (no unknown
    key, no bad value: systemd-analyze only warns about those, so its
    output must be empty), and the keys that make a stop safe are there."""
    k = unit_keys()
    s = lambda key: k[("Service", key)]
    assert s("KillSignal") == "SIGTERM" and s("SendSIGHUP") == "no" and s("Restart") == "no"
    assert s("KillMode") == "mixed"  # SIGTERM to mlip-rt alone; SIGKILL only after the timeout
    assert int(s("TimeoutStopSec")) >= 10
    assert s("LimitMEMLOCK") == "infinity"
    argv = s("ExecStart").split()
    prio = int(argv[argv.index("--priority") + 1])
    assert 1 <= prio <= int(s("LimitRTPRIO"))
    assert s("CPUAffinity") == argv[argv.index("--cpu") + 1]
    # every option the unit passes is one mlip-rt knows
    usage = subprocess.run([tool("mlip-rt"), "--help"], capture_output=True, text=True).stdout
    for opt in (a for a in argv if a.startswith("--")):
        assert f"  {opt} " in usage, opt
    if shutil.which("systemd-analyze") is None:
        pytest.skip("no systemd-analyze: the keys were checked above")
    unit = tmp_path / "mlip-rt.service"
    unit.write_text(UNIT.read_text().replace("/usr/local/bin/mlip-rt", tool("mlip-rt")))
    p = subprocess.run(["systemd-analyze", "verify", "--man=no", str(unit)],
                       capture_output=True, text=True)
    assert p.returncode == 0 and p.stderr.strip() == "" and p.stdout.strip() == "", p.stderr


@ROOT_ONLY
def test_unprivileged_controller_runs_a_program():
    """Observed on main: mlip-rt as an ordinary user did not start ("cannot
    start the loop: Resource temporarily unavailable": an 8 MiB default
    thread stack under mlockall against the 8 MiB RLIMIT_MEMLOCK). Now: it
    starts on SCHED_OTHER with the warnings, and runs a whole program fed by
    the same user. A root feeder refuses that user's segment unless told
    the controller's user (MLIP_SHM_OWNER)."""
    from conftest import ROOT
    shm = shm_name()
    rt = Proc(NOBODY + rt_cmd_sched_other(shm), stderr=subprocess.PIPE, text=True)
    env = dict(os.environ, MLIP_SHM_OWNER="nobody")
    ctl = lambda: subprocess.run([tool("mlip-ctl"), "--shm", shm, "status", "--json"], env=env,
                                 capture_output=True, text=True)
    try:
        assert wait_for(lambda: ctl().returncode == 0), "controller did not come up"
        assert os.stat("/dev/shm" + shm).st_uid == 65534
        demo = ROOT / "examples" / "demo.ngc"
        p = subprocess.run([tool("mlip-feed"), "--shm", shm, "-q", str(demo)],
                           capture_output=True, text=True, timeout=30)
        assert p.returncode == 1 and f"segment {shm} belongs to nobody, neither you (root) " \
            "nor root" in p.stderr and "MLIP_SHM_OWNER=nobody" in p.stderr, p.stderr
        p = subprocess.run(NOBODY + [tool("mlip-feed"), "--shm", shm, str(demo)],
                           capture_output=True, text=True, timeout=60)
        assert p.returncode == 0 and "program complete" in p.stderr, p.stderr
        assert status(shm) is None  # root's mlip-ctl refuses nobody's segment too
        s = ctl()
        assert '"exec_seq": 1820' in s.stdout and '"state": "idle"' in s.stdout, s.stdout
    finally:
        rt.send_signal(signal.SIGTERM)
        err = rt.communicate(timeout=10)[1]
    assert rt.returncode == 0, err
    assert "no SCHED_FIFO (not permitted): the loop runs SCHED_OTHER" in err
    assert "cannot start the loop" not in err and "1820 records taken" in err, err


@ROOT_ONLY
def test_memlock_too_small_runs_unlocked_and_names_the_limit():
    """A memlock limit that mlockall fits but the loop's stack would not:
    unlocked, with the exact limit to raise, still running."""
    if shutil.which("prlimit") is None:
        pytest.skip("no prlimit")
    syms = subprocess.run(["nm", tool("mlip-rt")], capture_output=True, text=True).stdout
    if "__asan_init" in syms:
        pytest.skip("AddressSanitizer makes mlockall a no-op: nothing is locked to check")
    shm = shm_name()
    rt = Proc(NOBODY + ["prlimit", "--memlock=5500000"] + rt_cmd(shm),
              stderr=subprocess.PIPE, text=True)
    try:
        env = dict(os.environ, MLIP_SHM_OWNER="nobody")
        up = lambda: subprocess.run([tool("mlip-ctl"), "--shm", shm, "status", "--json"],
                                    env=env, capture_output=True, text=True).returncode == 0
        assert wait_for(up), "controller did not come up"
    finally:
        rt.send_signal(signal.SIGHUP)
        err = rt.communicate(timeout=10)[1]
    assert rt.returncode == 0, err
    # either the check after mlockall (this build) or mlockall itself (a
    # sanitizer build maps more than the limit): both name the limit
    assert "memory not locked" in err and "RLIMIT_MEMLOCK" in err and "5371 KiB" in err, err
    assert "LimitMEMLOCK=infinity" in err and "memory locked" not in err


@ROOT_ONLY
def test_unprivileged_latency_tool_runs():
    from conftest import ROOT
    p = subprocess.run(NOBODY + [tool("mlip-latency"), "--plan", str(ROOT / "examples" / "demo.ngc"),
                                 "-D", "1", "-q"], capture_output=True, text=True, timeout=30)
    assert p.returncode == 0, p.stderr
    out = p.stdout + p.stderr
    assert "mlip-latency plan:" in out and "cannot start" not in out, out
    assert "no SCHED_FIFO (not permitted)" in p.stderr
    syms = subprocess.run(["nm", tool("mlip-latency")], capture_output=True, text=True).stdout
    if "__asan_init" not in syms:  # ASan makes mlockall a no-op
        assert "memory not locked" in p.stderr, p.stderr


@ROOT_ONLY
def test_shm_group_lets_its_members_feed():
    """--shm-group: mode 0660 and that group; a member of it (another user)
    feeds a whole program, naming the controller's user in MLIP_SHM_OWNER; a
    user outside the group is refused by the kernel."""
    from conftest import ROOT
    shm = shm_name()
    rt = Proc(NOBODY + rt_cmd_sched_other(shm, "--shm-group", "nogroup"),
              stderr=subprocess.PIPE, text=True)
    env = dict(os.environ, MLIP_SHM_OWNER="nobody")
    daemon = ["setpriv", "--reuid=daemon", "--regid=daemon"]
    ctl = lambda: subprocess.run(daemon + ["--groups=nogroup", tool("mlip-ctl"), "--shm", shm,
                                           "status", "--json"], env=env, capture_output=True,
                                 text=True)
    try:
        assert wait_for(lambda: ctl().returncode == 0), "controller did not come up"
        st = os.stat("/dev/shm" + shm)
        assert st.st_mode & 0o777 == 0o660 and st.st_uid == 65534 and st.st_gid == 65534
        demo = str(ROOT / "examples" / "demo.ngc")
        p = subprocess.run(daemon + ["--groups=nogroup", tool("mlip-feed"), "--shm", shm, demo],
                           env=env, capture_output=True, text=True, timeout=60)
        assert p.returncode == 0 and "program complete" in p.stderr, p.stderr
        p = subprocess.run(daemon + ["--clear-groups", tool("mlip-feed"), "--shm", shm, demo],
                           env=env, capture_output=True, text=True, timeout=60)
        assert p.returncode == 1 and "permission denied: run as mlip-rt's user or group" \
            in p.stderr, p.stderr
    finally:
        rt.send_signal(signal.SIGTERM)
        err = rt.communicate(timeout=10)[1]
    assert rt.returncode == 0 and "1820 records taken" in err, err
