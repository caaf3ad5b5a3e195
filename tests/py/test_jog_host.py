"""The continuous jog (issue 18) on this host (mlip-rt --can none), judged on
the setpoints mlip-rt recorded (--record): mlip-ctl jog at speed, released
(SECONDS elapsed) and killed (its renewals stop: the controller's dead-man
stops it), each stop at the acceleration limit; a jog toward a soft limit
stops exactly at it and one beyond it is refused (Grbl's error 15); bad
arguments are refused before anything moves."""
import signal
import subprocess

from conftest import CONFIG, Proc, status, tool, wait_for

MILL = CONFIG / "mill-3axis.ini"
A = 1000.0  # mm/s^2, every axis of mill-3axis


def ctl(shm, *args, **kw):
    return subprocess.run([tool("mlip-ctl"), "--shm", shm, *map(str, args)], capture_output=True,
                          text=True, **kw)


T = 0.001  # s, mill-3axis' period


def records(path, k):
    """(t, position of axis k) per period the controller ran: its time is
    the controller's (period count x T), not the deadline's, since a late
    wake-up on this non-real-time host leaves a hole in the deadlines, not
    in the motion."""
    out = []
    for line in path.read_text().splitlines():
        f = line.split(",")
        try:
            out.append((len(out) * T, float(f[1 + k])))
        except ValueError:
            continue  # a header
    return out


def kinematics(rows):
    """Speeds and accelerations between recorded periods (holes skipped)."""
    v = []
    for (t0, x0), (t1, x1) in zip(rows, rows[1:]):
        v.append(((t1 + t0) / 2, (x1 - x0) / (t1 - t0)))
    a = [(v1 - v0) / (t1 - t0) for (t0, v0), (t1, v1) in zip(v, v[1:])]
    return v, a


def stop_distance(rows, v_jog):
    """From the last period at the jog's speed to rest."""
    v, _ = kinematics(rows)
    last = max(i for i, (_, s) in enumerate(v) if abs(abs(s) - v_jog) < 1e-6)
    return abs(rows[-1][1] - rows[last + 1][1])


def test_jog_released(controller, tmp_path):
    rec = tmp_path / "rt.csv"
    shm, rt = controller(MILL, "--record", rec)
    p = ctl(shm, "jog", "X+", 6000, 0.5, timeout=60)  # 100 mm/s for 0.5 s
    assert p.returncode == 0, p.stderr
    assert "jog X+: at rest at X" in p.stdout and "jog released" in p.stdout, p.stdout
    st = status(shm)
    assert st["state"] == "idle" and st["reason"] == "jog released", st
    rt.send_signal(signal.SIGTERM)
    rt.communicate(timeout=20)
    rows = records(rec, 0)
    v, a = kinematics(rows)
    assert max(abs(s) for _, s in v) <= 100.0 * (1 + 1e-9)
    assert max(abs(x) for x in a) <= A * (1 + 1e-6)
    d, want = stop_distance(rows, 100.0), 100.0 ** 2 / (2 * A)
    print(f"\n[jog] released at 100 mm/s: {d:.4f} mm to rest, v^2/2A = {want:.4f} mm")
    assert want * 0.999 <= d <= want * 1.03
    assert abs(st["stop_mm"] - d) < 1e-3


