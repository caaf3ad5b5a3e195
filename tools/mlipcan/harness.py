"""Glue for the end-to-end CAN runs: mlip-rt on a real (v)CAN interface, the
listener (mlipcan.listen, tools/mlip-listen.py) recording the bus, mlip-feed
streaming a program, mlip-ctl commands while it runs, and the comparisons
against the offline simulator (mlip-sim) and the checker (mlip-check).

Used by tools/demo.sh (through tools/mlip-demo.py) and the CAN tests
(tests/can). Standard library only: every Python import costs seconds in the
software-emulated test VM.
"""
import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from . import decoders, layout, listen, sources  # noqa: F401 (the tests' API)

ROOT = Path(__file__).resolve().parents[2]
BUILD = ROOT / os.environ.get("MLIP_BUILD", "build")
SHARED = Path(os.environ.get("MLIP_SHARED", ROOT.parent / "shared"))
TOOLPATHS = SHARED / "toolpaths"
CONFIG = ROOT / "config"
LISTEN = ROOT / "tools" / "mlip-listen.py"
DRIVE_SIM = ROOT / "tools" / "mlip-drive-sim.py"
PY = sys.executable
IFACE = os.environ.get("MLIP_VCAN_IFACE", "vcan0")
IN_VM = os.environ.get("MLIP_IN_VM") == "1"
# Generous waits: in the emulated VM a process start takes seconds.
START_TIMEOUT = float(os.environ.get("MLIP_CAN_START_TIMEOUT", "240"))
# The listener: a fork of this process running its main() (default), or a
# fresh `python tools/mlip-listen.py` (MLIP_CAN_LISTEN_EXEC=1: the real CLI,
# but a Python start costs 20-35 s in the emulated VM).
EXEC_LISTENER = os.environ.get("MLIP_CAN_LISTEN_EXEC") == "1"
# Also write the listener's candump log (can.log) in each run's directory.
KEEP_LOG = os.environ.get("MLIP_CAN_LOG") == "1"


def tool(name):
    return str(BUILD / name)


def setup_of(config):
    """Axes, nodes, counts per unit, ids of a machine INI (the listener's reader)."""
    return listen.Setup.from_ini(config)


def prime_dbc_cache():
    """Read the DBC with cantools once, so listener processes find its layout
    in the cache and skip the (slow in the VM) cantools import."""
    return layout.load_dbc(layout.DEFAULT_DBC, ROOT / "build")[1]


# ------------------------------------------------------------------ numbers

def to_counts(pos, cpu):
    """round(pos * cpu), ties away from zero: mlip_can_counts of canenc.h (the
    product is the same IEEE double multiplication as in C)."""
    x = pos * cpu
    a = abs(x)
    r = math.floor(a)
    if a - r >= 0.5:  # exact for |x| < 2^52
        r += 1
    return int(-r if x < 0 else r)


def read_trace(path):
    """mlip-sim --trace CSV -> (header, rows of floats)."""
    with open(path) as fh:
        header = fh.readline().strip().split(",")
        rows = [tuple(float(v) for v in line.split(",")) for line in fh if line.strip()]
    return header, rows


def trace_counts(rows, cpu):
    return [tuple(to_counts(r[1 + i], c) for i, c in enumerate(cpu)) for r in rows]


def read_can_csv(path, n):
    """The listener's --csv -> (cycles, t seconds, counts tuples)."""
    cyc, ts, cnt = [], [], []
    with open(path) as fh:
        header = fh.readline().strip().split(",")
        assert header[:2] == ["cycle", "t"] and len(header) == 2 + 2 * n, header
        for line in fh:
            f = line.rstrip("\n").split(",")
            cyc.append(int(f[0]))
            ts.append(float(f[1]))
            cnt.append(tuple(int(v) for v in f[2 + n:]))
    return cyc, ts, cnt


def write_positions_csv(path, counts, cpu, period_s, cycles=None):
    """A trace for mlip-check: t,x,y,... from decoded counts, t = k T, k the
    row's index or, given cycles, its bus cycle number (holes where cycles
    were lost: mlip-check takes no difference across them)."""
    n = len(cpu)
    names = "xyzabc"[:n]  # header only; mlip-check reads the columns by position
    ks = range(len(counts)) if cycles is None else [c - cycles[0] for c in cycles]
    with open(path, "w") as fh:
        fh.write("t," + ",".join(names) + "\n")
        for k, c in zip(ks, counts):
            fh.write(repr(k * period_s) + "," + ",".join(repr(c[i] / cpu[i]) for i in range(n)) + "\n")


