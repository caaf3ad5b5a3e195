"""Shared helpers for the system tests: where things are, how to run a tool."""
import contextlib
import json
import mmap
import os
import signal
import struct
import subprocess
import threading
import time
from pathlib import Path

import pytest

import mlipcan  # the project's Python package (pip install -e . by tools/deps.sh)
from mlipcan.settings import Settings

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / os.environ.get("MLIP_BUILD", "build")
SHARED = Path(os.environ.get("MLIP_SHARED", ROOT.parent / "shared"))
TOOLPATHS = SHARED / "toolpaths"
CONFIG = ROOT / "config"
# the package's view of the same: what its functions take as settings
S = Settings.from_environ(ROOT)
if Path(mlipcan.__file__).resolve().parent != ROOT / "python" / "mlipcan":
    pytest.exit(f"mlipcan is imported from {Path(mlipcan.__file__).parent}, not from this "
                f"checkout ({ROOT}): run tools/deps.sh (pip install -e .)", returncode=4)

# Every physical limit is asserted with this relative tolerance, above; and
# "the limit is used" is asserted below it (both sides of each bound).
REL = 1e-9


def tool(name):
    return str(BUILD / name)


def run(args, check=True, **kw):
    """Run a built tool; returns CompletedProcess with text output."""
    p = subprocess.run([tool(args[0])] + [str(a) for a in args[1:]], capture_output=True,
                       text=True, **kw)
    if check and p.returncode != 0:
        raise AssertionError(f"{args} exited {p.returncode}:\n{p.stderr}")
    return p


def sim_summary(path, *opts):
    p = run(["mlip-sim", "-q", "--summary", "-", *opts, path])
    return json.loads(p.stdout)


# ---- judging motion by the setpoints sent (mlip-rt --record), not by the
# controller's own counters or log

def record_rows(path):
    """The setpoints of mlip-rt --record (or mlip-sim --trace): [t, x, y, ...]
    per row, the header skipped."""
    return [list(map(float, r.split(","))) for r in Path(path).read_text().splitlines()[1:]]


def record_checked(config, program, record):
    """The whole record against the machine's limits and the program's path
    (mlip-check: acceleration, speed, contour, order), a stop allowed
    (--no-end): a dropped or jumping machine fails it."""
    p = run(["mlip-check", "--config", config, "--no-end", program, record], check=False)
    assert p.returncode == 0, p.stdout + p.stderr
    return p


def program_end(config, program, tmp_path):
    """Where the program ends: the last setpoint of mlip-sim's trace."""
    trace = tmp_path / "program-end.csv"
    run(["mlip-sim", "-q", "--config", config, "--trace", trace, program])
    return record_rows(trace)[-1][1:]


def braking_tail(rows):
    """The record's last deceleration to rest: (path mm, periods) from the
    last row at which the speed stopped falling to the end."""
    d = [sum((b - a) ** 2 for a, b in zip(p[1:], q[1:])) ** 0.5 for p, q in zip(rows, rows[1:])]
    k = len(d) - 1
    while k > 0 and d[k - 1] >= d[k]:
        k -= 1
    return sum(d[k:]), len(d) - k


def longest_rest(rows):
    """The longest stretch the setpoints stand still: (seconds by t, position)."""
    best, start = (0.0, None), 0
    for i in range(1, len(rows) + 1):
        if i == len(rows) or rows[i][1:] != rows[start][1:]:
            if rows[i - 1][0] - rows[start][0] > best[0]:
                best = (rows[i - 1][0] - rows[start][0], rows[start][1:])
            start = i
    return best


def offsets_file(path, *sets, config=CONFIG / "mill-3axis.ini"):
    """A sealed offsets file: mlip-offsets --init (all zero, G54, G28/G30 at
    HOME), then --set for each "KEY VALUES" (e.g. "G55 X10 Y20")."""
    run(["mlip-offsets", "--init", "--config", config, path])
    if sets:
        run(["mlip-offsets", *[a for s in sets for a in ("--set", s)], path])
    return path


