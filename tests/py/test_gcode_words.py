"""The G-code people actually have (issue 11) and programs of any length
(issue 9), as a user meets them: every sender example loads and runs within
the limits; work offsets, G64 P, G61, G93, G28 and Grbl's conventions act on
the motion (judged from the trace by mlip-check); the offsets file is read
and written back; non-files are refused; loading memory does not grow with
the program."""
import json
import math
import os
import shutil
import signal
import subprocess
import time

import pytest

from conftest import CONFIG, TOOLPATHS, Proc, offsets_file, periods_on, run, tool

MILL = CONFIG / "mill-3axis.ini"
SENDERS = TOOLPATHS / "senders"
SENDER_FILES = sorted(p.name for p in SENDERS.iterdir()) if SENDERS.is_dir() else []


def sim(tmp_path, text, *opts, name="p.ngc", check=True):
    prog = tmp_path / name
    prog.write_text(text)
    trace = tmp_path / (name + ".csv")
    p = run(["mlip-sim", "--config", MILL, "--trace", trace, "--summary", "-", *opts, prog],
            check=check)
    return prog, trace, p


def rows(trace):
    lines = trace.read_text().splitlines()[1:]
    return [[float(v) for v in l.split(",")] for l in lines]


def check(prog, trace, *opts):
    return run(["mlip-check", "--config", MILL, *opts, prog, trace], check=False)


@pytest.mark.parametrize("name", SENDER_FILES)
def test_sender_examples_load_and_run(tmp_path, name):
    """Every sender example loads (a program that sets no F needs
    --default-feed, as Grbl needs an F before G1) and runs within the limits."""
    src = SENDERS / name
    trace = tmp_path / "t.csv"
    # the motion is under test: the lasers' and routers' S, M3, T on purpose as nothing
    io = ("--ignore-spindle", "--ignore-coolant", "--ignore-tools")
    p = run(["mlip-sim", "--config", MILL, "--default-feed", "300", *io, "--trace", trace,
             "--summary", "-", src])
    s = json.loads(p.stdout)
    assert s["blocks"] > 10
    assert s["max_contour_error_mm"] <= s["eps_mm"] * (1 + 1e-9)
    c = run(["mlip-check", "--config", MILL, "--default-feed", "300", *io, src, trace],
            check=False)
    assert c.returncode == 0, c.stdout + c.stderr
    assert ": error:" not in p.stderr


def test_sender_notes_name_what_mlip_did():
    p = run(["mlip-sim", "--config", MILL, SENDERS / "laser_circle.gcode"])
    assert "laser_circle.gcode:1: note: $32= (Grbl settings or report) skipped" in p.stderr
    assert "(2 times)" in p.stderr
    p = run(["mlip-sim", "--config", MILL, "--strict", SENDERS / "laser_circle.gcode"],
            check=False)
    assert p.returncode == 1
    assert "laser_circle.gcode:1:1: error: Grbl system line '$32=1' is not G-code" in p.stderr
    p = run(["mlip-sim", "--config", MILL, SENDERS / "line_skip_test.gcode"], check=False)
    assert p.returncode == 1
    assert "line_skip_test.gcode:4:1: error: missing feed: no F before the first feed move " \
           "(a program with none runs with --default-feed F)" in p.stderr