def cut_program(src, n_lines, dst):
    """The first n_lines lines of a program (its header sets units and modes)."""
    with open(src) as fh, open(dst, "w") as out:
        for i, line in enumerate(fh):
            if i >= n_lines:
                break
            out.write(line)
    return dst


def run(args, check=True, timeout=600, **kw):
    p = subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=timeout, **kw)
    if check and p.returncode != 0:
        raise AssertionError(f"{' '.join(map(str, args))} exited {p.returncode}:\n{p.stderr}")
    return p


def simulate(config, ngc, workdir, *sim_args):
    """mlip-sim on the same machine and program: (rows, summary)."""
    trace = Path(workdir) / "sim.csv"
    summ = Path(workdir) / "sim.json"
    run([tool("mlip-sim"), "-q", "--config", config, "--trace", trace, "--summary", summ,
         *sim_args, ngc])
    return read_trace(trace)[1], json.loads(summ.read_text())


def mlip_check(config, ngc, trace_csv, quantum, json_out=None):
    args = [tool("mlip-check"), "--config", config, "--quantum", repr(quantum)]
    if json_out:
        args += ["--json", json_out]
    p = run(args + [ngc, trace_csv], check=False)
    js = json.loads(Path(json_out).read_text()) if json_out and Path(json_out).exists() else None
    return p, js


def check_bounds(config, js, quantum, max_abs, rel=1e-9):
    """mlip-check's verdict redone from its --json measurements, without the
    end-on-the-last-point condition (after a stop the machine rests elsewhere
    on the path): the bounds of tools/mlip-check.c and check.c exactly, with
    abs_acc = rounding floor (8 max|x| DBL_EPSILON / T^2) + 4 quantum / T^2:
    acceleration <= A (1 + rel) + abs_acc, axis velocity and tool speed
    <= limit (1 + rel) + abs_acc T, contour <= eps (1 + rel) + quantum, no
    sample out of order.
    Returns the violations (strings)."""
    m = MachineLimits(config)
    T = m.period_s
    abs_acc = 8 * max_abs * sys.float_info.epsilon / T**2 + 4 * quantum / T**2
    bad = []
    for k, a in enumerate(js["max_axis_accel"]):
        lim = m.accel[k] * (1 + rel) + abs_acc
        if a > lim:
            bad.append(f"axis {m.axes[k]} acceleration {a:.12g} > {lim:.12g}")
    for k, v in enumerate(js["max_axis_vel"]):
        lim = m.vel[k] * (1 + rel) + abs_acc * T
        if v > lim:
            bad.append(f"axis {m.axes[k]} velocity {v:.12g} > {lim:.12g}")
    lim = m.vmax * (1 + rel) + abs_acc * T
    if js["max_speed_mm_s"] > lim:
        bad.append(f"tool speed {js['max_speed_mm_s']:.12g} > {lim:.12g}")
    lim = m.eps * (1 + rel) + quantum
    if js["max_contour_error_mm"] > lim:
        bad.append(f"contour error {js['max_contour_error_mm']:.12g} > {lim:.12g}")
    if js.get("order_errors"):
        bad.append(f"{js['order_errors']} sample(s) out of order along the path")
    return bad


def machine_of(config):
    """The configuration as the C reader parsed it (mlip-config --json): one
    INI reader for every tool, never a second one here."""
    return json.loads(run([tool("mlip-config"), "--json", config]).stdout)


class MachineLimits:
    """The few [TRAJ]/[AXIS_*] numbers the checks need (from machine_of)."""

    def __init__(self, config):
        m = machine_of(config)["machine"]
        axes = m["axes"]
        self.axes = [a["letter"] for a in axes]
        self.vmax = float(m["max_linear_velocity"])
        self.eps = float(m["contour_tolerance"])
        self.period_s = float(m["period"])
        self.accel = [float(a["max_acceleration"]) for a in axes]
        self.vel = [float(a["max_velocity"]) for a in axes]
        self.home = [float(a["home"]) for a in axes]


# ------------------------------------------------------------------ alignment

def align(can_counts, trc):
    """Offset o such that CAN cycle o + i carries trace row i. The controller
    sends the home position while idle and pre-reading; the first row of the
    trace that differs from its start is matched with the first cycle on the
    bus that differs from home. Returns (offset, explanation)."""
    home = trc[0]
    k0 = next((i for i, c in enumerate(trc) if c != home), None)
    c0 = next((i for i, c in enumerate(can_counts) if c != home), None)
    if k0 is None:
        raise AssertionError("the simulated trace never leaves its start point (in counts)")
    if c0 is None:
        raise AssertionError(f"the bus never leaves the home position {home} (counts): "
                             f"{len(can_counts)} cycles seen")
    return c0 - k0, f"trace row {k0} (first to move) is bus cycle index {c0}"


