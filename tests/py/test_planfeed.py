"""mlip-rt's planning thread for [TRAJ] JERK_PLAN = path, on this host
(tools/lib/planfeed.h, bench/bench_planfeed.c): a producer thread runs the
plan's controller (smooth without J, eps less the band) on the records
mlip-feed would send, the streaming plan, and fills the planned queue
(mlip/motion/planq.h); the main thread pops it a period at a time.

When the thread keeps up, the setpoints are `mlip-sim --config CFG
--strategy smooth` with JERK_PLAN = path in CFG, byte for byte: the
controller sees mlip-sim's records in every period, and the plan's
compaction does not depend on the consumer. Paced by a 1 ms clock
(SCHED_OTHER), the same unless the queue ran dry (then the period brakes:
not seen on this host; the figures are printed)."""
import json
import math
import re
import subprocess

import pytest

from conftest import BUILD, CONFIG, TOOLPATHS
from test_pathfeeds import two_feeds

SQUARE = "G21 G90\nG1 F12000\nG1 X20\nG1 Y20\nG1 X0\nG1 Y0\n"


def machine(tmp_path):
    ini = (CONFIG / "mill-3axis.ini").read_text()
    for a in "XYZ":
        ini = ini.replace(f"[AXIS_{a}]\n", f"[AXIS_{a}]\nMAX_JERK = 100000\n")
    f = tmp_path / "mill-path.ini"
    f.write_text(ini.replace("[TRAJ]\n", "[TRAJ]\nJERK_PLAN = path\n"))
    return f


def one_feed(src, n, dst, feed=6000):
    """The first n lines of a CAM file, every G0 a G1 and one F."""
    lines = src.read_text().splitlines()[:n]
    out = [re.sub(r"F[0-9.]+", "", re.sub(r"\bG0\b", "G1", ln)) for ln in lines]
    dst.write_text("\n".join(out[:2] + [f"G1 F{feed}"] + out[2:]) + "\n")
    return dst


def fast_machine(tmp_path):
    """600 mm/s: smooth's setpoints 0.6 mm apart, the window's look-ahead
    (~460 mm) near a stop's length: where the compaction's dependence on
    the period's lag (docs/algorithm.md) would show first."""
    ini = machine(tmp_path).read_text().replace("MAX_LINEAR_VELOCITY = 200",
                                                "MAX_LINEAR_VELOCITY = 600")
    f = tmp_path / "mill-path-fast.ini"
    f.write_text(re.sub(r"MAX_VELOCITY = [0-9.]+", "MAX_VELOCITY = 600", ini))
    return f


def programs(tmp_path):
    cfg = machine(tmp_path)
    sq = tmp_path / "square.ngc"
    sq.write_text(SQUARE)
    yield cfg, sq, 200.0
    mb = TOOLPATHS / "MB-2.3_test.nc"
    if mb.exists():
        yield cfg, one_feed(mb, 400, tmp_path / "mb23-400.ngc"), 100.0
    if mb.exists():
        # its own F words (2000, 1684, 1676 mm/min) and a G0 (94 mm at
        # the machine's 200 mm/s): each block under its own cap
        own = tmp_path / "mb23-own.ngc"
        own.write_text("".join(mb.read_text().splitlines(keepends=True)[:400]))
        yield cfg, own, 200.0
    two = tmp_path / "two-feeds.ngc"
    two_feeds(two)
    yield cfg, two, 50.0
    fast = tmp_path / "fast.ngc"
    fast.write_text("G21 G90\nG1 F36000\nG1 X300\nG1 X300 Y300\nG1 X0 Y0\n")
    yield fast_machine(tmp_path), fast, 600.0


def bench(cfg, prog, trace, *extra):
    p = subprocess.run([str(BUILD / "bench_planfeed"), "--config", str(cfg), "--trace",
                        str(trace), *extra, str(prog)], capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)