def test_jog_client_killed(controller, tmp_path):
    """mlip-ctl jog killed (SIGKILL: no release): the controller stops it by
    itself MLIP_JOG_DEADMAN_S (250 ms) after the last renewal, at the
    acceleration limit."""
    rec = tmp_path / "rt.csv"
    shm, rt = controller(MILL, "--record", rec)
    j = Proc([tool("mlip-ctl"), "--shm", shm, "jog", "Y-", "3000"],
             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # at the jog's speed (3000 mm/min) before the kill: the stop then brakes from it
    assert wait_for(lambda: (lambda s: s.get("state") == "jog" and s["speed_mm_s"] >= 50.0 *
                             (1 - 1e-9))(status(shm) or {}), 60), status(shm)
    j.kill()
    j.wait(10)
    y_kill = status(shm)["position"]["Y"]
    st = wait_for(lambda: (lambda s: s if s["state"] == "idle" else None)(status(shm)), 60)
    assert st and st["reason"] == "jog not renewed", st
    rt.send_signal(signal.SIGTERM)
    rt.communicate(timeout=20)
    rows = records(rec, 1)
    _, a = kinematics(rows)
    assert max(abs(x) for x in a) <= A * (1 + 1e-6)
    d, want = stop_distance(rows, 50.0), 50.0 ** 2 / (2 * A)
    travel = y_kill - st["position"]["Y"]
    # after the kill: at most the dead-man (0.25 s) plus a renewal interval
    # (0.1 s) and this status read's latency at 50 mm/s, then the braking
    print(f"\n[jog] client killed at 50 mm/s: {d:.4f} mm to rest (v^2/2A = {want:.4f} mm), "
          f"{travel:.3f} mm after the kill")
    assert want * 0.999 <= d <= want * 1.05
    assert 0 < travel <= 50.0 * (0.25 + 0.1 + 0.15) + want


def test_jog_soft_limit(controller, tmp_path):
    ini = tmp_path / "m.ini"
    ini.write_text(MILL.read_text().replace("MAX_LIMIT = 500", "MAX_LIMIT = 5", 1))
    shm, rt = controller(ini)
    p = ctl(shm, "jog", "Z+", 1200, 30, timeout=60)
    assert p.returncode == 0, p.stderr
    st = status(shm)
    assert st["reason"] == "jog at the soft limit" and st["position"]["Z"] == 5.0, st
    p = ctl(shm, "jog", "Z+", 1200, timeout=60)
    assert p.returncode == 1, p.stdout
    assert "at or beyond its soft limit MAX_LIMIT 5" in p.stderr and "error 15" in p.stderr
    assert status(shm)["position"]["Z"] == 5.0


def test_jog_bad_arguments(controller):
    shm, rt = controller(MILL)
    for args, msg in ((("Q+", 100), "'Q+' is not an axis of this machine"),
                      (("X", 100), "'X' is not an axis"),
                      (("X+", 0), "the speed must be a number of mm/min"),
                      (("X+", "nan"), "the speed must be a number of mm/min"),
                      (("X+", 100, -1), "SECONDS must be in (0, 86400]")):
        p = ctl(shm, "jog", *args)
        assert p.returncode == 2 and msg in p.stderr, (args, p.stderr)
    assert status(shm)["position"] == {"X": 0.0, "Y": 0.0, "Z": 0.0}


def rows3(path):
    """(t, x, y, z) per recorded period, on the controller's time."""
    out = []
    for line in path.read_text().splitlines()[1:]:
        f = line.split(",")
        out.append((len(out) * T, *map(float, f[1:4])))
    return out


def limits_of(rows):
    """The largest path speed and per-axis |acceleration| of the rows."""
    vs = [[(b[k] - a[k]) / T for k in (1, 2, 3)] for a, b in zip(rows, rows[1:])]
    amax = max(abs(w[k] - v[k]) / T for v, w in zip(vs, vs[1:]) for k in range(3))
    return max(sum(c * c for c in v) ** 0.5 for v in vs), amax


def test_jog_incremental(controller, tmp_path):
    """X+1.5 Y-2.5 at 1200 mm/min: one line, at rest exactly at its target
    (reason "jog done"), within the speed and the acceleration limit."""
    rec = tmp_path / "rt.csv"
    shm, rt = controller(MILL, "--record", rec)
    p = ctl(shm, "jog", "X+1.5", "Y-2.5", 1200, timeout=60)
    assert p.returncode == 0, p.stderr
    assert "at rest at X 1.5000 Y -2.5000 (jog done)" in p.stdout, p.stdout
    st = status(shm)
    assert st["reason"] == "jog done" and st["position"] == {"X": 1.5, "Y": -2.5, "Z": 0.0}, st
    rt.terminate()
    rt.communicate(timeout=20)
    rows = rows3(rec)
    assert rows[-1][1:] == (1.5, -2.5, 0.0), rows[-1]
    v, a = limits_of(rows)
    print(f"\n[jog] X+1.5 Y-2.5 at 20 mm/s: peak {v:.6f} mm/s, peak |a| {a:.3f} mm/s^2")
    assert 20.0 * 0.99 <= v <= 20.0 * (1 + 1e-9)
    assert a <= A * (1 + 1e-6)
    for y0, y1 in zip(rows, rows[1:]):  # one straight line: Y = -5/3 X throughout
        assert abs(y1[2] + y1[1] * 2.5 / 1.5) < 1e-9, y1


def test_jog_incremental_soft_limit(controller, tmp_path):
    """A target beyond the soft limit is refused whole (Grbl's error 15),
    nothing moves; one that reaches it exactly runs."""
    ini = tmp_path / "m.ini"
    ini.write_text(MILL.read_text().replace("MAX_LIMIT = 500", "MAX_LIMIT = 5", 1))
    shm, rt = controller(ini)
    p = ctl(shm, "jog", "Z+", "--distance", 6, 600, timeout=60)
    assert p.returncode == 1, p.stdout
    assert "beyond its soft limit MAX_LIMIT 5" in p.stderr and "error 15" in p.stderr, p.stderr
    assert "the target Z 6.0000; nothing moved" in p.stderr, p.stderr
    assert status(shm)["position"]["Z"] == 0.0
    p = ctl(shm, "jog", "Z+5", 1200, timeout=60)
    assert p.returncode == 0, p.stderr
    assert status(shm)["position"]["Z"] == 5.0
    for args, msg in ((("X+1", "Y+", 100), "every axis a distance"),
                      (("X+", "X-", 100), "axis X given twice"),
                      (("X+0", 100), "'X+0' is not an axis"),
                      (("X+", "--distance", "-1", 100), "--distance must be a positive"),
                      (("X+2000", 100), "a distance is 0.001 .. 1048.58")):
        p = ctl(shm, "jog", *args)
        assert p.returncode == 2 and msg in p.stderr, (args, p.stderr)
    assert status(shm)["position"] == {"X": 0.0, "Y": 0.0, "Z": 5.0}


def test_jog_several_axes(controller, tmp_path):
    """Z+ Y- continuously at 1200 mm/min: along one line at 20 mm/s, until
    the first axis (Z, MAX_LIMIT 5) stops exactly at its soft limit."""
    rec = tmp_path / "rt.csv"
    ini = tmp_path / "m.ini"
    ini.write_text(MILL.read_text().replace("MAX_LIMIT = 500", "MAX_LIMIT = 5", 1))
    shm, rt = controller(ini, "--record", rec)
    p = ctl(shm, "jog", "Z+", "Y-", 1200, 30, timeout=60)
    assert p.returncode == 0, p.stderr
    st = status(shm)
    assert st["reason"] == "jog at the soft limit", st
    assert st["position"] == {"X": 0.0, "Y": -5.0, "Z": 5.0}, st
    rt.terminate()
    rt.communicate(timeout=20)
    rows = rows3(rec)
    v, a = limits_of(rows)
    print(f"\n[jog] Z+ Y- at 20 mm/s to Z's limit: peak {v:.6f} mm/s, peak |a| {a:.3f}")
    assert 20.0 * 0.99 <= v <= 20.0 * (1 + 1e-9)
    assert a <= A * (1 + 1e-6)
    assert rows[-1][1:] == (0.0, -5.0, 5.0)


def test_jog_status(controller):
    """Status shows the jog in progress, every axis with its direction."""
    shm, rt = controller(MILL)
    j = Proc([tool("mlip-ctl"), "--shm", shm, "jog", "X+", "Y-", "600", "30"],
             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        st = wait_for(lambda: (lambda s: s if s["state"] == "jog" else None)(status(shm)), 60)
        assert st and st["jog"] == "X+ Y-", st
        text = ctl(shm, "status").stdout
        assert "jog         X+ Y-" in text, text
    finally:
        j.terminate()
        j.wait(20)
    st = wait_for(lambda: (lambda s: s if s["state"] == "idle" else None)(status(shm)), 60)
    assert st and st["jog"] is None, st
    assert st["position"]["X"] > 0 and st["position"]["Y"] == -st["position"]["X"], st