def first_mismatch(can_counts, trc, offset):
    """None when can_counts[offset + i] == trc[i] for every row, else a message."""
    if offset < 0:
        return f"negative offset {offset}: the bus moved before the trace did"
    if offset + len(trc) > len(can_counts):
        return (f"the bus has {len(can_counts)} cycles, the trace needs {offset + len(trc)} "
                f"(offset {offset} + {len(trc)} rows)")
    for i, want in enumerate(trc):
        got = can_counts[offset + i]
        if got != want:
            return f"trace row {i} (bus cycle index {offset + i}): bus {got}, sim {want}"
    return None


# ------------------------------------------------------------------ processes

class Forked:
    """The Popen calls Proc uses, for a forked child running fn()."""

    def __init__(self, fn, out, err):
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:  # child: never returns
            rc = 1
            try:
                os.dup2(out.fileno(), 1)
                os.dup2(err.fileno(), 2)
                nul = os.open(os.devnull, os.O_RDONLY)
                os.dup2(nul, 0)
                sys.stdout = open(1, "w", buffering=1, closefd=False)
                sys.stderr = open(2, "w", buffering=1, closefd=False)
                signal.signal(signal.SIGTERM, signal.SIG_DFL)
                signal.signal(signal.SIGINT, signal.SIG_DFL)
                rc = fn()
            except SystemExit as e:
                rc = e.code if isinstance(e.code, int) else 1
            except BaseException:
                import traceback

                traceback.print_exc()
            finally:
                try:
                    sys.stdout.flush()
                    sys.stderr.flush()
                finally:
                    os._exit(rc if isinstance(rc, int) else 1)
        self.pid = pid
        self.returncode = None

    def poll(self):
        if self.returncode is None:
            pid, st = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.returncode = os.waitstatus_to_exitcode(st)
        return self.returncode

    def wait(self, timeout=None):
        t_end = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            if t_end is not None and time.monotonic() > t_end:
                raise subprocess.TimeoutExpired(f"pid {self.pid}", timeout)
            time.sleep(0.02)
        return self.returncode

    def send_signal(self, sig):
        if self.poll() is None:
            os.kill(self.pid, sig)

    def kill(self):
        self.send_signal(signal.SIGKILL)


class Proc:
    """A child process with its stderr in a file, waited for a ready line.
    fn instead of args: a forked copy of this process runs fn() (the listener:
    no interpreter start, no imports; that takes tens of seconds in the VM)."""

    def __init__(self, name, args, workdir, env=None, fn=None):
        self.name = name
        self.args = [str(a) for a in args]
        self.err_path = Path(workdir) / f"{name}.err"
        self.out_path = Path(workdir) / f"{name}.out"
        self._err = open(self.err_path, "w")
        self._out = open(self.out_path, "w")
        if fn is not None:
            self.p = Forked(fn, self._out, self._err)
        else:
            self.p = subprocess.Popen(self.args, stdout=self._out, stderr=self._err, env=env,
                                      stdin=subprocess.DEVNULL)
        self.rc = None

    def stderr(self):
        return self.err_path.read_text(errors="replace")

    def stdout(self):
        return self.out_path.read_text(errors="replace")

    def wait_for(self, text, timeout=START_TIMEOUT):
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            if text in self.stderr():
                return
            if self.p.poll() is not None:
                raise AssertionError(f"{self.name} exited {self.p.returncode} before '{text}':\n"
                                     f"{self.stderr()}")
            time.sleep(0.05)
        raise AssertionError(f"{self.name}: no '{text}' within {timeout} s:\n{self.stderr()}")

    def terminate(self, timeout=120):
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGTERM)
        try:
            self.rc = self.p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.p.kill()
            self.rc = self.p.wait()
            raise AssertionError(f"{self.name} ignored SIGTERM for {timeout} s:\n{self.stderr()}")
        finally:
            self._err.close()
            self._out.close()
        return self.rc

    def kill(self):
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait()
        self._err.close()
        self._out.close()


def parse_rt_exit(stderr):
    """mlip-rt's last line: 'stopped after N periods: F frames sent, D dropped
    (tx queue), B bus errors, O overruns, U underruns, R records taken; ...'."""
    import re

    line = [l for l in stderr.splitlines() if "stopped after" in l]
    if not line:
        raise AssertionError(f"mlip-rt printed no 'stopped after' line:\n{stderr}")
    line = line[-1]
    m = re.search(r"stopped after (\d+) periods: (\d+) frames sent, (\d+) dropped", line)
    if not m:
        raise AssertionError(f"cannot read mlip-rt's exit line: {line}")
    out = {"periods": int(m.group(1)), "frames_sent": int(m.group(2)),
           "tx_dropped": int(m.group(3)), "line": line}
    for key in ("overruns", "underruns", "bus errors", "records taken"):
        mm = re.search(r"(\d+) " + key, line)
        if mm:
            out[key.replace(" ", "_")] = int(mm.group(1))
    return out


