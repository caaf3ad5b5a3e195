"""mlip-latency end to end: short runs of the real loop, idle and under the
real controller tick, whose JSON must be complete (cyclictest's keys plus
ours) and self-consistent (counts add up, min <= p50 <= ... <= max, histogram
plus overflow = samples). No timing bound anywhere: the machines are noisy,
only the logic of the counts is asserted."""
import json
import math
import os
import shutil
import subprocess
import sys

import pytest

from conftest import BUILD, CONFIG, ROOT, TOOLPATHS, run

MILL = CONFIG / "mill-3axis.ini"
DEMO = ROOT / "examples" / "demo.ngc"
PCTS = ["p50", "p99", "p99_9", "p99_99"]
SERIES = ["wakeup_latency", "period_jitter", "compute"]


@pytest.fixture(scope="module", autouse=True)
def latency_built():
    if not (BUILD / "mlip-latency").exists():
        pytest.fail(f"{BUILD / 'mlip-latency'} missing: run make first")


def latency(tmp_path, *args, check=True):
    out = tmp_path / "lat.json"
    p = run(["mlip-latency", "-q", "--json", out, *args], check=check)
    return p, (json.loads(out.read_text()) if out.exists() else None)


def check_series(s, name, hist_us):
    """One series: its statistics in order, its histogram adding up."""
    assert s["unit"] == "us"
    n = s["samples"]
    assert n > 0, name
    chain = [s["min"]] + [s[k] for k in PCTS] + [s["max"]]
    assert chain == sorted(chain), f"{name}: min/percentiles/max out of order: {chain}"
    assert s["min"] <= s["avg"] <= s["max"], name
    assert s["min"] >= 0
    assert s["histogram_us"] == hist_us
    bins = {int(k): v for k, v in s["histogram"].items()}
    assert all(0 <= b < hist_us for b in bins), name
    assert all(v > 0 for v in bins.values()), f"{name}: the histogram lists non-empty bins only"
    assert sum(bins.values()) + s["overflow"] == n, name
    # min and max lie in the first and last bins (or beyond the histogram)
    if bins:
        assert min(bins) == math.floor(s["min"] + 1e-9) or s["overflow"] == n
        if s["overflow"] == 0:
            assert max(bins) == math.floor(s["max"] + 1e-9)
    # percentiles within one bin above the exact value: each is >= the
    # smallest sample whose bin reaches its rank
    cum = 0
    for b in sorted(bins):
        cum += bins[b]
        for k, p in zip(PCTS, [50, 99, 99.9, 99.99]):
            rank = max(1, math.ceil(p / 100 * n - 1e-9))
            if cum >= rank and cum - bins[b] < rank:  # the rank's bin
                assert s[k] == pytest.approx(min(b + 1.0, s["max"]), abs=1e-3), (name, k)


def check_cyclictest_keys(d):
    """What a reader of cyclictest's --json finds (rt-tests 2.4)."""
    for k in ("file_version", "cmdline:", "rt_test_version:", "start_time", "end_time",
              "return_code", "sysinfo", "num_threads", "resolution_in_ns", "thread"):
        assert k in d, k
    assert d["return_code"] == 0
    assert set(d["sysinfo"]) >= {"sysname", "nodename", "release", "version", "machine",
                                 "realtime"}
    assert d["num_threads"] == 1
    t = d["thread"]["0"]
    assert set(t) >= {"histogram", "cycles", "min", "max", "avg", "cpu", "node"}
    assert isinstance(t["min"], int) and isinstance(t["max"], int)
    assert t["min"] <= t["avg"] + 0.01 and t["avg"] <= t["max"] + 1


def check_common(d, mode, hist_us):
    check_cyclictest_keys(d)
    m = d["mlip"]
    assert m["mode"] == mode
    periods = m["periods"]
    t = d["thread"]["0"]
    lat = m["wakeup_latency"]
    # cyclictest's thread 0 is our wake-up latency, in its units (whole us)
    assert t["cycles"] == periods == lat["samples"]
    assert t["min"] == math.floor(lat["min"] + 1e-9)
    assert t["max"] == math.floor(lat["max"] + 1e-9)
    assert t["avg"] == pytest.approx(lat["avg"], abs=0.006)
    assert {int(k): v for k, v in t["histogram"].items()} == \
        {int(k): v for k, v in lat["histogram"].items()}
    assert t["overflow"] == lat["overflow"]
    for k in PCTS:
        assert t[k] == lat[k]
    for name in SERIES:
        check_series(m[name], name, hist_us)
    # one sample per period; jitter needs two wakes
    assert m["compute"]["samples"] == periods
    assert m["period_jitter"]["samples"] == periods - 1
    # overruns: deadlines missed, at least one per overrun period
    assert m["overrun_periods"] <= m["overruns"]
    assert m["overrun_periods"] <= periods
    rt = m["realtime"]
    for k in ("priority", "sched_fifo", "mlockall", "pinned", "kernel", "preempt_rt",
              "isolated_cpus", "warnings"):
        assert k in rt, k
    assert rt["kernel"] == d["sysinfo"]["release"]
    if not rt["preempt_rt"]:
        assert any("PREEMPT_RT" in w for w in rt["warnings"])
    if not rt["isolated_cpus"]:
        assert any("isolated" in w for w in rt["warnings"])
    if rt["priority"] > 0 and not rt["sched_fifo"]:
        assert any("SCHED_FIFO" in w for w in rt["warnings"])
    assert m["summary"].startswith(f"mlip-latency {mode}: wake-up p99 ")
    return m


