"""Process control for the end-to-end runs: the C tools run to their end, a
child process waited for by its ready line, mlip-rt with the listener on one
bus (Rig), the simulated drives as a child (DriveSimProc). Used by the demo
(mlip-demo) and the CAN tests. Standard library only: every Python import
costs seconds in the software-emulated test VM."""

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import IO, Any

from . import listen
from .config import StrPath, setup_of
from .report import read_csv
from .settings import Settings


def entry_point(script: str, module: str) -> list[str]:
    """The command that runs one of the package's programs: its console
    script beside this interpreter (.venv/bin/mlip-listen: what a user types),
    else `python -m module`."""
    exe = Path(sys.executable).with_name(script)
    return [str(exe)] if exe.exists() else [sys.executable, "-m", module]


def run_tool(
    args: Sequence[object], check: bool = True, timeout: float = 600
) -> "subprocess.CompletedProcess[str]":
    """Run a program (a C tool) to its end; with check, a non-zero exit is an
    AssertionError carrying its stderr."""
    p = subprocess.run(
        [str(a) for a in args], capture_output=True, text=True, timeout=timeout, check=False
    )
    if check and p.returncode != 0:
        raise AssertionError(f"{' '.join(map(str, args))} exited {p.returncode}:\n{p.stderr}")
    return p


class Forked:
    """The Popen calls Proc uses, for a forked child running fn() (no
    interpreter start, no imports: that takes tens of seconds in the VM)."""

    def __init__(self, fn: Callable[[], int], out: IO[str], err: IO[str]) -> None:
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
                sys.stdout = open(1, "w", buffering=1, closefd=False)  # noqa: SIM115
                sys.stderr = open(2, "w", buffering=1, closefd=False)  # noqa: SIM115
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
                    os._exit(rc)
        self.pid = pid
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            pid, st = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.returncode = os.waitstatus_to_exitcode(st)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        t_end = None if timeout is None else time.monotonic() + timeout
        while True:
            rc = self.poll()
            if rc is not None:
                return rc
            if t_end is not None and time.monotonic() > t_end:
                raise subprocess.TimeoutExpired(f"pid {self.pid}", timeout or 0.0)
            time.sleep(0.02)

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            os.kill(self.pid, sig)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


class Proc:
    """A child process with its stderr in a file, waited for a ready line.
    fn instead of running args: a forked copy of this process runs fn() (the
    listener: no interpreter start, no imports; that takes tens of seconds in
    the VM)."""

    def __init__(
        self,
        name: str,
        args: Sequence[object],
        workdir: StrPath,
        env: Mapping[str, str] | None = None,
        fn: Callable[[], int] | None = None,
        start_timeout: float = 240.0,
    ) -> None:
        self.name = name
        self.args = [str(a) for a in args]
        self.start_timeout = start_timeout
        self.err_path = Path(workdir) / f"{name}.err"
        self.out_path = Path(workdir) / f"{name}.out"
        self._err = open(self.err_path, "w")  # noqa: SIM115 (closed by terminate/kill)
        self._out = open(self.out_path, "w")  # noqa: SIM115
        self.p: Forked | subprocess.Popen[bytes]
        if fn is not None:
            self.p = Forked(fn, self._out, self._err)
        else:
            self.p = subprocess.Popen(
                self.args, stdout=self._out, stderr=self._err, env=env, stdin=subprocess.DEVNULL
            )
        self.rc: int | None = None

    def stderr(self) -> str:
        return self.err_path.read_text(errors="replace")

    def stdout(self) -> str:
        return self.out_path.read_text(errors="replace")

    def wait_for(self, text: str, timeout: float | None = None) -> None:
        """Until text shows on its stderr (default: the start timeout)."""
        limit = self.start_timeout if timeout is None else timeout
        t_end = time.monotonic() + limit
        while time.monotonic() < t_end:
            if text in self.stderr():
                return
            if self.p.poll() is not None:
                raise AssertionError(
                    f"{self.name} exited {self.p.returncode} before '{text}':\n{self.stderr()}"
                )
            time.sleep(0.05)
        raise AssertionError(f"{self.name}: no '{text}' within {limit} s:\n{self.stderr()}")

    def close_files(self) -> None:
        self._err.close()
        self._out.close()

    def terminate(self, timeout: float = 120) -> int:
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGTERM)
        try:
            self.rc = self.p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.p.kill()
            self.rc = self.p.wait()
            raise AssertionError(
                f"{self.name} ignored SIGTERM for {timeout} s:\n{self.stderr()}"
            ) from None
        finally:
            self.close_files()
        return self.rc

    def kill(self) -> None:
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait()
        self.close_files()