def test_work_offsets_through_the_tools(tmp_path):
    """G55 from the offsets file moves the part; mlip-check judges the trace
    against the program in machine coordinates only with the same offsets;
    --save-offsets writes what G10 set."""
    off = offsets_file(tmp_path / "offsets", "G55 X10 Y20 Z0")
    text = "G55 G1 X1 Y1 F600\nG10 L2 P1 X5\nG54 G1 X0 Y0\n"
    prog, trace, p = sim(tmp_path, text, "--offsets", off, "--save-offsets")
    assert f"mlip-sim: offsets: G54 X0 Y0 Z0, G92 off ({off})" in p.stderr
    r = rows(trace)
    assert min(math.hypot(x - 11, y - 21) for _, x, y, _ in r) < 0.02  # G55: (11, 21), blended
    assert r[-1][1:] == [5.0, 0.0, 0.0]  # G54's X origin is now 5
    assert check(prog, trace, "--offsets", off).returncode == 0
    # the state as written: G54 X origin 5, G55 kept, G54 selected
    saved = off.read_text()
    assert "\nSELECT G54\n" in saved and "\nG54 X5 Y0 Z0\n" in saved
    assert "\nG55 X10 Y20 Z0\n" in saved
    # the same trace against the program without those offsets is off the path
    fresh = offsets_file(tmp_path / "fresh")
    bad = check(prog, trace, "--offsets", fresh)
    assert bad.returncode == 1 and "contour" in bad.stdout + bad.stderr
    # an edit that was not accepted is refused; accepting it names file:line
    off.write_text(saved.replace("\nG55 X10 Y20 Z0\n", "\nG55 X1 Y2\n"))
    p = run(["mlip-sim", "--config", MILL, "--offsets", off, prog], check=False)
    assert p.returncode == 1
    assert f"{off}: changed after mlip wrote it" in p.stderr
    assert f"mlip-offsets --accept {off}" in p.stderr
    p = run(["mlip-offsets", "--accept", off], check=False)
    line = saved[:saved.index("\nG55 ")].count("\n") + 2
    assert p.returncode == 1 and f"{off}:{line}: G55: no value for axis Z" in p.stderr


def test_soft_limits_in_machine_coordinates(tmp_path):
    off = offsets_file(tmp_path / "offsets", "G55 X900")
    prog = tmp_path / "p.ngc"
    prog.write_text("G55 G0 X50\nG0 X150\n")
    p = run(["mlip-sim", "--config", MILL, "--offsets", off, prog], check=False)
    assert p.returncode == 1
    assert f"{prog}:2:4: error: X 1050.000 beyond soft limit 1000.000" in p.stderr


ZIGZAG = "G1 X0 Y0 F6000\n" + "".join(f"X{(k + 1) * 2} Y{5 * (k % 2)}\n" for k in range(20))


def test_g64_p_region_within_its_tolerance(tmp_path):
    """G64 P0.002: every corner within 0.002 mm (tighter than eps 0.01),
    and the tolerance is used; without it corners use eps."""
    prog, trace, p = sim(tmp_path, "G64 P0.002\n" + ZIGZAG)
    s = json.loads(p.stdout)
    assert 0.0005 < s["max_contour_error_mm"] <= 0.002 * (1 + 1e-9)  # blends, within P
    assert check(prog, trace, "--eps", "0.002").returncode == 0
    prog2, trace2, p2 = sim(tmp_path, ZIGZAG, name="q.ngc")
    assert json.loads(p2.stdout)["max_contour_error_mm"] > 0.005
    assert check(prog2, trace2, "--eps", "0.002").returncode == 1
    # a P larger than the machine's eps is capped, and said so
    _, _, p3 = sim(tmp_path, "G64 P0.5\n" + ZIGZAG, name="r.ngc")
    assert "r.ngc:1: note: G64 P tolerance larger than the machine's CONTOUR_TOLERANCE: " \
           "capped to it" in p3.stderr
    assert json.loads(p3.stdout)["max_contour_error_mm"] <= 0.01 * (1 + 1e-9)