def test_idle_loops(tmp_path):
    p, d = latency(tmp_path, "--idle", "-l", 700, "-i", 500)
    m = check_common(d, "idle", 10000)
    assert m["periods"] == 700  # -l is exact
    assert m["period_us"] == 500
    assert "send" not in m and "load" not in m
    lines = p.stdout.splitlines()
    assert lines[0].startswith("mlip-latency: idle, 700 periods of 500 us")
    assert lines[-1] == m["summary"]  # the summary line closes the output


def test_idle_duration(tmp_path):
    """-D in cyclictest's forms. The loop stops at the first period whose
    deadline reaches the duration; skipped deadlines are overruns, so the
    periods plus the overruns cover the duration, never fewer."""
    _, d = latency(tmp_path, "-D", "1s", "-i", "1000")
    m = check_common(d, "idle", 10000)
    assert m["duration_s"] == 1.0
    assert m["periods"] <= 1000
    assert m["periods"] + m["overruns"] >= 1000


def test_plan_demo(tmp_path):
    """The real controller tick: blocks taken from the private ring, motion,
    4 cia402 frames (SYNC + 3 RPDOs) encoded every period."""
    _, d = latency(tmp_path, "--plan", DEMO, "--config", MILL, "-l", 1500, "-h", 300)
    m = check_common(d, "plan", 300)
    assert m["periods"] == 1500
    assert m["program"] == str(DEMO)
    load = m["load"]
    assert load["program_blocks"] > 1000
    assert load["blocks_taken"] > 0
    assert 0 < load["moving_periods"] <= m["periods"]
    assert load["encode_faults"] == 0
    assert load["frames_encoded"] == 4 * m["periods"]
    assert "send" not in m


def test_plan_restarts(tmp_path):
    """A short program runs again and again for the whole run: the load is
    counted in periods, so this is exact whatever the machine's noise."""
    prog = tmp_path / "short.ngc"
    prog.write_text("G1 X5 Y0 F6000\nG1 X5 Y5\nG1 X0 Y0\n")
    _, d = latency(tmp_path, "--plan", prog, "-l", 3000)
    m = check_common(d, "plan", 10000)
    load = m["load"]
    assert load["program_blocks"] == 3
    assert load["runs_finished"] >= 3
    # every finished run took its 3 blocks and its END record
    assert load["blocks_taken"] >= 4 * load["runs_finished"]
    assert load["underruns"] == 0  # the feeder keeps the ring full
    assert load["moving_periods"] < m["periods"]  # each run ends at rest


@pytest.mark.skipif(not (TOOLPATHS / "MB-2.3_test.nc").exists(), reason="no MB-2.3")
def test_plan_real_toolpath(tmp_path):
    _, d = latency(tmp_path, "--plan", TOOLPATHS / "MB-2.3_test.nc", "-l", 800)
    m = check_common(d, "plan", 10000)
    assert m["load"]["program_blocks"] > 100000
    # the pre-read fills the 4096-block look-ahead before moving
    assert m["load"]["blocks_taken"] >= 4096


def test_histogram_stdout(tmp_path):
    """-h US: cyclictest's histogram layout on stdout, one column per series,
    agreeing with the JSON."""
    p, d = latency(tmp_path, "--idle", "-l", 400, "-h", 120)
    m = check_common(d, "idle", 120)
    rows = [l for l in p.stdout.splitlines() if l[:1].isdigit()]
    assert len(rows) == 120
    cols = [list(map(int, r.split())) for r in rows]
    assert [c[0] for c in cols] == list(range(120))
    for j, name in enumerate(SERIES, start=1):
        hist = {c[0]: c[j] for c in cols if c[j]}
        assert hist == {int(k): v for k, v in m[name]["histogram"].items()}
    over = next(l for l in p.stdout.splitlines() if l.startswith("# Histogram Overflows:"))
    assert list(map(int, over.split(":")[1].split())) == [m[s]["overflow"] for s in SERIES]
    total = next(l for l in p.stdout.splitlines() if l.startswith("# Total:"))
    assert [int(x) + m[s]["overflow"] for x, s in zip(total.split(":")[1].split(), SERIES)] == \
        [m[s]["samples"] for s in SERIES]