class DriveSim:
    """tools/mlip-drive-sim.py as a child process: simulated CiA 402 drives on
    iface, their records in workdir/drives/ (events.jsonl, sync.csv), fault
    injection at run time through workdir/drives.ctl.

        sim = DriveSim(tmp, nodes=[1, 2, 3], starts={1: 1234}, inject=["2:never-enable"])
        sim.inject("1:fault=0x2310"); sim.events("state", 1); sim.sync_rows()
        sim.stop()
    """

    def __init__(self, workdir, nodes=None, config=None, starts=None, states=None, inject=(),
                 iface=IFACE, args=(), name="drivesim"):
        w = Path(workdir)
        self.rec = w / "drives"
        self.ctl = w / "drives.ctl"
        self.ctl.write_text("")
        a = [PY, DRIVE_SIM, "--can", iface, "--record", self.rec, "--control", self.ctl]
        if config is not None:
            a += ["--config", config]
        if nodes is not None:
            a += ["--nodes", ",".join(map(str, nodes))]
        for n, c in (starts or {}).items():
            a += ["--start", f"{n}={c}"]
        for n, st in (states or {}).items():
            a += ["--state", f"{n}={st}"]
        for i in inject:
            a += ["--inject", i]
        self.proc = Proc(name, a + list(args), w)
        self.proc.wait_for(": ready")

    def inject(self, line):
        """'N:WHAT[=ARG]', taken within 20 ms (see mlip-drive-sim.py)."""
        with open(self.ctl, "a") as fh:
            fh.write(line + "\n")

    def events(self, kind=None, node=None):
        out = []
        path = self.rec / "events.jsonl"
        for line in path.read_text().splitlines() if path.exists() else ():
            if not line.endswith("}"):
                continue  # being written
            e = json.loads(line)
            if (kind is None or e["kind"] == kind) and (node is None or e["node"] == node):
                out.append(e)
        return out

    def wait_event(self, pred, what, timeout=START_TIMEOUT):
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            ev = [e for e in self.events() if pred(e)]
            if ev:
                return ev
            if self.proc.p.poll() is not None:
                raise AssertionError(f"drive simulator exited {self.proc.p.returncode}:\n"
                                     f"{self.proc.stderr()}")
            time.sleep(0.02)
        raise AssertionError(f"drive simulator recorded no {what} within {timeout} s")

    def sync_rows(self):
        """sync.csv as dicts (written every few ms: a last partial line is skipped)."""
        rows = []
        path = self.rec / "sync.csv"
        with open(path) as fh:
            fh.readline()
            for line in fh:
                if not line.endswith("\n"):
                    break
                f = line.rstrip("\n").split(",")
                rows.append({"sync": int(f[0]), "node": int(f[1]), "t": float(f[2]),
                             "state": f[3], "cw": int(f[4]),
                             "target": int(f[5]) if f[5] else None, "fresh": f[6] == "1",
                             "actual": int(f[7]), "sw": int(f[8])})
        return rows

    def wait_sync_rows(self, pred, timeout=START_TIMEOUT):
        t_end = time.monotonic() + timeout
        while True:
            rows = self.sync_rows()
            if pred(rows) or time.monotonic() > t_end:
                return rows
            time.sleep(0.05)

    def stop(self, timeout=120):
        """SIGTERM: the records are written, the summary line printed. Returns the exit code."""
        return self.proc.terminate(timeout=timeout)


def targets_by_sync(rows, nodes):
    """DriveSim.sync_rows() -> per SYNC with a fresh target for every node:
    the tuple of targets (counts), in SYNC order."""
    by = {}
    for r in rows:
        if r["node"] in nodes and r["target"] is not None and r["fresh"]:
            by.setdefault(r["sync"], {})[r["node"]] = r["target"]
    return [tuple(d[n] for n in nodes) for s, d in sorted(by.items()) if len(d) == len(nodes)]


def trim(seq):
    """Without the leading and trailing repeats (the machine at rest)."""
    i = 0
    while i + 1 < len(seq) and seq[i + 1] == seq[i]:
        i += 1
    j = len(seq)
    while j - 1 > i and seq[j - 2] == seq[j - 1]:
        j -= 1
    return seq[i:j]