def test_arc_p_turns(tmp_path):
    """G2 with P3 (LinuxCNC): the programmed full circle plus two more, Z
    linear in the angle over all three, judged from the trace: mlip-check
    passes it against the program, and from the helix's first sample below
    Z0 to its lowest the tool winds 6 pi clockwise around the centre (to
    0.05 rad: the blended corners at its ends; P2 would be 4 pi), with Z
    within eps of -3 * angle / (6 pi) away from them."""
    prog, trace, _ = sim(tmp_path, "G0 X10 Y0 Z0\nG2 I-10 Z-3 P3 F3000\nG0 Z5\n")
    assert check(prog, trace).returncode == 0
    r = rows(trace)
    i0 = next(i for i, row in enumerate(r) if row[3] < 0)
    i1 = min(range(len(r)), key=lambda i: r[i][3])
    turn, prev = 0.0, math.atan2(r[i0 - 1][2], r[i0 - 1][1])
    for _, x, y, z in r[i0:i1 + 1]:
        a = math.atan2(y, x)
        turn += (a - prev + math.pi) % (2 * math.pi) - math.pi
        prev = a
        if 0.1 < -turn < 6 * math.pi - 0.1:
            assert abs(z - 3 * turn / (6 * math.pi)) <= 0.01
    assert abs(turn + 6 * math.pi) <= 0.05
    bad = tmp_path / "e.ngc"
    bad.write_text("G0 X10\nG2 I-10 P1.5 F3000\n")
    e = run(["mlip-sim", "--config", MILL, bad], check=False)
    assert e.returncode == 1
    assert "e.ngc:2:9: error: G2 P1.5: the number of turns is a whole number" in e.stderr


def test_canned_cycles_drill_a_plate(tmp_path):
    """G81, G83 and G82 (LinuxCNC), judged from the trace: mlip-check passes
    it against the program; below R (1 mm) the tool is only over a hole (it
    never drags through the part); each hole reaches its bottom
    exactly and no deeper; G83 pecks to -1, -3, -5, then -6 (Q2 from R1),
    out to R between; G82 rests 0.25 s at its bottom (250 periods); G98
    goes back to Z10, G99 to R."""
    prog, trace, p = sim(tmp_path, "G21 G90 G17\nG0 X0 Y0 Z10\n"
                         "G98 G81 X5 Y5 Z-2 R1 F300\nX10\n"
                         "G99 G83 X15 Y5 Z-6 R1 Q2\nG82 X20 Y5 Z-3 R1 P0.25\nG80\nG0 Z10\n")
    assert check(prog, trace).returncode == 0
    r = rows(trace)
    # below R only over a hole: a sample more than a period's step from rest
    # (A T^2 / 2 = 5e-4 mm at 1000 mm/s^2, 1 ms: a move's end at rest falls
    # between two samples) below R is within that of a hole's X Y
    step = 1000 * 1e-6 / 2
    holes = ((5, 5), (10, 5), (15, 5), (20, 5))
    for row in r[next(k for k, row in enumerate(r) if row[3] >= 10) :]:  # from above the part
        if row[3] < 1.0 - step:
            assert min(math.hypot(row[1] - x, row[2] - y) for x, y in holes) <= step, row
    for x, bottom in ((5, -2), (10, -2), (15, -6), (20, -3)):
        z = [row[3] for row in r if abs(row[1] - x) < 1e-9 and abs(row[2] - 5) < 1e-9]
        assert bottom - 1e-9 <= min(z) <= bottom + step, (x, min(z))
    z15 = [row[3] for row in r if abs(row[1] - 15) < 1e-9 and abs(row[2] - 5) < 1e-9]
    lows = [z15[k] for k in range(1, len(z15) - 1) if z15[k] < z15[k - 1] and z15[k] <= z15[k + 1]]
    assert len(lows) == 4, lows
    for low, depth in zip(lows, (-1, -3, -5, -6)):
        assert depth - 1e-9 <= low <= depth + step, lows
    at20 = [row for row in r if abs(row[1] - 20) < 1e-9 and abs(row[3] + 3) < 1e-9]
    assert 250 <= len(at20) <= 252, len(at20)
    # G98 after the first hole: back to 10 before X10; G99 from the G83 on: R
    z10 = [row[3] for row in r if 5 < row[1] < 10]
    assert z10 and min(z10) >= 10 - 1e-9, min(z10)
    z17 = [row[3] for row in r if 15 < row[1] < 20]
    assert z17 and max(z17) <= 1 + 1e-9 and min(z17) >= 1 - 1e-9, (min(z17), max(z17))
    assert r[-1][1:] == [20.0, 5.0, 10.0]


