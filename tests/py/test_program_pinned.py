"""A program is pinned for the whole run (issue 17, item 4), through the
real mlip-rt (--can none, --record), mlip-feed and mlip-sim: a program
rewritten in place after its check (the same length, X900 for an X in
100..149; or `cp other.ngc`, the same block count) never moves the machine
to what was not checked: the stream ends at the first chunk that differs,
the machine stops at rest at the end of the last block sent, and mlip-feed
says "the file changed after it was checked" (mlip-sim's second reader:
tests/unit/test_program_pin.c)."""
import subprocess

from conftest import CONFIG, Proc, status, tool, wait_for

MILL = CONFIG / "mill-3axis.ini"
LINE = 12  # bytes of each "X1xx.xxx Y0\n"


def write_program(path, n, x900_at=None):
    with open(path, "w") as f:
        f.write("G1 F6000 X1\n")
        for k in range(1, n):
            f.write("X%07.3f Y0\n" % (900.0 if k + 1 == x900_at else 100.0 + k * 0.008))


def rewrite_line(path, line, text):
    with open(path, "r+b") as f:
        f.seek((line - 1) * LINE)
        f.write(text.encode())


def started_feeder(shm, prog):
    """mlip-feed at 1000 blocks/s, once it has checked the program (its note
    on the offsets ends the check): the first chunk's 5461 blocks take it
    5.5 s, so the second chunk is read seconds after this returns."""
    f = Proc([tool("mlip-feed"), "--shm", shm, "--rate", "1000", str(prog)],
             stderr=subprocess.PIPE, text=True)
    checked = lambda: "mlip-feed: offsets:" in f.said()  # noqa: E731
    assert wait_for(lambda: checked() or f.poll() is not None, 60) and checked(), f.said()
    return f


def recorded_x(rec):
    rows = rec.read_text().splitlines()[1:]
    return [float(r.split(",")[1]) for r in rows]


def test_program_rewritten_while_it_streams(controller, tmp_path):
    """Observed on main: line 752 of an 800-line program rewritten to X900
    after the check: the machine reached X 899.7, mlip-feed exited 0. Here
    6000 lines (72 kB, two chunks) sent at 1000 blocks/s, line 5800 (in the
    second chunk, not read yet) rewritten to X900.000: the machine never
    passes X 149, stops at rest, mlip-feed exits 1 with the message."""
    prog = tmp_path / "p.ngc"
    write_program(prog, 6000)
    rec = tmp_path / "rt.csv"
    shm, rt = controller(MILL, "--record", rec)
    f = started_feeder(shm, prog)
    rewrite_line(prog, 5800, "X900.000 Y0\n")
    s = status(shm)
    # the second chunk begins in line 5462: still far ahead of what was sent
    assert s["blocks_consumed"] + s["queued"] < 5000, s
    err = f.communicate(timeout=120)[1]
    assert f.returncode == 1, err
    assert f"{prog}: the file changed after it was checked (bytes 65536 to 71999 differ " \
           "from the ones checked, line 5462): the rest is not run; the machine stops at " \
           "rest after block 5461: continue with --start-seq 5462" in err, err
    assert "program complete" not in err
    s = wait_for(lambda: (lambda s: s if s["speed_mm_s"] == 0.0 and s["state"] in
                          ("starved", "idle") else None)(status(shm)), 30)
    assert s and s["exec_seq"] == 5461, s  # the last line wholly in the verified chunk
    rt.terminate()
    rt.communicate(timeout=20)
    xs = recorded_x(rec)
    assert max(xs) <= 100.0 + 5461 * 0.008 + 1e-9, max(xs)  # never X900


def test_copy_over_the_program_while_it_streams(controller, tmp_path):
    """`cp other.ngc prog.ngc` (the same block count, one X900 in it) while
    the first chunk runs: refused at the second chunk, the same way."""
    prog = tmp_path / "p.ngc"
    other = tmp_path / "other.ngc"
    write_program(prog, 6000)
    write_program(other, 6000, x900_at=5900)
    shm, rt = controller(MILL)
    f = started_feeder(shm, prog)
    subprocess.run(["cp", str(other), str(prog)], check=True)
    s = status(shm)
    assert s["blocks_consumed"] + s["queued"] < 5000, s
    err = f.communicate(timeout=120)[1]
    assert f.returncode == 1 and "the file changed after it was checked" in err, err
    s = wait_for(lambda: (lambda s: s if s["speed_mm_s"] == 0.0 and s["state"] in
                          ("starved", "idle") else None)(status(shm)), 30)
    assert s and s["position"]["X"] < 149.0, s