def test_not_realtime_warned(tmp_path):
    p, d = latency(tmp_path, "--idle", "-l", 50, "-p", 0, "--no-mlockall")
    rt = check_common(d, "idle", 10000)["realtime"]
    assert rt["sched_fifo"] is False and rt["mlockall"] is False and rt["priority"] == 0
    assert any("SCHED_OTHER" in w for w in rt["warnings"])
    assert any("not locked" in w for w in rt["warnings"])
    assert "SCHED_OTHER" in p.stderr and "not locked" in p.stderr
    assert "NOT REAL-TIME" in d["mlip"]["summary"]


def test_json_stdout(tmp_path):
    """--json -: the JSON alone on stdout, the results on stderr."""
    p = run(["mlip-latency", "-q", "-l", 30, "--json", "-"])
    d = json.loads(p.stdout)
    check_common(d, "idle", 10000)
    assert "mlip-latency idle: wake-up p99" in p.stderr


@pytest.mark.parametrize("args,code,msg", [
    (["-D", "10x"], 2, "-D/--duration: '10x'"),
    (["-D", "0"], 2, "-D/--duration"),
    (["-i", "50"], 2, "-i/--interval: '50' is not 100..100000 us"),
    (["-p", "120"], 2, "-p/--priority"),
    (["-l", "0"], 2, "-l/--loops"),
    (["-h", "0"], 2, "-h/--histogram"),
    (["-a", "x"], 2, "-a/--affinity"),
    (["--idle", "--plan", "x.ngc"], 2, "--idle is a load of its own"),
    (["--plan", "/nonexistent.ngc", "-l", "5"], 1, "/nonexistent.ngc: No such file"),
    (["--plan", str(DEMO), "--config", "/nonexistent.ini", "-l", "5"], 1, "nonexistent.ini"),
    (["stray"], 2, "unexpected argument 'stray'"),
])
def test_cli_errors(args, code, msg):
    p = run(["mlip-latency", "-q", *args], check=False)
    assert p.returncode == code, p.stderr
    assert msg in p.stderr, p.stderr


def test_bad_program_rejected(tmp_path):
    prog = tmp_path / "bad.ngc"
    prog.write_text("G1 X1 F600\nG1 X1.2.3\n")
    p = run(["mlip-latency", "-q", "--plan", prog, "-l", 5], check=False)
    assert p.returncode == 1
    assert f"{prog}:2:5: error: malformed number" in p.stderr


def test_help():
    p = run(["mlip-latency", "--help"])
    for opt in ("--idle", "--plan", "--can", "--config", "-p,", "-i,", "-D,", "-l,", "-a,", "-m,",
                "-h,", "-q,", "--json", "--compare-cyclictest"):
        assert opt in p.stdout, opt


@pytest.mark.skipif(shutil.which("cyclictest") is None, reason="rt-tests' cyclictest missing")
@pytest.mark.skipif(os.geteuid() != 0, reason="cyclictest -p needs root")
def test_compare_cyclictest(tmp_path):
    p, d = latency(tmp_path, "--idle", "-l", 300, "--compare-cyclictest")
    check_common(d, "idle", 10000)
    ct = d["cyclictest"]
    assert ct["cmdline"].startswith("cyclictest -q -i1000 -p80 -m ")
    assert "-l300" in ct["cmdline"]
    check_cyclictest_keys(ct["json"])
    assert ct["json"]["thread"]["0"]["cycles"] == 300
    s = ct["wakeup_latency"]
    assert s["samples"] == 300
    chain = [s["min"]] + [s[k] for k in PCTS] + [s["max"]]
    assert chain == sorted(chain)
    assert sum(s["histogram"].values()) + s["overflow"] == 300
    table = p.stdout.split("wake-up latency, us (the same loop settings")[1]
    assert "mlip-latency idle" in table and "cyclictest" in table


def test_plot(tmp_path):
    """latency-plot.py: one run, and two side by side, as PNG."""
    pytest.importorskip("matplotlib")
    _, d1 = latency(tmp_path, "--idle", "-l", 200)
    a = tmp_path / "a.json"
    (tmp_path / "lat.json").rename(a)
    _, d2 = latency(tmp_path, "--plan", DEMO, "-l", 200)
    b = tmp_path / "lat.json"
    for args, out in (([a], tmp_path / "one.png"), ([a, b], tmp_path / "two.png")):
        p = subprocess.run([sys.executable, ROOT / "tools" / "latency-plot.py", *args, "-o", out],
                           capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        data = out.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
    # side by side is twice as wide
    import struct
    w1 = struct.unpack(">I", (tmp_path / "one.png").read_bytes()[16:20])[0]
    w2 = struct.unpack(">I", (tmp_path / "two.png").read_bytes()[16:20])[0]
    assert w2 > 1.8 * w1