def test_parameters_and_expressions_bolt_circle(tmp_path):
    """A hand-written LinuxCNC bolt circle: named and numbered parameters,
    expressions, SIN/COS in degrees, a setting read before it takes effect
    on its line, a G55 origin read back through #5241. Judged from the
    trace against Python's own arithmetic: the tool rests at each hole's
    bottom (x, y within 1e-9 mm of R (cos, sin) of its angle), and never
    below it; mlip-check passes the trace against the program."""
    prog, trace, p = sim(tmp_path, """G21 G90 G17 G61 (exact stop: each hole to its bottom)
G10 L2 P2 X30 Y40
G55
#<radius> = 12.5
#<holes> = 6
#<_depth> = -[1 + 0.5]
#1 = 15 (start angle)
#2 = [360 / #<holes>]
G0 Z5
G0 X[#<radius> * COS[#1]] Y[#<radius> * SIN[#1]]
G1 Z#<_depth> F300
G0 Z5
#1 = [#1 + #2] G0 X[#<radius> * COS[#1]] Y[#<radius> * SIN[#1]]
G0 X[#<radius> * COS[#1]] Y[#<radius> * SIN[#1]]
G1 Z#<_depth>
G0 Z5
#1 = [#1 + #2]
G0 X[#<radius> * COS[#1]] Y[#<radius> * SIN[#1]]
G1 Z#<_depth>
G0 Z5
#5 = 7 G0 X#5 Y0 (#5 is 0 on this line: the setting comes after it)
G1 Z-0.5
G0 Z5
G0 X[#5241 - 30] Y[ROUND[#5242 / 10] * 10 - 40]
M2
""")
    assert check(prog, trace).returncode == 0
    r = rows(trace)
    step = 1000 * 1e-6 / 2  # a move's end at rest falls between two samples
    # holes at 15, 75, 135 degrees (the setting on a moving line takes effect
    # after it: that line moves to the old angle, the next to the new one)
    holes = {(round(30 + 12.5 * math.cos(math.radians(a)), 6),
              round(40 + 12.5 * math.sin(math.radians(a)), 6)): -1.5 for a in (15.0, 75.0, 135.0)}
    holes[(30.0, 40.0)] = -0.5  # X#5 read before "#5 = 7" took effect: G55's X0
    below = [row for row in r if row[3] < 0]
    assert {(round(b[1], 6), round(b[2], 6)) for b in below} == set(holes)
    for (x, y), depth in holes.items():
        z = [row[3] for row in below if abs(row[1] - x) < 1e-6 and abs(row[2] - y) < 1e-6]
        assert depth - 1e-9 <= min(z) <= depth + step, (x, y, min(z))
    assert r[-1][1:] == [30.0, 40.0, 5.0]  # G55's origin, read back


def test_g61_corners_at_rest(tmp_path):
    """G61: the tool stops exactly on every corner; G64 cuts them."""
    square = "G1 X10 F6000\nY10\nX0\nY0\n"
    _, trace, _ = sim(tmp_path, "G61\n" + square)
    r = rows(trace)
    for cx, cy in ((10, 0), (10, 10), (0, 10)):
        k = min(range(len(r)), key=lambda i: math.hypot(r[i][1] - cx, r[i][2] - cy))
        assert math.hypot(r[k][1] - cx, r[k][2] - cy) < 1e-9
        # at rest there: the samples around it move less than a*T^2
        assert math.hypot(r[k + 1][1] - r[k][1], r[k + 1][2] - r[k][2]) <= 1000 * 1e-6 * 1.01
    _, trace2, _ = sim(tmp_path, square, name="q.ngc")
    r2 = rows(trace2)
    assert min(math.hypot(x - 10, y - 10) for _, x, y, _ in r2) > 1e-4


def test_g93_inverse_time(tmp_path):
    """G93 F6: the 10 mm move takes 1/6 min = 10 s: 1 mm/s, (plus the ramps)."""
    _, trace, p = sim(tmp_path, "G0 X10\nG93 G1 X20 F6\n")
    s = json.loads(p.stdout)
    rapid = sim(tmp_path, "G0 X10\n", name="r.ngc")[2]
    t = s["total_time_s"] - json.loads(rapid.stdout)["total_time_s"]
    assert 9.99 <= t <= 10.01
    r = rows(trace)
    v = [(r[k + 1][1] - r[k][1]) / 1e-3 for k in range(len(r) - 1) if 10.5 < r[k][1] < 19.5]
    assert len(v) > 8000 and max(abs(x - 1.0) for x in v) < 1e-6


