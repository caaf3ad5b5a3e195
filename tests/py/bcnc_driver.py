"""Drive bCNC (PyPI bCNC, its own Sender: the serial thread, the GRBL1
controller plugin, its G-code compiler) without its window: connect through
pyserial's socket:// URL, read the DRO, jog, run a file, hold and resume it, and
print one JSON line per event for the test to judge.

    python bcnc_driver.py socket://127.0.0.1:PORT FILE [--hold-at SECONDS] [--jog X2Y1]

bCNC's modules import each other by their bare names (its __main__ puts its
folder on the path): this driver does the same for the installed package.
"""
import json
import os
import sys
import time

import bCNC

HERE = os.path.dirname(bCNC.__file__)
for sub in ("", "lib", "plugins", "controllers"):
    sys.path.insert(0, os.path.join(HERE, sub))

import Helpers  # noqa: E402,F401  (bCNC's: installs gettext's _ first, as its main does)
import Utils  # noqa: E402  (bCNC's)

Utils.loadConfiguration()
from CNC import CNC, WAIT  # noqa: E402
from Sender import Sender  # noqa: E402


class Headless(Sender):
    """bCNC's Sender with its window's hooks doing nothing."""

    def disable(self):
        pass

    def enable(self):
        pass

    def checkStop(self):
        return self._stop  # what bCNC's window's checkStop answers, without its events


def say(**kw):
    kw["t"] = round(time.monotonic() - T0, 3)
    print(json.dumps(kw), flush=True)


def dro():
    return {"state": CNC.vars.get("state"), "mpos": [CNC.vars.get(k) for k in ("mx", "my", "mz")],
            "wpos": [CNC.vars.get(k) for k in ("wx", "wy", "wz")]}


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
    hold_at = float(sys.argv[sys.argv.index("--hold-at") + 1]) if "--hold-at" in sys.argv else None
    s = Headless()
    s.open(url, 115200)
    end = time.monotonic() + 10
    while time.monotonic() < end and CNC.vars.get("state") not in ("Idle", "Alarm"):
        time.sleep(0.05)
    say(event="connected", version=CNC.vars.get("version"), **dro())
    if "--jog" in sys.argv:
        # its jog pad's step, as its GRBL1 controller sends it ($J=G91 ... F100000)
        s.mcontrol.jog(sys.argv[sys.argv.index("--jog") + 1])
        end = time.monotonic() + 20
        while time.monotonic() < end and CNC.vars.get("state") != "Jog":
            time.sleep(0.01)
        seen_jog = CNC.vars.get("state") == "Jog"
        while time.monotonic() < end and CNC.vars.get("state") != "Idle":
            time.sleep(0.05)
        time.sleep(0.3)  # a status report after the move
        drain(s)
        say(event="jogged", seen_jog=seen_jog, **dro())
    s.load(path)
    # what bCNC's Application.run does, without the canvas
    s.initRun()
    s._runLines = sys.maxsize
    s._gcount = 0
    CNC.vars["running"] = True
    paths = s.gcode.compile(s.queue, s.checkStop)
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
        if hold_at is not None and not held and time.monotonic() - t_run > hold_at:
            s.feedHold()
            held = True
            end = time.monotonic() + 10
            while time.monotonic() < end and not str(CNC.vars.get("state")).startswith("Hold:0"):
                time.sleep(0.05)
            a = dro()
            time.sleep(0.5)
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
    s.close()
    os._exit(0)


if __name__ == "__main__":
    main()