def parse_rt_exit(stderr: str) -> dict[str, Any]:
    """mlip-rt's last line: 'stopped after N periods: F frames sent, D dropped
    (tx queue), B bus errors, O overruns, U underruns, R records taken; ...'."""
    lines = [ln for ln in stderr.splitlines() if "stopped after" in ln]
    if not lines:
        raise AssertionError(f"mlip-rt printed no 'stopped after' line:\n{stderr}")
    line = lines[-1]
    m = re.search(r"stopped after (\d+) periods: (\d+) frames sent, (\d+) dropped", line)
    if not m:
        raise AssertionError(f"cannot read mlip-rt's exit line: {line}")
    out: dict[str, Any] = {
        "periods": int(m.group(1)),
        "frames_sent": int(m.group(2)),
        "tx_dropped": int(m.group(3)),
        "line": line,
    }
    for key in ("overruns", "underruns", "bus errors", "records taken"):
        mm = re.search(r"(\d+) " + key, line)
        if mm:
            out[key.replace(" ", "_")] = int(mm.group(1))
    return out


class DriveSimProc:
    """mlip-drive-sim as a child process: simulated CiA 402 drives on the
    settings' interface, their records in workdir/drives/ (events.jsonl,
    sync.csv), fault injection at run time through workdir/drives.ctl.

        sim = DriveSimProc(s, tmp, nodes=[1, 2, 3], starts={1: 1234}, inject=["2:never-enable"])
        sim.inject("1:fault=0x2310"); sim.events("state", 1); sim.sync_rows()
        sim.stop()
    """

    def __init__(
        self,
        s: Settings,
        workdir: StrPath,
        nodes: Sequence[int] | None = None,
        config: StrPath | None = None,
        starts: Mapping[int, int] | None = None,
        states: Mapping[int, str] | None = None,
        inject: Sequence[str] = (),
        iface: str | None = None,
        args: Sequence[object] = (),
        name: str = "drivesim",
    ) -> None:
        w = Path(workdir)
        self.start_timeout = s.start_timeout
        self.rec = w / "drives"
        self.ctl = w / "drives.ctl"
        self.ctl.write_text("")
        a: list[object] = [*entry_point("mlip-drive-sim", "mlipcan.drivesim")]
        a += ["--can", iface or s.iface]
        a += ["--record", self.rec, "--control", self.ctl]
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
        self.proc = Proc(name, a + list(args), w, start_timeout=s.start_timeout)
        self.proc.wait_for(": ready")

    def inject(self, line: str) -> None:
        """'N:WHAT[=ARG]', taken within 20 ms (see mlip-drive-sim --help)."""
        with open(self.ctl, "a") as fh:
            fh.write(line + "\n")

    def events(self, kind: str | None = None, node: int | None = None) -> list[dict[str, Any]]:
        out = []
        path = self.rec / "events.jsonl"
        for line in path.read_text().splitlines() if path.exists() else ():
            if not line.endswith("}"):
                continue  # being written
            e: dict[str, Any] = json.loads(line)
            if (kind is None or e["kind"] == kind) and (node is None or e["node"] == node):
                out.append(e)
        return out

    def wait_event(
        self, pred: Callable[[dict[str, Any]], bool], what: str, timeout: float | None = None
    ) -> list[dict[str, Any]]:
        limit = self.start_timeout if timeout is None else timeout
        t_end = time.monotonic() + limit
        while time.monotonic() < t_end:
            ev = [e for e in self.events() if pred(e)]
            if ev:
                return ev
            if self.proc.p.poll() is not None:
                raise AssertionError(
                    f"drive simulator exited {self.proc.p.returncode}:\n{self.proc.stderr()}"
                )
            time.sleep(0.02)
        raise AssertionError(f"drive simulator recorded no {what} within {limit} s")

    def sync_rows(self) -> list[dict[str, Any]]:
        """sync.csv as dicts (written every few ms: a last partial line is skipped)."""
        rows = []
        for f in self._csv("sync.csv"):
            rows.append(
                {
                    "sync": int(f[0]),
                    "node": int(f[1]),
                    "t": float(f[2]),
                    "state": f[3],
                    "cw": int(f[4]),
                    "target": int(f[5]) if f[5] else None,
                    "fresh": f[6] == "1",
                    "actual": int(f[7]),
                    "sw": int(f[8]),
                }
            )
        return rows

    def io_rows(self) -> list[dict[str, Any]]:
        """io.csv as dicts: the I/O modules' outputs and inputs at every SYNC
        (bytes 0x6200:1..8 / 0x6000:1..8); a last partial line is skipped."""
        return [
            {
                "sync": int(f[0]),
                "node": int(f[1]),
                "t": float(f[2]),
                "outputs": bytes.fromhex(f[3]),
                "inputs": bytes.fromhex(f[4]),
            }
            for f in self._csv("io.csv")
        ]

    def _csv(self, name: str) -> list[list[str]]:
        """A record file's rows as fields, its header skipped; a last partial
        line (being written) is left out."""
        out = []
        with open(self.rec / name) as fh:
            fh.readline()
            for line in fh:
                if not line.endswith("\n"):
                    break
                out.append(line.rstrip("\n").split(","))
        return out

    def wait_sync_rows(
        self, pred: Callable[[list[dict[str, Any]]], bool], timeout: float | None = None
    ) -> list[dict[str, Any]]:
        limit = self.start_timeout if timeout is None else timeout
        t_end = time.monotonic() + limit
        while True:
            rows = self.sync_rows()
            if pred(rows) or time.monotonic() > t_end:
                return rows
            time.sleep(0.05)

    def stop(self, timeout: float = 120) -> int:
        """SIGTERM: the records are written, the summary line printed. Returns the exit code."""
        return self.proc.terminate(timeout=timeout)