def ini_set(text, section, key, value):
    """A machine INI's text with KEY's value in [SECTION] replaced (the key
    must be there: the change is asserted, never silently lost)."""
    import re

    pat = rf"(^\[{section}\][ \t]*$(?:\n(?!\[).*)*?\n{key}[ \t]*=[ \t]*)[^\s#;]+"
    out, n = re.subn(pat, lambda m: m.group(1) + str(value), text, count=1, flags=re.M)
    if n != 1:
        raise AssertionError(f"no {key} in [{section}]")
    return out


class Rig:
    """One controller + listener on IFACE with its own shm segment.

        with Rig(config, profile, tmp) as rig:
            res = rig.feed(ngc, actions=...)
        rig.result  # after the with: exit line, listener report, decoded cycles
    """

    seq = 0

    def __init__(self, config, profile, workdir, iface=IFACE, priority=None,
                 exec_listener=EXEC_LISTENER, rt_args=()):
        Rig.seq += 1
        self.exec_listener = exec_listener
        self.config = Path(config)
        self.profile = profile
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.iface = iface
        self.shm = f"/mlip-can-{os.getpid()}-{Rig.seq}"
        self.setup = setup_of(config)
        self.priority = priority
        self.rt_args = [str(a) for a in rt_args]
        self.listener = self.rt = None
        self.events = []  # (time.time(), what)
        self.status_log = []

    # -- start / stop
    def __enter__(self):
        try:
            self.start()
        except BaseException:
            self.abort()
            raise
        return self

    def __exit__(self, et, ev, tb):
        if et is not None:
            self.abort()
            return False
        self.finish()
        return False

    def start(self):
        w = self.workdir
        largs = ["--can", self.iface, "--config", self.config, "--profile", self.profile,
                 "--csv", w / "can.csv", "--json", w / "can.json"]
        if KEEP_LOG:
            largs += ["--log", w / "can.log"]
        largs = [str(a) for a in largs]
        if self.exec_listener:
            self.listener = Proc("listen", [PY, LISTEN] + largs, w)
        else:
            def fn():
                sources._stop = False
                return listen.main(largs)
            self.listener = Proc("listen", [PY, LISTEN] + largs, w, fn=fn)
        self.listener.wait_for("listening on")
        args = [tool("mlip-rt"), "--config", self.config, "--can", self.iface,
                "--profile", self.profile, "--shm", self.shm]
        if self.priority is not None:
            args += ["--priority", self.priority]
        if "--stall-periods" not in self.rt_args:
            # a QEMU guest is not real-time: no stall holds unless a test asks
            args += ["--stall-periods", "100000"]
        self.rt = Proc("rt", args + self.rt_args, w)
        self.rt.wait_for("ready on")
        self.t_ready = time.time()

    def abort(self):
        for p in (self.rt, self.listener):
            if p is not None:
                try:
                    p.terminate(timeout=30)
                except Exception:
                    p.kill()

    def finish(self, settle_s=0.3, rt_gone=False):
        """SIGTERM mlip-rt (a controlled stop), then the listener; collect.
        rt_gone: mlip-rt has ended already (killed, or stopped by a signal
        the test sent): only wait for it."""
        time.sleep(settle_s)  # the stream stays at the last point meanwhile
        rt_gone = rt_gone or self.rt.p.poll() is not None
        self.final_status = None if rt_gone else self.status()
        rc = self.rt.terminate()
        rt_err = self.rt.stderr()
        time.sleep(0.2)
        lrc = self.listener.terminate()
        r = {"rt_rc": rc, "rt_stderr": rt_err, "listen_rc": lrc,
             "listen_stderr": self.listener.stderr(), "listen_stdout": self.listener.stdout()}
        if rc == 0:
            r["rt"] = parse_rt_exit(rt_err)
        js = self.workdir / "can.json"
        r["report"] = json.loads(js.read_text()) if js.exists() else None
        csv = self.workdir / "can.csv"
        if csv.exists():
            r["cycles"], r["t"], r["counts"] = read_can_csv(csv, len(self.setup.axes))
        self.result = r
        return r

    # -- talking to the controller
    def ctl(self, *args, check=True):
        p = run([tool("mlip-ctl"), "--shm", self.shm, *args], check=False, timeout=60)
        self.events.append((time.time(), " ".join(map(str, args)), p.returncode))
        if check and p.returncode != 0:
            raise AssertionError(f"mlip-ctl {' '.join(map(str, args))} exited {p.returncode}:\n"
                                 f"{p.stdout}{p.stderr}")
        return p

    def status(self):
        p = run([tool("mlip-ctl"), "--shm", self.shm, "status", "--json"], check=False, timeout=60)
        try:
            s = json.loads(p.stdout)
        except ValueError:
            raise AssertionError(f"mlip-ctl status --json exited {p.returncode}: {p.stdout}{p.stderr}")
        s["_t"] = time.time()
        self.status_log.append(s)
        return s

    def feeder(self, ngc, *args, name="feed"):
        """mlip-feed on ngc, started, not waited for (a Proc)."""
        return Proc(name, [tool("mlip-feed"), "--shm", self.shm, *args, ngc], self.workdir)

    def feed(self, ngc, actions=None, timeout=600, args=(), name="feed"):
        """Run mlip-feed on ngc to its end; actions(rig) runs in a thread
        meanwhile (mlip-ctl commands). Returns (rc, stdout, stderr)."""
        f = self.feeder(ngc, *args, name=name)
        self.t_feed = time.time()
        th = err = None
        if actions is not None:
            box = {}

            def body():
                try:
                    actions(self)
                except BaseException as e:  # reported after the feed ends
                    box["e"] = e

            th = threading.Thread(target=body, daemon=True)
            th.start()
        try:
            rc = f.p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            f.kill()
            raise AssertionError(f"mlip-feed did not finish within {timeout} s:\n{f.stderr()}")
        self.t_feed_end = time.time()
        out, errtext = f.stdout(), f.stderr()
        f._err.close()
        f._out.close()
        if th is not None:
            th.join(timeout=120)
            err = box.get("e")
            if err is not None:
                raise AssertionError(f"the mlip-ctl actions failed: {err}") from err
        return rc, out, errtext

    def wait_state(self, state, timeout=60, pred=None):
        """Poll mlip-ctl status until state (and pred(status)) holds."""
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            s = self.status()
            if s["state"] == state and (pred is None or pred(s)):
                return s
            time.sleep(0.05)
        raise AssertionError(f"controller not {state} within {timeout} s: {self.status_log[-1]}")


