"""A Grbl 1.1 client for the tests: a reader thread sorts what the server
sends into status reports, answers (ok / error:N, each with the push
messages that came before it) and the rest; stream() sends lines with
character counting against the 128-byte receive buffer exactly as
gnea/grbl's doc/script/stream.py and interface.md describe it."""
import queue
import re
import socket
import threading
import time

RX_BUFFER_SIZE = 128
STATUS_RE = re.compile(r"^<([^|>]+)\|(.*)>$")


def parse_status(line):
    """'<Run|MPos:1.000,2.000,3.000|FS:500,0|Ov:100,100,100>' ->
    {'state': 'Run', 'MPos': [1.0, 2.0, 3.0], 'FS': [500.0, 0.0], ...}"""
    m = STATUS_RE.match(line)
    assert m, f"not a status report: {line!r}"
    out = {"state": m.group(1), "raw": line, "fields": []}
    for field in m.group(2).split("|"):
        key, _, val = field.partition(":")
        out["fields"].append(key)
        if key in ("Pn", "A"):
            out[key] = val
        else:
            out[key] = [float(x) for x in val.split(",")]
    return out


class Grbl:
    def __init__(self, port=None, host="127.0.0.1", sock=None, timeout=60.0):
        self.sock = sock or socket.create_connection((host, port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock.settimeout(None)  # the reader waits as long as the server is silent
        self.timeout = timeout
        self.status_q = queue.Queue()
        self.answers = queue.Queue()
        self.lines = []  # everything received, in order
        self.pending_msgs = []
        self.closed = threading.Event()
        # what the reader sorts and what cmd()/status() mark as "from now on"
        self._lock = threading.Lock()
        self._buf = b""
        self._t = threading.Thread(target=self._reader, daemon=True)
        self._t.start()

    def _reader(self):
        try:
            while True:
                d = self.sock.recv(65536)
                if not d:
                    break
                self._buf += d
                while b"\n" in self._buf:
                    raw, self._buf = self._buf.split(b"\n", 1)
                    line = raw.decode("ascii", "replace").rstrip("\r")
                    if line == "":
                        continue
                    with self._lock:
                        self._sort(line)
        except OSError:
            pass
        self.closed.set()

    def _sort(self, line):
        self.lines.append(line)
        if line.startswith("Grbl "):
            self.pending_msgs = []
        if line.startswith("<"):
            self.status_q.put(line)
        elif line == "ok" or line.startswith("error:"):
            self.answers.put((line, self.pending_msgs))
            self.pending_msgs = []
        else:
            self.pending_msgs.append(line)

    def close(self):
        """Disconnect now: shutdown sends the FIN at once (a close alone
        waits for the reader thread's recv to return)."""
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        try:
            self.sock.close()
        except OSError:
            pass

    def wait_line(self, pred, timeout=None):
        """The first received line (old or new) for which pred is true."""
        end = time.monotonic() + (timeout or self.timeout)
        i = 0
        while time.monotonic() < end:
            while i < len(self.lines):
                if pred(self.lines[i]):
                    return self.lines[i]
                i += 1
            time.sleep(0.005)
        raise AssertionError(f"no such line in {self.lines[-20:]}")

    def welcome(self):
        return self.wait_line(lambda s: s.startswith("Grbl "))

    def send(self, data):
        self.sock.sendall(data if isinstance(data, bytes) else data.encode())

    def answer(self, timeout=None):
        """(answer, [push messages before it])."""
        return self.answers.get(timeout=timeout or self.timeout)

    def cmd(self, line, timeout=None):
        """Send one line, wait for its answer: (answer, messages pushed
        after it was sent). The messages received before (a welcome, a
        note) are not its answer's."""
        with self._lock:
            self.pending_msgs = []
            self.send(line + "\n")
        return self.answer(timeout)

    def status(self, timeout=None):
        """Send '?' and return the first report received after it, parsed
        (the server answers a '?' once it has applied the real-time
        commands before it)."""
        with self._lock:
            while not self.status_q.empty():
                self.status_q.get_nowait()
            self.send(b"?")
        return parse_status(self.status_q.get(timeout=timeout or self.timeout))

    def no_answer_yet(self):
        """No line was answered up to a report asked for now: what the
        server sent before that report (one TCP stream, in order) holds
        every answer it had given."""
        self.status()
        return self.answers.empty()

    def wait_status(self, pred, timeout=60.0, period=0.02):
        """Poll '?' until a report for which pred is true; that report."""
        end = time.monotonic() + timeout
        last = None
        while time.monotonic() < end:
            last = self.status()
            if pred(last):
                return last
            time.sleep(period)
        raise AssertionError(f"no such report in {timeout} s: last {last}")

    def wait_state(self, states, timeout=60.0, period=0.05):
        end = time.monotonic() + timeout
        last = None
        while time.monotonic() < end:
            last = self.status()
            if last["state"] in states:
                return last
            time.sleep(period)
        raise AssertionError(f"state never in {states}: last {last}")

    def stream(self, lines, poll_hz=0.0, on_status=None, stop_on_error=False):
        """Character-counting stream (interface.md): returns the answers in
        order, each (answer, messages). poll_hz > 0: '?' at that rate while
        streaming, the reports passed to on_status."""
        counts, answers = [], []
        next_poll = time.monotonic()
        it = iter(lines)
        pending = None
        done_sending = False
        while True:
            if poll_hz and time.monotonic() >= next_poll:
                self.send(b"?")
                next_poll += 1.0 / poll_hz
            while not self.status_q.empty():
                s = self.status_q.get_nowait()
                if on_status:
                    on_status(parse_status(s))
            if not done_sending:
                if pending is None:
                    try:
                        pending = next(it).rstrip("\r\n")
                    except StopIteration:
                        done_sending = True
                if pending is not None:
                    n = len(pending) + 1
                    if sum(counts) + n <= RX_BUFFER_SIZE:
                        self.send(pending + "\n")
                        counts.append(n)
                        pending = None
                        continue
            if done_sending and not counts:
                return answers
            try:
                a = self.answers.get(timeout=0.01)
            except queue.Empty:
                if self.closed.is_set():
                    raise AssertionError("server closed the connection")
                continue
            counts.pop(0)
            answers.append(a)
            if stop_on_error and a[0].startswith("error"):
                done_sending = True
                pending = None
