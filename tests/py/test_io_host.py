"""The machine's I/O (issue 19) end to end on this host: a config with a
manual spindle, a manual tool change at a change position and manual
coolant, a sealed tool table, the offsets file keeping the tool in the
spindle. mlip-sim (the controller on a virtual clock, the operator resuming
at once) and the real mlip-rt / mlip-feed / mlip-ctl (--can none): every
spindle, tool and coolant word pauses the machine at rest with what the
operator is to do; resume continues; nothing a program asks is dropped."""
import csv
import json
import re
import signal
import subprocess
import threading

from conftest import CONFIG, offsets_file, run, status, tool, wait_for

PROGRAM = """G21 G90 G17
T1 M6
G43 H1
S12000 M3
M8
G0 X10 Y10 Z5
G1 Z-1 F600
G1 X20
G0 Z5
T2 M6
G43
S8000 M4
G1 Z-1 F600
G1 X10
G0 Z5
M30
"""
TABLE = "T1 P1 Z12.5 D6 ;6 mm flat\nT2 P2 Z30.25 D3.175 ;1/8 ball\n"
IO = ("\n[SPINDLE]\nTYPE = manual\nMIN_RPM = 1000\nMAX_RPM = 24000\n"
      "[TOOL]\nCHANGE = manual\nCHANGE_Z = 100\n[COOLANT]\nTYPE = manual\n")


def machine(tmp_path):
    cfg = tmp_path / "mill-io.ini"
    cfg.write_text((CONFIG / "mill-3axis.ini").read_text() + IO)
    tbl = tmp_path / "tool.tbl"
    tbl.write_text(TABLE)
    p = run(["mlip-tools", "--accept", tbl])
    assert "accepted and sealed" in p.stdout and "T2" in p.stdout
    prog = tmp_path / "io.ngc"
    prog.write_text(PROGRAM)
    return cfg, tbl, prog


def test_sim_pauses_and_length_offsets(tmp_path):
    """Each event pauses the machine at rest (8: two changes, each with its
    spindle stop before, two starts, coolant on, and M30's spindle and
    coolant off); Z carries the tool's length in machine coordinates; M6
    goes to the change position Z100 first."""
    cfg, tbl, prog = machine(tmp_path)
    trace = tmp_path / "t.csv"
    s = run(["mlip-sim", "-q", "--config", cfg, "--tools", tbl, "--summary", "-", "--trace", trace,
             prog])
    summary = json.loads(s.stdout)
    assert summary["pauses"] == 8 and summary["violations"] == 0
    rows = [[float(v) for v in r] for r in list(csv.reader(trace.open()))[1:]]
    z = [r[3] for r in rows]
    assert max(z) == 100.0  # the change position, machine coordinates
    # from the first change on (the start is HOME, Z0): the cutting depth Z-1
    # with T1 (12.5) and with T2 (30.25) reached, nothing lower
    z = z[z.index(100.0):]
    assert min(z) == 11.5
    assert any(abs(v - 29.25) < 1e-12 for v in z)
    # without the table the program is refused at the first T, nothing runs
    p = run(["mlip-sim", "-q", "--config", cfg, prog], check=False)
    assert p.returncode == 1
    assert f"{prog}:2:1: error: T1: no tool table given (--tools FILE)" in p.stderr


def test_sim_refusals(tmp_path):
    """A machine without them refuses the words at their line and column,
    unless --ignore-* says so on purpose; an S beyond MAX_RPM is refused."""
    cfg, tbl, prog = machine(tmp_path)
    plain = CONFIG / "mill-3axis.ini"
    p = run(["mlip-sim", "-q", "--config", plain, "--tools", tbl, prog], check=False)
    assert p.returncode == 1
    no_change = "T: this machine has no tool change ([TOOL] CHANGE = none)"
    assert f"{prog}:2:1: error: {no_change}" in p.stderr
    assert f"{prog}:4:1: error: S: this machine has no spindle ([SPINDLE] TYPE = none)" in p.stderr
    assert f"{prog}:5:1: error: M8: this machine has no coolant ([COOLANT] TYPE = none)" in p.stderr
    p = run(["mlip-sim", "--config", plain, "--ignore-spindle", "--ignore-coolant",
             "--ignore-tools", prog])
    assert "ignored on purpose (--ignore-spindle)" in p.stderr
    assert "ignored on purpose (--ignore-tools)" in p.stderr
    fast = tmp_path / "fast.ngc"
    fast.write_text("G0 X1\nS30000 M3\nG1 X2 F100\n")
    p = run(["mlip-sim", "--config", cfg, fast], check=False)
    assert p.returncode == 1
    assert f"{fast}:2:1: error: S30000 beyond the spindle's MAX_RPM 24000: refused" in p.stderr
    # --tools without a machine: refused (there is nothing to apply it to)
    p = run(["mlip-sim", "--tools", tbl, prog], check=False)
    assert p.returncode == 1 and "give its --config" in p.stderr