def test_queue_equals_mlip_sim(tmp_path):
    n = 0
    for cfg, prog, cap in programs(tmp_path):
        ref = tmp_path / f"{prog.stem}-sim.csv"
        p = subprocess.run([str(BUILD / "mlip-sim"), "-q", "--config", str(cfg), "--strategy",
                            "smooth", "--trace", str(ref), "--summary", "-", str(prog)],
                           capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, p.stderr
        summ = json.loads(p.stdout)
        assert summ["violations"] == 0 and "path_window_peak" in summ, summ  # the plan ran
        # the program's one F is the cap (0.995 of it planned), and used
        assert 0.5 * cap < summ["max_speed_mm_s"] <= cap, summ["max_speed_mm_s"]
        got = tmp_path / f"{prog.stem}-q.csv"
        r = bench(cfg, prog, got)
        assert r["periods"] == r["planned"] == summ["periods"] and r["brakes"] == 0, r
        assert got.read_bytes() == ref.read_bytes(), prog
        paced = tmp_path / f"{prog.stem}-paced.csv"
        r = bench(cfg, prog, paced, "--paced")
        print(f"\n{prog.name}: {summ['periods']} periods; thread CPU per planned period "
              f"median {r['cpu_us_per_planned']['median']} us p99 "
              f"{r['cpu_us_per_planned']['p99']} us; paced queue low-water "
              f"{r['queue_low_water']} of 256, brakes {r['brakes']}")
        if r["brakes"] == 0:
            assert paced.read_bytes() == ref.read_bytes(), prog
        n += 1
    assert n >= 2


@pytest.mark.parametrize("body,line,what", [("G1 X20\nG4 P0.5\nG1 Y20\n", 4, "a dwell (G4)"),
                                            ("G1 X20\nG61\nG1 Y20\n", 5,
                                             "an exact stop (G61 or a canned cycle)")])
def test_refused_before_the_thread(tmp_path, body, line, what):
    prog = tmp_path / "p.ngc"
    prog.write_text("G21 G90\nG1 F12000\n" + body)
    p = subprocess.run([str(BUILD / "bench_planfeed"), "--config", str(machine(tmp_path)),
                        str(prog)], capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and f"p.ngc:{line}: {what}" in p.stderr, p.stderr


def test_refused_after_the_start(tmp_path):
    """A plan refused after its start (a 2 ms machine: a 10 mm line, then
    a zigzag of 0.3 mm turning 150 degrees: at its first corner a piece's
    sag and its knots' fairing moves reach 0.0024 mm against the band's
    0.002, P6) ends the bench with the refusal
    mlip-sim gives (its period waited for an entry for ever before), and
    mlip-sim's message states the bound the band is held to. (A circle of
    2 degree steps was refused so until smooth ran for the plan at band /
    T^2, tools/lib/simpath.c.)"""
    cfg = tmp_path / "mill-path-2ms.ini"
    cfg.write_text(machine(tmp_path).read_text().replace("PERIOD = 0.001", "PERIOD = 0.002"))
    prog = tmp_path / "zigzag.ngc"
    pts, ang = [(10.0, 0.0)], 0.0
    for k in range(20):
        ang += math.radians(150.0) * (1 if k % 2 == 0 else -1)
        pts.append((pts[-1][0] + 0.3 * math.cos(ang), pts[-1][1] + 0.3 * math.sin(ang)))
    prog.write_text("G21 G90\nG1 F6000\nG1 X10 Y0\n"
                    + "".join(f"G1 X{x:.4f} Y{y:.4f}\n" for x, y in pts[1:]))
    s = subprocess.run([str(BUILD / "mlip-sim"), "--config", str(cfg), "--strategy", "smooth",
                        str(prog)], capture_output=True, text=True, timeout=120)
    m = re.search(r"\(P6\), its sag and its knots' fairing moves together at [0-9.]+ mm of the path "
                  r"\(([0-9.]+) mm, the band ([0-9.]+) mm\)", s.stderr)
    assert s.returncode == 1 and m and float(m[1]) > float(m[2]), s.stderr
    p = subprocess.run([str(BUILD / "bench_planfeed"), "--config", str(cfg), str(prog)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 1 and "more than the band (P6)" in p.stderr, p.stderr