@pytest.fixture(scope="session", autouse=True)
def built():
    for t in ("mlip-sim", "mlip-check"):
        if not (BUILD / t).exists():
            pytest.fail(f"{BUILD / t} missing: run make first")
    if not TOOLPATHS.is_dir():
        pytest.fail(f"{TOOLPATHS} missing: the shared toolpaths are needed (set MLIP_SHARED)")


# ---- the controller's processes on this host (--can none)

_n = [0]


def shm_name():
    _n[0] += 1
    return f"/mlip-pytest-{os.getpid()}-{_n[0]}"


def status(shm):
    p = subprocess.run([tool("mlip-ctl"), "--shm", shm, "status", "--json"], capture_output=True,
                       text=True)
    return json.loads(p.stdout) if p.stdout.strip() else None


def wait_for(pred, timeout=60.0, poll=0.02):
    """pred()'s first true value, polled until timeout s (None then): generous,
    a loaded host may be slow; a wait that succeeds costs no more."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        v = pred()
        if v:
            return v
        time.sleep(poll)
    return None


def periods_on(shm, n, timeout=60.0):
    """The status once the controller has run n more periods (its
    heartbeat): "nothing moves meanwhile" checked over the loop's own
    periods, not over a sleep a loaded host may spend elsewhere."""
    s0 = status(shm)
    assert s0 and s0["alive"], s0
    return wait_for(lambda: (lambda s: s if s and s["heartbeat"] >= s0["heartbeat"] + n
                             else None)(status(shm)), timeout)


@contextlib.contextmanager
def frozen(proc):
    """proc stopped (SIGSTOP, every thread of it seen stopped) for the block,
    continued (SIGCONT) after it: what the block reads of its segment stays
    put whatever the host's load (mlip-rt's heartbeat goes stale: late, not
    dead, for the feeder and mlip-ctl)."""
    proc.send_signal(signal.SIGSTOP)
    try:
        def stopped():
            tasks = Path(f"/proc/{proc.pid}/task")
            return all((t / "stat").read_text().rsplit(")", 1)[1].split()[0] in "tT"
                       for t in tasks.iterdir())
        assert wait_for(stopped, 10, 0.001), f"pid {proc.pid} did not stop"
        yield
    finally:
        proc.send_signal(signal.SIGCONT)


# The segment's record ring (include/mlip/ipc/ring.h, layout version 10): a
# record, the producer's and the consumer's free-running indices, the
# capacity, where the records start.
REC = struct.Struct("<QIHH6dddd")
HEAD, TAIL, CAPACITY, HDR_BYTES = 64, 128, 12, 24


class Ring:
    """The segment's record ring, read (and written behind the feeder's back,
    as a hostile local user would) by the tests."""

    def __init__(self, shm):
        fd = os.open("/dev/shm" + shm, os.O_RDWR)
        try:
            self.mem = mmap.mmap(fd, 0)
        finally:
            os.close(fd)
        self.cap = self.u32(CAPACITY)

    def u32(self, off):
        return struct.unpack_from("<I", self.mem, off)[0]

    def count(self):
        return (self.u32(HEAD) - self.u32(TAIL)) % 2**32

    def _off(self, index):
        return self.u32(HDR_BYTES) + (index % self.cap) * REC.size

    def read(self, index):
        return list(REC.unpack_from(self.mem, self._off(index)))

    def write(self, index, rec):
        REC.pack_into(self.mem, self._off(index), *rec)


class Log:
    """A process's output stream, read to its end by a thread as it comes. A
    pipe nobody reads fills (64 KB) and blocks its writer: mlip-rt's monitor
    thread, which also drains the --record queue (a record then loses its
    setpoints), a feeder, or a server's loop. Kept for failure messages."""

    def __init__(self, proc, name, stream=None):
        self.proc, self.name = proc, name
        self.stream = proc.stderr if stream is None else stream
        self.chunks = []
        self._t = threading.Thread(target=self._read, daemon=True)
        self._t.start()

    def _read(self):
        for line in self.stream:
            self.chunks.append(line)

    @property
    def lines(self):
        return "".join(self._text(list(self.chunks))).splitlines()

    def _text(self, chunks):
        return [c.decode(errors="replace") if isinstance(c, bytes) else c for c in chunks]

    def wait(self, pred, timeout=60):
        """The first line for which pred is true (None at the deadline)."""
        def first():
            return next((l for l in self.lines if pred(l)), None)
        return wait_for(first, timeout) if timeout > 0 else first()

    def join(self, timeout=30):
        self._t.join(timeout)

    def text(self):
        """Everything so far; all of it once the process has exited."""
        if self.proc.poll() is not None:
            self.join()
        return "".join(self._text(list(self.chunks)))