def test_feed_pauses_for_the_operator(controller, tmp_path):
    """The real processes: mlip-rt publishes the machine's I/O, mlip-feed
    checks the program against it and the table, the controller pauses at
    rest at each event with its reason, mlip-feed and mlip-ctl say what to
    do; mlip-ctl resume continues; the offsets file keeps tool 2 after."""
    cfg, tbl, prog = machine(tmp_path)
    offs = offsets_file(tmp_path / "offsets", config=cfg)
    shm, rt = controller(cfg)
    feeder = subprocess.Popen([tool("mlip-feed"), "--shm", shm, "--tools", str(tbl),
                               "--offsets", str(offs), str(prog)],
                              stderr=subprocess.PIPE, text=True)
    expected = [
        (2, "tool change (manual)", "insert tool 1 (6 mm flat), then resume"),
        (4, "spindle (manual)", "start the spindle clockwise at 12000 rpm, then resume"),
        (5, "coolant (manual)", "turn the flood coolant on (mist off), then resume"),
        (10, "spindle (manual)", "stop the spindle, then resume"),
        (10, "tool change (manual)", "insert tool 2 (1/8 ball), then resume"),
        (12, "spindle (manual)", "start the spindle counter-clockwise at 8000 rpm, then resume"),
        (16, "spindle (manual)", "stop the spindle, then resume"),
        (16, "coolant (manual)", "turn the coolant off, then resume"),
    ]
    # what mlip-feed prints, as it prints it: the operator reads the message,
    # then resumes (a resume before mlip-feed saw the pause would leave it
    # untold, as it would a person)
    lines = []
    reader = threading.Thread(target=lambda: lines.extend(iter(feeder.stderr.readline, "")),
                              daemon=True)
    reader.start()
    try:
        last = None
        for line, why, what in expected:
            def paused(last=last):
                s = status(shm)
                if s and s["state"] == "paused" and s["reason_seq"] != last:
                    return s
                return None
            s = wait_for(paused, timeout=30)
            assert s, f"no pause for line {line}: {status(shm)}"
            # mlip-ctl has no tool table: the tool without its comment
            ctl_what = what
            if why.startswith("tool"):
                ctl_what = re.sub(r" \([^)]*\), then", ", then", what)
            assert (s["reason_line"], s["reason"], s["operator"]) == (line, why, ctl_what), s
            # at rest where the last move ended
            assert s["speed_mm_s"] == 0.0
            text = subprocess.run([tool("mlip-ctl"), "--shm", shm, "status"], capture_output=True,
                                  text=True).stdout
            assert why in text
            last = s["reason_seq"]
            told = f"paused at line {line}, {why}: {what} (mlip-ctl resume)"
            assert wait_for(lambda told=told: any(told in t for t in lines), 30), "".join(lines)
            assert subprocess.run([tool("mlip-ctl"), "--shm", shm, "resume"]).returncode == 0
        feeder.wait(timeout=60)
        reader.join(timeout=10)
    finally:
        if feeder.poll() is None:
            feeder.send_signal(signal.SIGINT)
            feeder.wait(10)
    err = "".join(lines)
    assert feeder.returncode == 0, err
    for line, why, what in expected:
        assert f"paused at line {line}, {why}: {what} (mlip-ctl resume)" in err, err
    assert "TOOL 2" in offs.read_text()
    assert f"tool 2 in the spindle now ({offs})" in err, err