def longest_still_run(counts, start, end):
    """Longest run of identical consecutive positions in counts[start:end]:
    (length, index of its first cycle)."""
    best, best_at, run_len, run_at = 0, start, 1, start
    for i in range(start + 1, end):
        if counts[i] == counts[i - 1]:
            run_len += 1
        else:
            run_len, run_at = 1, i
        if run_len > best:
            best, best_at = run_len, run_at
    return best, best_at


def speeds(counts, cpu, period_s, linear):
    """Tool speed (linear axes, mm/s) between consecutive cycles."""
    out = []
    for a, b in zip(counts, counts[1:]):
        s = 0.0
        for i, c in enumerate(cpu):
            if linear[i]:
                d = (b[i] - a[i]) / c
                s += d * d
        out.append(math.sqrt(s) / period_s)
    return out


# ------------------------------------------------------------------ the demo

def demo(outdir, config=CONFIG / "mill-3axis.ini", ngc=ROOT / "examples" / "demo.ngc",
         profile="cia402"):
    """mlip-rt + mlip-feed + the listener on one program; what happened, checked.
    Writes outdir/decoded.csv (t,x,y,... from the first period on the bus),
    outdir/demo.json and the processes' logs. Returns the number of failed checks."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    work = out / "run"
    work.mkdir(exist_ok=True)
    setup = setup_of(config)
    lim = MachineLimits(config)
    T = setup.period_s
    print(f"demo: {ngc.name} on {config.name} ({' '.join(setup.axes)}), CAN profile {profile} "
          f"on {IFACE}{' (inside the test VM)' if IN_VM else ''}", flush=True)
    rows, summ = simulate(config, ngc, work)
    trc = trace_counts(rows, setup.cpu)
    print(f"demo: mlip-sim says {summ['total_time_s']:.3f} s of machining, {summ['blocks']} blocks, "
          f"{summ['path_length_mm']:.1f} mm", flush=True)
    t0 = time.monotonic()
    with Rig(config, profile, work) as rig:
        print(f"demo: listener and mlip-rt up ({time.monotonic() - t0:.1f} s); mlip-feed "
              f"{ngc.name} ...", flush=True)
        rc, fout, ferr = rig.feed(ngc)
        done = rig.wait_state("idle", timeout=60)
    r = rig.result
    rep, rt = r["report"], r.get("rt", {})
    checks = []

    def check(ok, what):
        checks.append((bool(ok), what))
        print(f"  [{'ok' if ok else 'FAILED'}] {what}", flush=True)

    can = r.get("counts", [])
    print(f"demo: mlip-feed exit {rc}; {ferr.strip().splitlines()[-1] if ferr.strip() else ''}")
    print(f"demo: mlip-rt: {rt.get('line', r['rt_stderr'].strip().splitlines()[-1:])}")
    print(f"demo: listener: {r['listen_stdout'].strip()}", flush=True)
    per = {"cia402": 1 + len(setup.axes), "packed": (len(setup.axes) + 1) // 2 + 1, "fd": 1}[profile]
    check(rc == 0, f"mlip-feed exited {rc} (0: every block executed, machine at rest)")
    check(done["exec_seq"] == summ["blocks"] + 1,
          f"exec_seq {done['exec_seq']} = {summ['blocks']} blocks + END")
    check(r["rt_rc"] == 0 and rt.get("tx_dropped") == 0,
          f"mlip-rt stopped cleanly on SIGTERM, {rt.get('tx_dropped')} frames dropped at send")
    check(rep["frames_ours"] == rt.get("frames_sent") == rt.get("periods", -1) * per,
          f"frames: {rt.get('frames_sent')} sent in {rt.get('periods')} periods, "
          f"{rep['frames_ours']} received")
    clean = not any(rep.get(k) for k in ("gaps", "incomplete", "duplicates", "stray", "malformed",
                                         "socket_drops"))
    check(clean and rep["cycles"] == rt.get("periods") and r["cycles"] == list(range(rep["cycles"])),
          f"cycles: {rep['cycles']} complete, numbered 0..{rep['cycles'] - 1}, {rep['gaps']} lost, "
          f"{rep['incomplete']} incomplete, {rep['stray']} stray, {rep.get('socket_drops')} dropped")
    try:
        off, how = align(can, trc)
        bad = first_mismatch(can, trc, off)
    except AssertionError as e:
        off, bad = 0, str(e)
    check(bad is None, f"the bus carries mlip-sim's trace to the last count: {len(trc)} rows "
                       f"= cycles {off}..{off + len(trc) - 1}" + (f" -- {bad}" if bad else ""))
    tail = can[off + len(trc):]
    check(tail and all(c == trc[-1] for c in tail),
          f"then at rest on the program's last point for {len(tail)} cycles")
    moving = can[max(off, 0):]
    quantum = max(1.0 / c for c in setup.cpu)
    write_positions_csv(out / "decoded.csv", moving, setup.cpu, T)
    p, js = mlip_check(config, ngc, out / "decoded.csv", quantum, out / "check.json")
    msg = p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ""
    check(p.returncode == 0, f"mlip-check --quantum {quantum:g} on the decoded positions: {msg}")
    machining = (len(trc) - 1) * T
    tm = rep["timing"]
    info = {
        "program": str(ngc), "config": str(config), "profile": profile, "in_vm": IN_VM,
        "machining_s": machining, "sim_s": summ["total_time_s"], "blocks": summ["blocks"],
        "path_mm": summ["path_length_mm"], "frames": rep["frames_ours"], "cycles": rep["cycles"],
        "periods": rt.get("periods"), "overruns": rt.get("overruns"), "offset": off,
        "period_s": T, "vmax_mm_s": lim.vmax, "axes": setup.axes,
        "linear": [a in "XYZ" for a in setup.axes],
        "max_speed_mm_s": js and js.get("max_speed_mm_s"),
        "max_contour_mm": js and js.get("max_contour_error_mm"),
        "bus_period_us": {k: tm.get(k) for k in ("min_us", "p50_us", "p99_us", "p99_9_us", "max_us")},
        "feeds_mm_s": program_feeds(ngc),
        "checks": [{"ok": ok, "what": w} for ok, w in checks],
    }
    (out / "demo.json").write_text(json.dumps(info, indent=1) + "\n")
    for name in ("can.json", "rt.err", "feed.err", "listen.err"):
        if (work / name).exists():
            (out / name).write_text((work / name).read_text())
    failed = sum(1 for ok, _ in checks if not ok)
    print(f"demo: machining {machining:.3f} s ({summ['blocks']} blocks, {summ['path_length_mm']:.1f} mm), "
          f"{rep['frames_ours']} frames, {rep['cycles']} cycles; bus period p50 {tm.get('p50_us')} us, "
          f"p99 {tm.get('p99_us')} us, max {tm.get('max_us')} us"
          + (" (emulated VM: timing says nothing about real time)" if IN_VM else ""))
    print(f"demo: {len(checks) - failed} of {len(checks)} checks passed", flush=True)
    return failed


def program_feeds(ngc):
    """The distinct F words of a program, in mm/s (F is in units per minute)."""
    import re

    feeds = set()
    with open(ngc) as fh:
        for line in fh:
            code = re.sub(r"\(.*?\)|;.*", "", line)
            for m in re.finditer(r"[Ff]\s*([0-9.]+)", code):
                feeds.add(float(m.group(1)) / 60.0)
    return sorted(feeds)


def plot(outdir, png):
    """Speed vs time from the decoded positions, the feed limits marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(outdir)
    info = json.loads((out / "demo.json").read_text())
    T = info["period_s"]
    n = len(info["axes"])
    t, pos = [], []
    with open(out / "decoded.csv") as fh:
        fh.readline()
        for line in fh:
            f = [float(v) for v in line.split(",")]
            t.append(f[0])
            pos.append(f[1:1 + n])
    lin = info["linear"]
    sp, ts = [], []
    for k in range(1, len(pos)):
        d = sum((pos[k][i] - pos[k - 1][i]) ** 2 for i in range(n) if lin[i])
        sp.append(math.sqrt(d) / T)
        ts.append((t[k] + t[k - 1]) / 2)
    w = 9  # a centred moving average over 9 periods, to see through the 1-count steps
    avg = [sum(sp[max(0, i - w // 2):i + w // 2 + 1]) / len(sp[max(0, i - w // 2):i + w // 2 + 1])
           for i in range(len(sp))]
    fig, ax = plt.subplots(figsize=(11, 5.6), dpi=110)
    ax.plot(ts, sp, lw=0.5, color="#9ecae1", label="tool speed from the decoded CAN positions, per period")
    ax.plot(ts, avg, lw=1.2, color="#08519c", label=f"the same, {w}-period moving average")
    vmax = info["vmax_mm_s"]
    ax.axhline(vmax, color="#d62728", ls="--", lw=1.4,
               label=f"feed limit v_m (MAX_LINEAR_VELOCITY) = {vmax:g} mm/s: G0 moves run at it")
    feeds = [f for f in info["feeds_mm_s"] if f < vmax]
    for j, fmm in enumerate(feeds):
        ax.axhline(fmm, color="#ff7f0e", ls=":", lw=1.3,
                   label=("programmed feeds: " + ", ".join(f"F{f * 60:g} = {f:g} mm/s" for f in feeds))
                   if j == 0 else None)
    ax.set_xlim(0, t[-1] if t else 1)
    ax.set_ylim(0, vmax * 1.1)
    ax.set_xlabel("time since the program's first period on the bus (s)")
    ax.set_ylabel("tool speed, X Y Z (mm/s)")
    ok = sum(1 for c in info["checks"] if c["ok"])
    ax.set_title(f"{Path(info['program']).name}: mlip-rt -> CAN ({info['profile']}) -> mlip-listen\n"
                 f"{info['machining_s']:.3f} s of machining, {info['blocks']} blocks, "
                 f"{info['cycles']} cycles on the bus, {ok} of {len(info['checks'])} checks passed "
                 f"(bus == mlip-sim to the count, mlip-check)", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8.5, frameon=False)
    fig.tight_layout()
    fig.savefig(png)
    print(f"demo: velocity profile written to {png}")


def cli(argv=None):
    """tools/mlip-demo.py: run the demo, or plot its result."""
    import argparse

    ap = argparse.ArgumentParser(description="the CAN demo: run it, or plot its result")
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("demo")
    d.add_argument("outdir")
    d.add_argument("--config", default=str(CONFIG / "mill-3axis.ini"))
    d.add_argument("--profile", default="cia402", choices=["cia402", "packed", "fd"])
    d.add_argument("program", nargs="?", default=str(ROOT / "examples" / "demo.ngc"))
    dr = sub.add_parser("drives", help="the drives stage: mlip-rt --drives with simulated drives")
    dr.add_argument("outdir")
    dr.add_argument("--config", default=str(CONFIG / "mill-3axis-drives.ini"))
    dr.add_argument("--period", type=float, default=None, help="s (default 0.04)")
    dr.add_argument("program", nargs="?", help="default: a small program of its own")
    p = sub.add_parser("plot")
    p.add_argument("outdir")
    p.add_argument("png")
    sub.add_parser("prime")
    a = ap.parse_args(argv)
    if a.cmd == "demo":
        sys.exit(1 if demo(a.outdir, Path(a.config), Path(a.program), a.profile) else 0)
    elif a.cmd == "drives":
        from . import drivedemo

        kw = {} if a.period is None else {"period_s": a.period}
        sys.exit(1 if drivedemo.run(a.outdir, Path(a.config), a.program and Path(a.program), **kw)
                 else 0)
    elif a.cmd == "plot":
        plot(a.outdir, a.png)
    else:
        print(prime_dbc_cache())