class Rig:
    """One controller + listener on the settings' interface with its own shm
    segment.

        with Rig(s, config, profile, tmp) as rig:
            res = rig.feed(ngc, actions=...)
        rig.result  # after the with: exit line, listener report, decoded cycles
    """

    seq = 0

    def __init__(
        self,
        s: Settings,
        config: StrPath,
        profile: str,
        workdir: StrPath,
        iface: str | None = None,
        priority: int | None = None,
        exec_listener: bool | None = None,
        rt_args: Sequence[object] = (),
    ) -> None:
        Rig.seq += 1
        self.s = s
        self.exec_listener = s.exec_listener if exec_listener is None else exec_listener
        self.config = Path(config)
        self.profile = profile
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.iface = iface or s.iface
        self.shm = f"/mlip-can-{os.getpid()}-{Rig.seq}"
        self.setup = setup_of(s, config)
        self.priority = priority
        self.rt_args = [str(a) for a in rt_args]
        self.listener: Proc | None = None
        self.rt: Proc | None = None
        self.events: list[tuple[float, str, int]] = []  # (time.time(), what, exit code)
        self.status_log: list[dict[str, Any]] = []
        self.result: dict[str, Any] = {}
        self.final_status: dict[str, Any] | None = None
        self.t_ready = self.t_feed = self.t_feed_end = 0.0

    # -- start / stop
    def __enter__(self) -> "Rig":
        try:
            self.start()
        except BaseException:
            self.abort()
            raise
        return self

    def __exit__(
        self,
        et: type[BaseException] | None,
        ev: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if et is not None:
            self.abort()
            return
        self.finish()

    def _rt(self) -> Proc:
        if self.rt is None:
            raise RuntimeError("the rig is not started")
        return self.rt

    def start(self) -> None:
        w = self.workdir
        largs = [
            "--can", self.iface, "--config", self.config, "--profile", self.profile,
            "--csv", w / "can.csv", "--json", w / "can.json",
        ]  # fmt: skip
        if self.s.keep_log:
            largs += ["--log", w / "can.log"]
        sargs = [str(a) for a in largs]
        cmd = [*entry_point("mlip-listen", "mlipcan.listen"), *sargs]
        timeout = self.s.start_timeout
        if self.exec_listener:
            self.listener = Proc("listen", cmd, w, start_timeout=timeout)
        else:
            s = self.s

            def fn() -> int:
                return listen.main(sargs, settings=s)

            self.listener = Proc("listen", cmd, w, fn=fn, start_timeout=timeout)
        self.listener.wait_for("listening on")
        args: list[object] = [self.s.tool("mlip-rt"), "--config", self.config]
        args += ["--can", self.iface, "--profile", self.profile, "--shm", self.shm]
        if self.priority is not None:
            args += ["--priority", self.priority]
        if "--stall-periods" not in self.rt_args:
            # a QEMU guest is not real-time: no stall holds unless a test asks
            args += ["--stall-periods", "100000"]
        self.rt = Proc("rt", args + self.rt_args, w, start_timeout=timeout)
        self.rt.wait_for("ready on")
        # "ready" comes before the loop's first period: a tool run at once
        # on a slow guest would find a segment that never beat ("start
        # mlip-rt"); the rig is ready once the controller has beaten
        t_end = time.monotonic() + timeout
        while True:
            p = run_tool(
                [self.s.tool("mlip-ctl"), "--shm", self.shm, "status", "--json"],
                check=False,
                timeout=60,
            )
            try:
                if json.loads(p.stdout).get("heartbeat", 0) > 0:
                    break
            except ValueError:
                pass
            assert time.monotonic() < t_end and self.rt.p.poll() is None, (
                f"mlip-rt never beat after 'ready on': {p.stdout}{p.stderr}"
            )
            time.sleep(0.05)
        self.t_ready = time.time()

    def abort(self) -> None:
        for p in (self.rt, self.listener):
            if p is not None:
                try:
                    p.terminate(timeout=30)
                except Exception:
                    p.kill()

    def finish(self, settle_s: float = 0.3, rt_gone: bool = False) -> dict[str, Any]:
        """SIGTERM mlip-rt (a controlled stop), then the listener; collect.
        rt_gone: mlip-rt has ended already (killed, or stopped by a signal
        the test sent): only wait for it."""
        rt = self._rt()
        assert self.listener is not None
        time.sleep(settle_s)  # the stream stays at the last point meanwhile
        rt_gone = rt_gone or rt.p.poll() is not None
        self.final_status = None if rt_gone else self.status()
        rc = rt.terminate()
        rt_err = rt.stderr()
        time.sleep(0.2)
        lrc = self.listener.terminate()
        r: dict[str, Any] = {
            "rt_rc": rc,
            "rt_stderr": rt_err,
            "listen_rc": lrc,
            "listen_stderr": self.listener.stderr(),
            "listen_stdout": self.listener.stdout(),
        }
        if rc == 0:
            r["rt"] = parse_rt_exit(rt_err)
        js = self.workdir / "can.json"
        r["report"] = json.loads(js.read_text()) if js.exists() else None
        csv = self.workdir / "can.csv"
        if csv.exists():
            r["cycles"], r["t"], r["counts"] = read_csv(csv, len(self.setup.axes))
        self.result = r
        return r

    # -- talking to the controller
    def ctl(self, *args: object, check: bool = True) -> "subprocess.CompletedProcess[str]":
        p = run_tool([self.s.tool("mlip-ctl"), "--shm", self.shm, *args], check=False, timeout=60)
        self.events.append((time.time(), " ".join(map(str, args)), p.returncode))
        if check and p.returncode != 0:
            raise AssertionError(
                f"mlip-ctl {' '.join(map(str, args))} exited {p.returncode}:\n{p.stdout}{p.stderr}"
            )
        return p

    def status(self) -> dict[str, Any]:
        p = run_tool(
            [self.s.tool("mlip-ctl"), "--shm", self.shm, "status", "--json"],
            check=False,
            timeout=60,
        )
        try:
            st: dict[str, Any] = json.loads(p.stdout)
        except ValueError:
            raise AssertionError(
                f"mlip-ctl status --json exited {p.returncode}: {p.stdout}{p.stderr}"
            ) from None
        st["_t"] = time.time()
        self.status_log.append(st)
        return st

    def feeder(self, ngc: StrPath, *args: object, name: str = "feed") -> Proc:
        """mlip-feed on ngc, started, not waited for (a Proc)."""
        cmd = [self.s.tool("mlip-feed"), "--shm", self.shm, *args, ngc]
        return Proc(name, cmd, self.workdir, start_timeout=self.s.start_timeout)

    def feed(
        self,
        ngc: StrPath,
        actions: Callable[["Rig"], None] | None = None,
        timeout: float = 600,
        args: Sequence[object] = (),
        name: str = "feed",
    ) -> tuple[int, str, str]:
        """Run mlip-feed on ngc to its end; actions(rig) runs in a thread
        meanwhile (mlip-ctl commands). Returns (rc, stdout, stderr)."""
        f = self.feeder(ngc, *args, name=name)
        self.t_feed = time.time()
        th = None
        box: dict[str, BaseException] = {}
        if actions is not None:
            act = actions

            def body() -> None:
                try:
                    act(self)
                except BaseException as e:  # reported after the feed ends
                    box["e"] = e

            th = threading.Thread(target=body, daemon=True)
            th.start()
        try:
            rc = f.p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            f.kill()
            raise AssertionError(
                f"mlip-feed did not finish within {timeout} s:\n{f.stderr()}"
            ) from None
        self.t_feed_end = time.time()
        out, errtext = f.stdout(), f.stderr()
        f.close_files()
        if th is not None:
            th.join(timeout=120)
            err = box.get("e")
            if err is not None:
                raise AssertionError(f"the mlip-ctl actions failed: {err}") from err
        return rc, out, errtext

    def wait_state(
        self,
        state: str,
        timeout: float = 60,
        pred: Callable[[dict[str, Any]], bool] | None = None,
    ) -> dict[str, Any]:
        """Poll mlip-ctl status until state (and pred(status)) holds."""
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            st = self.status()
            if st["state"] == state and (pred is None or pred(st)):
                return st
            time.sleep(0.05)
        raise AssertionError(f"controller not {state} within {timeout} s: {self.status_log[-1]}")