def test_g28_intermediate_point_and_stored_position(tmp_path):
    prog, trace, _ = sim(tmp_path, "G1 X5 Y5 F6000\nG28 X7\n")
    r = rows(trace)
    assert min(math.hypot(x - 7, y - 5) for _, x, y, _ in r) < 0.011  # through (7, 5)
    assert r[-1][1:] == [0.0, 5.0, 0.0]  # X to its G28 position (HOME), Y stays
    assert check(prog, trace).returncode == 0
    # G28.1 stores where we are; the offsets file keeps it
    off = offsets_file(tmp_path / "off")
    sim(tmp_path, "G1 X3 Y4 F6000\nG28.1\nG1 X0 Y0\n", "--offsets", off, "--save-offsets",
        name="s.ngc")
    assert "\nG28 X3 Y4 Z0\n" in off.read_text()
    _, trace, _ = sim(tmp_path, "G1 X1 F6000\nG28\n", "--offsets", off, name="u.ngc")
    assert rows(trace)[-1][1:] == [3.0, 4.0, 0.0]


def test_grbl_start_motion_mode_g0(tmp_path):
    """Axis words before any G0/G1: Grbl's G0, with a note; --strict refuses."""
    prog, trace, p = sim(tmp_path, "X300 Y300\nG1 X0 F600\n")
    assert "p.ngc:1: note: G0 axis words before any G0/G1/G2/G3 moved as G0" in p.stderr
    assert abs(json.loads(p.stdout)["max_speed_mm_s"] - 200) < 1e-6
    p = run(["mlip-sim", "--config", MILL, "--strict", prog], check=False)
    assert p.returncode == 1
    assert f"{prog}:1:1: error: axis words with no motion mode" in p.stderr


def test_not_regular_files_refused(tmp_path):
    p = run(["mlip-sim", "--config", MILL, "/dev/zero"], check=False, timeout=10)
    assert p.returncode == 1
    assert "mlip-sim: /dev/zero: a character device: mlip reads a program from a regular " \
           "file only" in p.stderr
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    p = run(["mlip-sim", "--config", MILL, fifo], check=False, timeout=10)  # never blocks
    assert p.returncode == 1 and "a FIFO (pipe)" in p.stderr
    p = run(["mlip-sim", "--config", MILL, tmp_path], check=False, timeout=10)
    assert p.returncode == 1 and "a directory" in p.stderr
    p = run(["mlip-sim", "/dev/zero"], check=False, timeout=10)  # axes scan without config
    assert p.returncode == 1 and "a character device" in p.stderr


def _spiral(path, size_bytes):
    with open(path, "w") as f:
        f.write("G21 G90\nG0 X100 Y0\nG1 F12000\n")
        a = 0.0
        while f.tell() < size_bytes:
            chunk = []
            for _ in range(5000):
                a += 0.0005
                chunk.append("X%.4f Y%.4f\n" % (100 * math.cos(a), 100 * math.sin(a)))
            f.write("".join(chunk))


