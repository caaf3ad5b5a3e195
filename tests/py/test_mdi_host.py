"""MDI and touch-off (issue 18) on this host (mlip-rt --can none): mlip-ctl
mdi runs G-code lines through mlip-feed's feeder, checked as a program is,
from where the machine stands; its modal state carries to the next mdi
(the modal state file beside the offsets file); a touch-off (G10 L20, G10
L2, G92) from MDI or from a program is kept in the offsets file, and a
program run afterwards moves in the new work coordinates. Judged on the
setpoints mlip-rt records (--record) and on the files written."""
import subprocess

from conftest import CONFIG, Proc, offsets_file, record_rows, status, tool, wait_for

MILL = CONFIG / "mill-3axis.ini"
T = 0.001  # s, mill-3axis' period


def ctl(shm, *args, **kw):
    return subprocess.run([tool("mlip-ctl"), "--shm", shm, *map(str, args)], capture_output=True,
                          text=True, timeout=kw.pop("timeout", 60), **kw)


def mdi(shm, off, *lines, **kw):
    return ctl(shm, "mdi", "--offsets", off, *lines, **kw)


def position(shm):
    return status(shm)["position"]


def speeds(rows, k):
    """Axis k's speed between recorded periods (the controller's time)."""
    return [abs(b[1 + k] - a[1 + k]) / T for a, b in zip(rows, rows[1:])]


def records(modal):
    return dict(line.split(" ", 1) for line in modal.read_text().splitlines()
                if line and not line.startswith("#"))


def test_mdi_moves_and_carries_modal_state(controller, tmp_path):
    """mlip-rt --record keeps the first program's setpoints: a first mdi of
    modes alone sends nothing, so the second one is recorded."""
    rec = tmp_path / "rt.csv"
    off = offsets_file(tmp_path / "off.txt")
    shm, rt = controller(MILL, "--record", rec)
    modal = tmp_path / "off.txt.modal"
    # a line of modes alone is a line: G91 G1 and F carried to the next mdi
    p = mdi(shm, off, "G91 G1 F1200")
    assert p.returncode == 0, p.stderr
    assert "no motion" in p.stderr, p.stderr
    r = records(modal)
    assert (r["MOTION"], r["DISTANCE"], r["F"]) == ("G1", "G91", "1200"), r
    p = mdi(shm, off, "X5 Y-2")  # G1 (carried), incremental, F1200 (carried)
    assert p.returncode == 0, p.stderr
    assert position(shm) == {"X": 5.0, "Y": -2.0, "Z": 0.0}
    p = mdi(shm, off, "G90", "G0 Z5", "X10")
    assert p.returncode == 0, p.stderr
    assert position(shm) == {"X": 10.0, "Y": -2.0, "Z": 5.0}
    r = records(modal)
    assert (r["MOTION"], r["DISTANCE"], r["F"]) == ("G0", "G90", "1200"), r
    rt.terminate()
    rt.communicate(timeout=20)
    rows = record_rows(rec)
    assert rows[-1][1:] == [5.0, -2.0, 0.0], rows[-1]
    v = [((a ** 2 + b ** 2) ** 0.5) for a, b in zip(speeds(rows, 0), speeds(rows, 1))]
    vmax = max(v)
    print(f"\n[mdi] X5 Y-2 after G91 G1 F1200: peak {vmax:.4f} mm/s (F1200 = 20 mm/s)")
    assert 20.0 * 0.99 <= vmax <= 20.0 * (1 + 1e-6)  # the carried F, not G0's speed


def test_mdi_canned_cycle(controller, tmp_path):
    """A drilling cycle from MDI (G98 G81): the hole drilled and the tool
    back where it began; the modal state file says MOTION G80 (the cycle's
    mode ends with its MDI line, its sticky numbers are not kept), so a next
    mdi of axis words alone is refused, naming why, and moves nothing; G0
    moves again."""
    off = offsets_file(tmp_path / "off.txt")
    shm, _ = controller(MILL)
    p = mdi(shm, off, "G0 Z5", "G98 G81 X3 Y4 Z-1 R1 F600")
    assert p.returncode == 0, p.stderr
    assert position(shm) == {"X": 3.0, "Y": 4.0, "Z": 5.0}
    assert records(tmp_path / "off.txt.modal")["MOTION"] == "G80"
    p = mdi(shm, off, "X6")
    assert p.returncode != 0 and "after a canned cycle ended" in p.stderr, p.stderr
    assert position(shm) == {"X": 3.0, "Y": 4.0, "Z": 5.0}
    p = mdi(shm, off, "G0 X6")
    assert p.returncode == 0, p.stderr
    assert position(shm) == {"X": 6.0, "Y": 4.0, "Z": 5.0}