def test_feed_says_what_a_stop_left(controller, tmp_path):
    """A program stopped mid-way leaves the spindle turning, a tool in it, a
    coolant question open: mlip-feed says each, and the offsets file keeps
    the tool the machine holds (the next program's G43 is then right)."""
    cfg, tbl, prog = machine(tmp_path)
    offs = offsets_file(tmp_path / "offsets", config=cfg)
    shm, rt = controller(cfg)
    feeder = subprocess.Popen([tool("mlip-feed"), "--shm", shm, "--tools", str(tbl),
                               "--offsets", str(offs), str(prog)],
                              stderr=subprocess.PIPE, text=True)
    lines = []
    reader = threading.Thread(target=lambda: lines.extend(iter(feeder.stderr.readline, "")),
                              daemon=True)
    reader.start()
    try:
        for line in (2, 4, 5):
            # the operator acts on what mlip-feed told, once it told it
            assert wait_for(lambda n=line: any(f"paused at line {n}," in t for t in lines), 30), \
                "".join(lines)
            if line < 5:
                assert subprocess.run([tool("mlip-ctl"), "--shm", shm, "resume"]).returncode == 0
        assert subprocess.run([tool("mlip-ctl"), "--shm", shm, "stop"]).returncode == 0
        feeder.wait(timeout=60)
        reader.join(timeout=10)
    finally:
        if feeder.poll() is None:
            feeder.send_signal(signal.SIGINT)
            feeder.wait(10)
    err = "".join(lines)
    assert feeder.returncode == 4, err
    assert "stopped while the machine waited at line 5 for the coolant" in err, err
    assert "the spindle turns since line 4 (12000 rpm clockwise)" in err, err
    assert "tool 1 is in the spindle since line 2" in err, err
    assert "TOOL 1" in offs.read_text()


def test_shipped_demo_io():
    """make demo's I/O stage: the shipped table is sealed, the program runs on
    the shipped config with its 8 operator pauses, inside every limit."""
    root = CONFIG.parent
    assert "3 tools" in run(["mlip-tools", root / "examples" / "tool.tbl"]).stdout
    s = json.loads(run(["mlip-sim", "-q", "--config", CONFIG / "mill-3axis-io.ini", "--tools",
                        root / "examples" / "tool.tbl", "--summary", "-",
                        root / "examples" / "demo-io.ngc"]).stdout)
    assert s["pauses"] == 8 and s["violations"] == 0 and s["order_errors"] == 0


def test_cia402_spindle_config_and_sim(tmp_path):
    """[SPINDLE] TYPE = cia402: mlip-config shows the drive; mlip-sim (no
    drive there) says what mlip-rt waits for at each spindle event; an S
    beyond MAX_RPM and M3 without S are refused at their line and column;
    mlip-rt refuses it without the CANopen master."""
    cfg = tmp_path / "sp.ini"
    cfg.write_text((CONFIG / "mill-3axis.ini").read_text()
                   + "\n[SPINDLE]\nTYPE = cia402\nMAX_RPM = 12000\nNODE = 5\n"
                   "COUNTS_PER_REV = 4096\nACCELERATION = 10000\n")
    p = run(["mlip-config", cfg])
    assert ("spindle: CiA 402 drive, node 5, profile velocity, 0..12000 rpm, 4096 counts/rev, "
            "10000 rpm/s, at speed within 240 rpm (timeout 3.4 s") in p.stdout, p.stdout
    prog = tmp_path / "p.ngc"
    prog.write_text("G21 G90\nM3 S6000\nG1 X5 F600\nM2\n")
    p = run(["mlip-sim", "--config", cfg, prog])
    assert ("p.ngc:2: t = 0.000 s, spindle (CiA 402, not simulated): to 6000 rpm: mlip-rt "
            "waits here until it is at speed (0.60 s from rest at ACCELERATION)") in p.stderr
    assert "spindle (CiA 402, not simulated): stop: mlip-rt waits here until it stands still" \
        in p.stderr
    prog.write_text("G21 G90\nG0 X1\nM3 S12001\nM3\n")
    p = run(["mlip-sim", "--config", cfg, prog], check=False)
    assert p.returncode == 1
    assert f"{prog}:3:4: error: S12001 beyond the spindle's MAX_RPM 12000: refused" in p.stderr
    prog.write_text("G21 G90\nM3\n")
    p = run(["mlip-sim", "--config", cfg, prog], check=False)
    assert f"{prog}:2:1: error: M3 with no S: the spindle speed was never set" in p.stderr
    p = run(["mlip-rt", "--config", cfg, "--can", "none"], check=False)
    assert p.returncode == 2 and "TYPE = cia402 needs the CANopen master" in p.stderr, p.stderr