class Proc(subprocess.Popen):
    """subprocess.Popen whose piped stdout and stderr are drained as they come
    (.log: stderr, .out: stdout, each a Log), so a long-running tool never
    blocks on a full pipe; communicate() waits for the exit and returns the
    whole of both (str when text=True, as Popen's)."""

    live = []  # started by the running test: killed after it if still running

    def __init__(self, args, **kw):
        super().__init__([str(a) for a in args], **kw)
        Proc.live.append(self)
        name = Path(str(args[0])).name
        self.log = Log(self, name) if self.stderr is not None else None
        self.out = Log(self, name, self.stdout) if self.stdout is not None else None

    def communicate(self, input=None, timeout=None):
        if self.stdin is not None:
            if input is not None:
                self.stdin.write(input)
            self.stdin.close()
        self.wait(timeout)

        def whole(log):
            if log is None:
                return None
            text = log.text()
            return text if self.text_mode else text.encode()
        return whole(self.out), whole(self.log)

    def said(self):
        """Its stderr so far (for failure messages)."""
        return self.log.text() if self.log is not None else ""


def terminate(p, timeout=30):
    """SIGTERM (a controlled stop for mlip-rt), SIGKILL after timeout s;
    its exit code."""
    if p.poll() is None:
        p.send_signal(signal.SIGTERM)
        try:
            return p.wait(timeout)
        except subprocess.TimeoutExpired:
            p.kill()
    return p.wait()


@pytest.fixture(autouse=True)
def reap_procs():
    """No process a test started (Proc) outlives it, whatever failed."""
    yield
    for p in Proc.live:
        if p.poll() is None:
            p.kill()
            p.wait()
    Proc.live.clear()


@pytest.fixture
def controller():
    """Start mlip-rt --can none on a fresh segment; stop it (SIGTERM) after."""
    procs = []

    def start(config=CONFIG / "mill-3axis.ini", *extra):
        shm = shm_name()
        # this shared 2-core VM is not real-time (wake-ups late by tens of ms):
        # a stall hold (default 3 missed periods) would stop any long run here;
        # the stall tests give their own limit
        if "--stall-periods" not in extra:
            extra = ("--stall-periods", "100000", *extra)
        p = Proc([tool("mlip-rt"), "--config", config, "--can", "none", "--shm", shm, *extra],
                 stderr=subprocess.PIPE, text=True)
        procs.append(p)
        assert wait_for(lambda: (status(shm) or {}).get("alive") or p.poll() is not None, 60), \
            f"controller did not come up: {p.said()}"
        assert p.poll() is None, f"mlip-rt exited {p.returncode}: {p.said()}"
        return shm, p

    yield start
    for p in procs:
        terminate(p)
        # pytest shows this with a failing test only
        print(f"---- mlip-rt {' '.join(p.args[1:])} (exit {p.returncode}):\n{p.said()}")


def virtual_bus_sim(tmp_path, specs, module=None):
    """Simulated drives (specs: Drive keyword arguments, node 5 in the
    tests) and an optional CiA 401 module (node id) in one DriveSim on
    python-can's in-process virtual bus, and a canopen master Network on the
    same channel: (sim, net), both started; sim.stop(), net.disconnect()."""
    import can
    import canopen

    from mlipcan import drive as D

    chan = f"vbus-{time.monotonic_ns()}"
    sim = D.DriveSim(chan, specs, D.Recorder(tmp_path),
                     bus=can.Bus(interface="virtual", channel=chan))
    if module is not None:
        sim.add_module(module, 0)
    net = canopen.Network(can.Bus(interface="virtual", channel=chan))
    net.connect()
    sim.start()
    return sim, net