def _rss_kb(cmd):
    aslr_off = ["setarch", "-R"] if shutil.which("setarch") else []  # steadier RSS
    p = subprocess.run([*aslr_off, "/usr/bin/time", "-f", "MAXRSS %M", *cmd],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    return int([l for l in p.stderr.splitlines() if l.startswith("MAXRSS ")][-1].split()[1]), p.stdout


# Linux 6.1 counts a task's resident pages per thread and folds them into the
# process' counters every 64 page faults (SPLIT_RSS_COUNTING; percpu counters
# with a batch since 6.2), and samples the peak (VmHWM, ru_maxrss) only at
# unmaps and exit: a run's peak reads up to 64 pages low for each of the
# anonymous and file counters, as scheduling falls (on main: 1808 kB once for
# a 1 MB program whose every other run gave 2100 kB). The peak only ever
# reads low, so each figure is the highest of three runs, and a growth within
# 2 x 64 pages is the measurement's own; the programs are far apart in length
# so that a growth of about a byte per block exceeds it.
RSS_NOISE_KB = 2 * 64 * 4


def _peak(cmd, small, big, runs=3):
    """Highest peak RSS of `runs` runs on each program, interleaved."""
    rs, rb, ps, pb = 0, 0, None, None
    for _ in range(runs):
        r, ps = _rss_kb([*cmd, small])
        rs = max(rs, r)
        r, pb = _rss_kb([*cmd, big])
        rb = max(rb, r)
    return rs, rb, ps, pb


def test_loading_memory_flat(tmp_path):
    """mlip-feed's loading (check the whole file, then stream it, pinned in
    chunks): the peak RSS of a 20 MB program (1.06 M blocks) within the
    kernel's accounting granularity of a 1 MB one's (55 k blocks): a growth
    of half a byte per block fails (bench/rss.py measures 2/20/200 MB)."""
    if not os.access("/usr/bin/time", os.X_OK):
        pytest.fail("/usr/bin/time (GNU time) missing: tools/deps.sh installs it")
    small, big = tmp_path / "s.ngc", tmp_path / "b.ngc"
    _spiral(small, 1_000_000)
    _spiral(big, 20_000_000)
    rs, rb, ps, pb = _peak([tool("bench_load")], small, big)
    ns, nb = json.loads(ps)["blocks"], json.loads(pb)["blocks"]
    assert nb > 19 * ns  # the big one really is twenty times longer
    assert rb <= rs + RSS_NOISE_KB, f"peak RSS {rs} kB for {ns} blocks, {rb} kB for {nb}"



def test_sim_memory_flat(tmp_path):
    """mlip-sim (its feeder and its own check each stream the program, the
    check keeps a fixed window of the polyline): the peak RSS of a 10 MB
    program within the kernel's accounting granularity of a 1 MB one's (a
    growth of about a byte per block fails). It grew ~3.5x from 2 to 20 MB
    while the check held the whole polyline in an array."""
    if not os.access("/usr/bin/time", os.X_OK):
        pytest.fail("/usr/bin/time (GNU time) missing: tools/deps.sh installs it")
    small, big = tmp_path / "s.ngc", tmp_path / "b.ngc"
    _spiral(small, 1_000_000)
    _spiral(big, 10_000_000)
    rs, rb, ps, pb = _peak([tool("mlip-sim"), "-q", "--summary", "-"], small, big)
    ss, sb = json.loads(ps), json.loads(pb)
    assert sb["blocks"] > 9 * ss["blocks"]  # the big one really is ten times longer
    assert rb <= rs + RSS_NOISE_KB, \
        f"peak RSS {rs} kB for {ss['blocks']} blocks, {rb} kB for {sb['blocks']}"
    assert ss["violations"] == 0 and sb["violations"] == 0  # the check did see the whole path


def test_dwell_and_pause_through_mlip_sim(tmp_path):
    """G4 P0.25: at rest on (10, 0) for round(0.25 / T) periods; M0 with
    --resume-after 0.5: at rest for 0.5 s; the trace still passes mlip-check."""
    prog, trace, _ = sim(tmp_path, "G1 X10 F6000\nG4 P0.25\nG1 X20\n")
    r = rows(trace)
    at = [k for k in range(len(r)) if r[k][1:] == [10.0, 0.0, 0.0]]
    assert len(at) == 251  # the arrival at rest, then the dwell's 250 periods
    assert check(prog, trace).returncode == 0
    prog, trace, _ = sim(tmp_path, "G1 X10 F6000 M0\nG1 X20\n", "--resume-after", "0.5",
                         name="m0.ngc")
    r = rows(trace)
    at = [k for k in range(len(r)) if r[k][1:] == [10.0, 0.0, 0.0]]
    assert len(at) == 501  # the arrival, then 500 periods paused
    assert check(prog, trace).returncode == 0


def test_mlip_feed_offsets_file(tmp_path, controller):
    """mlip-feed reads the offsets, says which it used, runs the program and
    writes the state back when the program completes (the motion in machine
    coordinates is the reader's, the same as mlip-sim's, tested above)."""
    shm, _ = controller()
    off = offsets_file(tmp_path / "offsets", "SELECT G55", "G55 X10 Y20 Z0")
    prog = tmp_path / "p.ngc"
    prog.write_text("G1 X1 Y1 F6000\nG10 L2 P2 X0\nG92 X0\n")
    p = subprocess.run([tool("mlip-feed"), "--shm", shm, "--offsets", str(off), str(prog)],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert f"mlip-feed: offsets: G55 X10 Y20 Z0, G92 off ({off})" in p.stderr
    assert "program complete" in p.stderr
    saved = off.read_text()
    assert "\nSELECT G55\n" in saved and "\nG55 X0 Y20 Z0\n" in saved
    assert "\nG92_ON 1\n" in saved and "\nG92 X11 Y0 Z0\n" in saved


def test_feed_dwell_pause_offsets_end_to_end(tmp_path, controller):
    """Through the real ring and controller (mlip-rt --can none): a program in
    G55 from the offsets file with a dwell and an M0. The controller pauses
    at the M0 point in machine coordinates until mlip-ctl resume; mlip-rt's
    record equals mlip-sim's trace row for row up to the pause, dwell
    included, and passes mlip-check with the same offsets."""
    off = offsets_file(tmp_path / "offsets", "SELECT G55", "G55 X10 Y20 Z0")
    prog = tmp_path / "p.ngc"
    prog.write_text("G1 X10 F6000\nG4 P0.25\nG1 X20 M0\nG1 X30\n")
    rec = tmp_path / "rt.csv"
    shm, rt = controller(MILL, "--record", rec)
    f = Proc([tool("mlip-feed"), "--shm", shm, "--offsets", str(off), str(prog)],
             stderr=subprocess.PIPE, text=True)
    paused = None
    for _ in range(600):
        st = subprocess.run([tool("mlip-ctl"), "--shm", shm, "status", "--json"],
                            capture_output=True, text=True).stdout
        st = json.loads(st) if st.strip() else {}
        if st.get("state") == "paused":
            paused = st
            break
        time.sleep(0.02)
    assert paused, "the controller never paused at the M0"
    # X20 in G55 is machine X30; Y, never programmed, stays where it was (LinuxCNC)
    assert paused["position"] == {"X": 30.0, "Y": 0.0, "Z": 0.0}
    later = periods_on(shm, 200)  # a pause waits for resume, however long
    assert later and later["state"] == "paused" and later["position"] == paused["position"], later
    assert subprocess.run([tool("mlip-ctl"), "--shm", shm, "resume"]).returncode == 0
    _, ferr = f.communicate(timeout=60)
    assert f.returncode == 0, ferr
    assert f"mlip-feed: offsets: G55 X10 Y20 Z0, G92 off ({off})" in ferr
    rt.send_signal(signal.SIGTERM)
    rt.communicate(timeout=20)
    rows = rec.read_text().splitlines()
    sim = tmp_path / "sim.csv"
    run(["mlip-sim", "-q", "--config", MILL, "--offsets", off, "--trace", sim, prog])
    srows = sim.read_text().splitlines()
    k = next(i for i, r in enumerate(srows[1:], 1) if r.split(",")[1:] == ["30", "0", "0"])
    assert [r.split(",", 1)[1] for r in rows[:k + 1]] == [r.split(",", 1)[1] for r in srows[:k + 1]]
    dwell = [r for r in rows[1:] if r.split(",")[1:] == ["20", "0", "0"]]
    assert len(dwell) == 251  # arrival at rest, then 250 periods of G4 P0.25
    assert rows[-1].split(",")[1:] == ["40", "0", "0"]
    c = run(["mlip-check", "--config", MILL, "--offsets", off, prog, rec], check=False)
    assert c.returncode == 0, c.stdout + c.stderr