def test_sim_probe_surface(tmp_path):
    """mlip-sim --probe-surface: G38 checked off-line with the machine's
    result. [PROBE] SOURCE = drive: the drives' touch probe latches the
    crossing itself: #5063 is the surface exactly (not a setpoint of the
    1 ms grid); io: the position of the period after the setpoint reached
    it, within a period's travel past it; without a surface G38.2 stops the
    program (exit 5, as mlip-feed); G38.3 goes on (#5070 = 0); mlip-rt
    refuses SOURCE = drive without the CANopen master."""
    base = (CONFIG / "mill-3axis.ini").read_text()
    drv = tmp_path / "drv.ini"
    drv.write_text(base + "\n[PROBE]\nSOURCE = drive\n")
    io = tmp_path / "io.ini"
    io.write_text(base + "\n[IO]\nNODE = 10\nPROBE = 10 0x6000:1 3 HIGH\n")
    prog = tmp_path / "p.ngc"
    prog.write_text("G21 G90\nG0 X1 Y2 Z0\nG38.2 Z-10 F120\nG0 Z5\nM2\n")
    pat = re.compile(r"p\.ngc:3: t = [0-9.]+ s, G38 tripped at X(\S+) Y(\S+) Z(\S+) \(#5070 = 1")
    got = {}
    for name, cfg in (("drive", drv), ("io", io)):
        p = run(["mlip-sim", "--config", cfg, "--probe-surface", "Z=-4.987", prog])
        m = pat.search(p.stderr)
        assert m, p.stderr
        got[name] = [float(v) for v in m.groups()]
        assert "order, contour and end not judged" in p.stderr
    assert got["drive"] == [1.0, 2.0, -4.987], got  # the latch: the crossing itself
    v_t = 120 / 60 * 0.001  # mm a period at the probe's feed
    assert -4.987 - v_t - 1e-9 <= got["io"][2] < -4.987, got  # the period after
    p = run(["mlip-sim", "--config", drv, prog], check=False)
    assert p.returncode == 5 and "G38 probe not tripped (G38.2/G38.4)" in p.stderr, p.stderr
    prog.write_text("G21 G90\nG0 X1 Y2 Z0\nG38.3 Z-10 F120\nG0 Z5\nM2\n")
    p = run(["mlip-sim", "--config", drv, prog])
    assert "G38 not tripped, at X1.000000 Y2.000000 Z-10.000000 (#5070 = 0" in p.stderr
    for bad, why in (("Q=1", "expected AXIS=POS"), ("Z=x", "POS must be a number"),
                     ("Z=1,left", "the side must be below")):
        p = run(["mlip-sim", "--config", drv, "--probe-surface", bad, prog], check=False)
        assert p.returncode == 2 and why in p.stderr, p.stderr
    p = run(["mlip-rt", "--config", drv, "--can", "none"], check=False)
    assert p.returncode == 2 and "[PROBE] SOURCE = drive needs the CANopen master" in p.stderr
    assert f"{drv}: warning: [PROBE] SOURCE = drive without [IO] PROBE" in p.stderr, p.stderr


def test_probe_config_check(tmp_path):
    """mlip-config says where G38's trip comes from, and warns (exit 0: the
    setup is valid) when SOURCE = drive has no probe level mapped: 0x60B9
    has no level, so a probe already on at a G38's start gives no edge;
    mapped (the drive's 0x60FD bit), no warning."""
    base = (CONFIG / "mill-3axis.ini").read_text()
    cfg = tmp_path / "m.ini"
    cases = (
        ("", "probe: none (G38 refused)", False),
        ("\n[IO]\nNODE = 10\nPROBE = 10 0x6000:1 3 HIGH\n",
         "probe: input node 10 0x6000:1 bit 3", False),
        ("\n[PROBE]\nSOURCE = drive\n",
         "probe: the axis drives' touch probe 1 (0x60B8..0x60BB), no level mapped", True),
        ("\n[PROBE]\nSOURCE = drive\n[IO]\nPROBE = 3 0x60FD:0 16 HIGH\n",
         "probe: the axis drives' touch probe 1 (0x60B8..0x60BB), level node 3 0x60FD:0 bit 16",
         False),
    )
    for extra, line, warned in cases:
        cfg.write_text(base + extra)
        p = run(["mlip-config", cfg])
        assert line in p.stdout, p.stdout
        assert (f"{cfg}: warning: [PROBE] SOURCE = drive without [IO] PROBE" in p.stderr) == warned, \
            p.stderr
        if warned:
            assert "gives no edge and nothing stops the move" in p.stderr
