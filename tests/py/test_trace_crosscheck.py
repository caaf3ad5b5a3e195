"""The setpoint trace itself: its format, and the C checker's figures redone
independently with numpy from the CSV (so the checker is not trusted blindly)."""
import numpy as np

from conftest import CONFIG, REL, TOOLPATHS, run, sim_summary


def load_trace(path):
    with open(path) as fh:
        header = fh.readline().strip().split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def test_trace_matches_checker(tmp_path):
    f = TOOLPATHS / "flower-spiral-2d.ngc"
    trace = tmp_path / "t.csv"
    opts = ["--accel", "3000,1000", "--vmax", "200", "--feed", "200", "--eps", "0.01"]
    s = sim_summary(f, *opts, "--trace", trace)
    header, d = load_trace(trace)
    assert header == ["t", "x", "y"]
    T = 0.001
    t, x = d[:, 0], d[:, 1:]
    # one row per period from t = 0 to the first sample at rest
    assert len(t) == s["periods"] + 1
    assert np.allclose(np.diff(t), T, rtol=0, atol=1e-9)
    assert t[0] == 0 and np.all(x[0] == 0)
    acc = np.abs(x[2:] - 2 * x[1:-1] + x[:-2]) / T**2
    vel = np.linalg.norm(np.diff(x, axis=0), axis=1) / T
    limits = np.array([3000.0, 1000.0])
    assert np.all(acc.max(axis=0) <= limits * (1 + REL))
    assert np.all(acc.max(axis=0) >= 0.99 * limits)
    assert vel.max() <= 200 * (1 + REL)
    assert np.allclose(acc.max(axis=0), s["max_axis_accel"], rtol=1e-9)
    assert abs(vel.max() - s["max_speed_mm_s"]) <= 1e-6
    # ends at rest on the program's last point (last G1 of the file)
    last = [l for l in open(f) if l.startswith("G1 X")][-1].split()
    end = np.array([float(last[1][1:]), float(last[2][1:])])
    assert np.all(np.abs(x[-1] - end) <= 1e-9)
    assert np.linalg.norm(x[-1] - x[-2]) / T <= 3000 * T  # the last period brakes to 0


def test_mlip_check_agrees_and_fails_on_violation(tmp_path):
    f = TOOLPATHS / "tball-pocket.gcode"
    trace = tmp_path / "t.csv"
    opts = ["--accel", "1000", "--vmax", "200", "--feed", "200"]
    sim_summary(f, *opts, "--trace", trace)
    ok = run(["mlip-check", *opts[:4], f, trace])
    assert "within limits" in ok.stderr
    # the same trace judged against a lower acceleration limit must fail
    bad = run(["mlip-check", "--accel", "900", "--vmax", "200", f, trace], check=False)
    assert bad.returncode == 1 and "acceleration" in bad.stderr
    # and a trace nudged 0.02 mm off the path somewhere must fail on contour
    # alone: limits high enough for the nudge's own acceleration (2 x 0.02 mm
    # / T^2 = 4e4 mm/s^2), yet a machine the config check accepts
    # (|A| T^2 / 8 <= eps: 45000 sqrt(3) 1e-6 / 8 = 0.0097 mm)
    lines = open(trace).read().splitlines()
    i = len(lines) // 2
    cols = lines[i].split(",")
    cols[1] = repr(float(cols[1]) + 0.02)
    cols[2] = repr(float(cols[2]) + 0.02)
    lines[i] = ",".join(cols)
    (tmp_path / "n.csv").write_text("\n".join(lines) + "\n")
    bad = run(["mlip-check", "--accel", "45000", "--vmax", "1e5", f, tmp_path / "n.csv"],
              check=False)
    assert bad.returncode == 1 and "contour" in bad.stderr
    assert "acceleration" not in bad.stderr and "velocity" not in bad.stderr, bad.stderr


def test_rotary_config_trace_header(tmp_path):
    trace = tmp_path / "r.csv"
    s = sim_summary(TOOLPATHS / "4006.nc", "--config", CONFIG / "rotary-4axis.ini",
                    "--ignore-spindle", "--ignore-tools", "--trace", trace)
    header, d = load_trace(trace)
    assert header == ["t", "x", "y", "z", "a"]
    assert s["axes"] == "XYZA"
    assert d.shape[1] == 5 and len(d) == s["periods"] + 1


def test_mlip_check_across_holes(tmp_path):
    """Rows missing from a trace (setpoints lost on a bus): the rows left are
    judged by their own differences, the hole by its mean speed; a hole
    passed over as if it were one period, or a jump the tool could not make
    in the hole's time, fails."""
    f = TOOLPATHS / "tball-pocket.gcode"
    trace = tmp_path / "t.csv"
    opts = ["--accel", "1000", "--vmax", "200", "--feed", "200"]
    sim_summary(f, *opts, "--trace", trace)
    lines = open(trace).read().splitlines()
    head, rows = lines[0], lines[1:]
    n = len(rows)
    # three holes of 40 periods where the tool moves fast
    holes = [range(n // 4, n // 4 + 40), range(n // 2, n // 2 + 40), range(3 * n // 4, 3 * n // 4 + 40)]
    drop = set(i for h in holes for i in h)
    kept = [r for i, r in enumerate(rows) if i not in drop]
    (tmp_path / "h.csv").write_text("\n".join([head] + kept) + "\n")
    ok = run(["mlip-check", *opts[:4], f, tmp_path / "h.csv"], check=False)
    assert ok.returncode == 0, ok.stderr
    # the same rows renumbered one period apart: the holes now read as jumps
    T = 0.001
    renum = [repr(k * T) + r[r.index(","):] for k, r in enumerate(kept)]
    (tmp_path / "r.csv").write_text("\n".join([head] + renum) + "\n")
    bad = run(["mlip-check", *opts[:4], f, tmp_path / "r.csv"], check=False)
    assert bad.returncode == 1 and "acceleration" in bad.stderr
    # a hole one period long that moves the tool 40 periods' worth: too fast
    two = [r for i, r in enumerate(rows) if i not in holes[0] or i == holes[0][-1]]
    k0 = holes[0][0]
    two[k0] = repr(float(rows[k0 - 1].split(",")[0]) + T) + two[k0][two[k0].index(","):]
    (tmp_path / "s.csv").write_text("\n".join([head] + two[:k0 + 1]) + "\n")
    bad = run(["mlip-check", *opts[:4], "--no-end", f, tmp_path / "s.csv"], check=False)
    assert bad.returncode == 1 and "speed" in bad.stderr, bad.stderr
    # time that does not go forward is an input error
    back = [head, rows[0], rows[2], rows[1]]
    (tmp_path / "b.csv").write_text("\n".join(back) + "\n")
    bad = run(["mlip-check", *opts[:4], "--no-end", f, tmp_path / "b.csv"], check=False)
    assert bad.returncode == 2 and "b.csv:4: t" in bad.stderr, bad.stderr
