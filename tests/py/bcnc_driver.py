"""Drive bCNC (PyPI bCNC, its own Sender: the serial thread, the GRBL1
controller plugin, its G-code compiler) without its window: connect through
pyserial's socket:// URL, read the DRO, jog, run a file, hold and resume it, and
print one JSON line per event for the test to judge.

    python bcnc_driver.py socket://127.0.0.1:PORT FILE [--hold-after LINES] [--jog X2Y1]
                          [--deadline S] [--sent OUT]

--sent OUT: the G-code lines bCNC sends, as its compiler made them (it
rewrites every coordinate with its `round` digits, 4 by default), written
to OUT when the run ends.

Every event carries `wall` (the wall clock, s) besides `t`. Every wait is on
a condition (a state, a position, status reports counted) with a generous
deadline (DEADLINE, --deadline S), never a fixed sleep: the host is loaded,
the emulated VM slower still.

bCNC's modules import each other by their bare names (its __main__ puts its
folder on the path): this driver does the same for the installed package.
"""
import json
import os
import re
import sys
import time

import bCNC

HERE = os.path.dirname(bCNC.__file__)
for sub in ("", "lib", "plugins", "controllers"):
    sys.path.insert(0, os.path.join(HERE, sub))

import Helpers  # noqa: E402,F401  (bCNC's: installs gettext's _ first, as its main does)
import Utils  # noqa: E402  (bCNC's)

Utils.loadConfiguration()
import GRBL1  # noqa: E402  (bCNC's Grbl 1.1 controller plugin)
from CNC import CNC, WAIT  # noqa: E402
from Sender import Sender  # noqa: E402

# s, for any one condition
DEADLINE = float(sys.argv[sys.argv.index("--deadline") + 1]) if "--deadline" in sys.argv else 60.0

# status reports bCNC has parsed (its plugin's handler, counted)
REPORTS = [0]
_parse = GRBL1.Controller.parseBracketAngle


def _counted(self, line, cline):
    _parse(self, line, cline)
    REPORTS[0] += 1


GRBL1.Controller.parseBracketAngle = _counted


class Headless(Sender):
    """bCNC's Sender with its window's hooks doing nothing."""

    def disable(self):
        pass

    def enable(self):
        pass

    def checkStop(self):
        return self._stop  # what bCNC's window's checkStop answers, without its events


class Recorded:
    """bCNC's send queue, the lines put on it kept (its compiler's output)."""

    def __init__(self, q):
        self.q, self.lines = q, []

    def put(self, item):
        if isinstance(item, str):
            self.lines.append(item)
        self.q.put(item)


def say(**kw):
    kw["t"] = round(time.monotonic() - T0, 3)
    kw["wall"] = time.time()
    print(json.dumps(kw), flush=True)


def dro():
    return {"state": CNC.vars.get("state"), "mpos": [CNC.vars.get(k) for k in ("mx", "my", "mz")],
            "wpos": [CNC.vars.get(k) for k in ("wx", "wy", "wz")]}


def until(pred, timeout=DEADLINE, period=0.01):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(period)
    return pred()


def reports_pass(n):
    """n more status reports parsed by bCNC (it polls `?` itself)."""
    start = REPORTS[0]
    return until(lambda: REPORTS[0] >= start + n)


def drain(s):
    while not s.log.empty():
        kind, msg = s.log.get_nowait()
        if kind in (Sender.MSG_ERROR,) or (isinstance(msg, str) and msg.startswith("error")):
            say(event="error", msg=str(msg))
        elif kind == Sender.MSG_RECEIVE and isinstance(msg, str) and msg.startswith("[MSG"):
            say(event="msg", msg=msg)


T0 = time.monotonic()


def main():
    url, path = sys.argv[1], sys.argv[2]
    hold_after = (int(sys.argv[sys.argv.index("--hold-after") + 1])
                  if "--hold-after" in sys.argv else None)
    s = Headless()
    s.open(url, 115200)
    until(lambda: CNC.vars.get("state") in ("Idle", "Alarm"))
    say(event="connected", version=CNC.vars.get("version"), **dro())
    if "--jog" in sys.argv:
        # its jog pad's step, as its GRBL1 controller sends it ($J=G91 ... F100000)
        step = sys.argv[sys.argv.index("--jog") + 1]
        start = dro()["mpos"]
        delta = {k.lower(): float(v) for k, v in re.findall(r"([XYZ])(-?[0-9.]+)", step)}
        target = [p + delta.get(k, 0.0) for p, k in zip(start, "xyz")]
        s.mcontrol.jog(step)
        seen_jog = until(lambda: CNC.vars.get("state") == "Jog", period=0.002)
        # at rest where the step ends, as its DRO shows it
        until(lambda: CNC.vars.get("state") == "Idle" and
              all(abs(a - b) < 1e-3 for a, b in zip(dro()["mpos"], target)))
        drain(s)
        say(event="jogged", seen_jog=seen_jog, **dro())
    s.load(path)
    # what bCNC's Application.run does, without the canvas
    s.initRun()
    s._runLines = sys.maxsize
    s._gcount = 0
    CNC.vars["running"] = True
    sent = Recorded(s.queue)
    paths = s.gcode.compile(sent, s.checkStop)
    s._runLines = len(paths) + 1
    s.queue.put((WAIT,))
    t_run = time.monotonic()
    say(event="run", lines=s._runLines)
    held = False
    seen = set()
    while True:
        drain(s)
        st = CNC.vars.get("state")
        if st not in seen:
            seen.add(st)
            say(event="state", **dro())
        if hold_after is not None and not held and s._gcount >= hold_after and st == "Run":
            s.feedHold()
            held = True
            until(lambda: str(CNC.vars.get("state")).startswith("Hold:0"))
            a = dro()
            reports_pass(3)  # held: where it stands over three more reports
            say(event="held", before=a, after=dro())
            s.resume()
        if s._gcount >= s._runLines and st == "Idle":
            s.runEnded()  # as bCNC's window does when every line was answered
            break
        if time.monotonic() - t_run > 600:
            say(event="timeout", **dro())
            break
        time.sleep(0.05)
    say(event="done", seconds=round(time.monotonic() - t_run, 3), gcount=s._gcount, **dro())
    if "--sent" in sys.argv:
        with open(sys.argv[sys.argv.index("--sent") + 1], "w") as fh:
            fh.write("".join(sent.lines))
    s.close()
    os._exit(0)


if __name__ == "__main__":
    main()