def test_mdi_touch_off_then_program(controller, tmp_path):
    """G10 L20 from MDI: the offsets file holds it; a program then runs in the
    new work coordinates, judged on its recorded setpoints (the machine's)."""
    rec = tmp_path / "rt.csv"
    off = offsets_file(tmp_path / "off.txt")
    shm, rt = controller(MILL, "--record", rec)
    # the machine stands at X0 Y0 Z0: it reads X-30 Y7 Z-4 in G54 from now on
    p = mdi(shm, off, "G10 L20 P1 X-30 Y7 Z-4")
    assert p.returncode == 0, p.stderr
    assert "written to" in p.stderr, p.stderr
    text = off.read_text()
    assert "G54 X30 Y-7 Z4" in text, text
    prog = tmp_path / "p.ngc"
    prog.write_text("G54 G90 G1 X1 Y2 Z-1 F600\n")
    p = subprocess.run([tool("mlip-feed"), "--shm", shm, "--offsets", off, prog],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert position(shm) == {"X": 31.0, "Y": -5.0, "Z": 3.0}
    rt.terminate()
    rt.communicate(timeout=20)
    rows = record_rows(rec)
    assert rows[0][1:] == [0.0, 0.0, 0.0] and rows[-1][1:] == [31.0, -5.0, 3.0], rows[-1]


def test_touch_off_program_and_g92(controller, tmp_path):
    """G10 L2 in a program with no motion: accepted, said, kept; G92 and
    G92.1 from MDI shift and restore the coordinates."""
    off = offsets_file(tmp_path / "off.txt")
    shm, _ = controller(MILL)
    prog = tmp_path / "touch.ngc"
    prog.write_text("G10 L2 P2 X100 Y50 Z-10\n")
    p = subprocess.run([tool("mlip-feed"), "--shm", shm, "--offsets", off, prog],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert "no motion: only the offsets change" in p.stderr, p.stderr
    assert "G55 X100 Y50 Z-10" in off.read_text()
    assert mdi(shm, off, "G55 G0 X1").returncode == 0
    assert position(shm) == {"X": 101.0, "Y": 0.0, "Z": 0.0}  # Y, Z not given: stay
    assert "SELECT G55" in off.read_text()
    assert mdi(shm, off, "G92 X0").returncode == 0
    assert "G92_ON 1" in off.read_text() and "G92 X1 Y0 Z0" in off.read_text()
    assert mdi(shm, off, "G0 X2").returncode == 0
    assert position(shm)["X"] == 103.0
    assert mdi(shm, off, "G92.1").returncode == 0
    assert "G92_ON 0" in off.read_text()
    assert mdi(shm, off, "G54 G0 X2").returncode == 0
    assert position(shm)["X"] == 2.0


def test_mdi_checked_like_a_program(controller, tmp_path):
    """Every error named with its line and column, nothing moves, nothing is
    written: a soft limit, a missing feed, an unknown word."""
    off = offsets_file(tmp_path / "off.txt")
    shm, _ = controller(MILL)
    assert mdi(shm, off, "G0 X10").returncode == 0
    modal = tmp_path / "off.txt.modal"
    before_modal, before_off = modal.read_text(), off.read_text()
    p = mdi(shm, off, "G91", "G0 X995")
    assert p.returncode == 1
    assert "mdi:2:4: error: X 1005.000 beyond soft limit" in p.stderr, p.stderr
    assert "nothing was run" in p.stderr
    p = mdi(shm, off, "G1 Y5")  # no F ever: an error, as in a program
    assert p.returncode == 1 and "mdi:1:1: error: missing feed" in p.stderr, p.stderr
    p = mdi(shm, off, "G10 L20 P1 X0", "G1 X1 Q7")
    assert p.returncode == 1 and "mdi:2:" in p.stderr, p.stderr
    assert position(shm)["X"] == 10.0
    assert modal.read_text() == before_modal and off.read_text() == before_off
    # a damaged modal state file is refused with what to do; nothing runs
    modal.write_text(before_modal.replace("G90", "G91"))
    p = mdi(shm, off, "G0 X0")
    assert p.returncode == 1 and "changed after mlip wrote it" in p.stderr, p.stderr
    assert position(shm)["X"] == 10.0
    p = ctl(shm, "mdi", "--accept", modal)
    assert p.returncode == 0, p.stderr
    assert mdi(shm, off, "G0 X1").returncode == 0
    assert position(shm)["X"] == 11.0  # G91, as accepted


def test_mdi_stdin_and_status(controller, tmp_path):
    """`mdi -` reads the lines from standard input; status shows the MDI in
    progress (text and JSON)."""
    off = offsets_file(tmp_path / "off.txt")
    shm, _ = controller(MILL)
    m = Proc([tool("mlip-ctl"), "--shm", shm, "mdi", "--offsets", off, "-"],
             stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
             text=True)
    m.stdin.write("G21 G90\nG1 X40 F600 ; 4 s\n")
    m.stdin.close()
    st = wait_for(lambda: (lambda s: s if s.get("mdi") and s["state"] == "running" else None)(
        status(shm)), 20)
    assert st, status(shm)
    text = ctl(shm, "status").stdout
    assert "(MDI: mlip-ctl mdi)" in text, text
    assert m.wait(60) == 0, m.said()
    assert position(shm)["X"] == 40.0
    assert status(shm)["mdi"] is False


def test_mdi_refused_while_busy(controller, tmp_path):
    """Not queued behind a jog (or a program): refused at once, nothing moves
    afterwards."""
    off = offsets_file(tmp_path / "off.txt")
    shm, _ = controller(MILL)
    j = Proc([tool("mlip-ctl"), "--shm", shm, "jog", "Y+", "600", "30"],
             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert wait_for(lambda: (status(shm) or {}).get("state") == "jog", 60)
        p = mdi(shm, off, "G0 X50")
        assert p.returncode == 1
        assert "refused: the controller on" in p.stderr and "is jog" in p.stderr, p.stderr
    finally:
        j.terminate()
        j.wait(20)
    assert wait_for(lambda: (status(shm) or {}).get("state") == "idle", 60)
    assert position(shm)["X"] == 0.0


def test_mdi_bad_arguments(controller, tmp_path):
    shm, _ = controller(MILL)
    p = ctl(shm, "mdi")
    assert p.returncode == 2 and "no line given" in p.stderr
    p = ctl(shm, "mdi", "--nope", "G0 X1")
    assert p.returncode == 2
    p = ctl(shm, "mdi", "X" * 70000)
    assert p.returncode == 2 and "that is a program" in p.stderr
    assert position(shm)["X"] == 0.0


def test_mdi_carries_tool_length_offset(controller, tmp_path):
    """G43 H1 in one mdi, a move in the next: Z in machine coordinates is the
    program's Z plus tool 1's length (the tool table's Z 10); G49 ends it."""
    off = offsets_file(tmp_path / "off.txt")
    tools = tmp_path / "tools.tbl"
    tools.write_text("T1 P1 Z10 D6 ;6 mm flat\n")
    subprocess.run([tool("mlip-tools"), "--accept", tools], check=True, capture_output=True)
    shm, _ = controller(MILL)
    p = ctl(shm, "mdi", "--offsets", off, "--tools", tools, "G43 H1")
    assert p.returncode == 0, p.stderr
    assert records(tmp_path / "off.txt.modal")["TOOL_OFFSET"] == "G43 10"
    p = ctl(shm, "mdi", "--offsets", off, "--tools", tools, "G0 Z0")
    assert p.returncode == 0, p.stderr
    assert position(shm)["Z"] == 10.0
    p = ctl(shm, "mdi", "--offsets", off, "--tools", tools, "G49", "G0 Z0")
    assert p.returncode == 0, p.stderr
    assert position(shm)["Z"] == 0.0
    assert records(tmp_path / "off.txt.modal")["TOOL_OFFSET"] == "G49"
