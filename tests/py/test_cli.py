"""The simulator as a user meets it: bad input is rejected as a whole, with
messages naming file, line and column, and nothing moves; options and
outputs behave as documented."""
import json
import os

import pytest

from conftest import CONFIG, ROOT, TOOLPATHS, run

MILL = CONFIG / "mill-3axis.ini"

# (program text, expected "line:col: error: ..." fragment)
BAD = {
    "malformed number": ("G1 X1.2.3 F600\n", ":1:5: error: malformed number '1.2.3'"),
    "unknown word": ("G1 X1 F600\nG1 E5\n", ":2:4: error: unknown word letter E"),
    "unsupported code": ("G41 D1\nG1 X1 F600\n", ":1:1: error: unsupported G code G41"),
    "inconsistent arc": ("G1 X10 Y0 F600\nG2 X0 Y10 I-10 J5\n",
                         ":2:1: error: arc radius to start"),
    "soft limit": ("G1 X1200 F600\n", ":1:4: error: X 1200.000 beyond soft limit 1000.000"),
    "nan": ("G1 Xnan F600\n", ":1:5: error: malformed number 'nan'"),
    "line too long": ("G1 X1 F600 (" + "x" * 300 + ")\n", ":1:257: error: line too long"),
    "missing feed": ("G1 X1 Y1\n", ":1:1: error: missing feed"),
    "non-UTF-8": ("G1 X1 F600 \xe9\n", ":1:12: error: non-ASCII byte 0xE9"),
    "empty program": ("(nothing)\n%\n", ":2: error: empty program"),
    "Grbl jog without F": ("$J=G91 X10\nG1 X1 F600\n", ":1:1: error: Grbl jog without F"),
    "G4 without P": ("G1 X1 F600\nG4\n", ":2:1: error: G4 without P"),
    "G10 without L2/L20": ("G10 L1 P1 Z5\nG1 X1 F600\n",
                           ":1:5: error: G10 without L2 or L20"),
    "G93 move without F": ("G1 X1 F600\nG93 G1 X2\n", ":2:5: error: G93 inverse time"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_program_rejected(tmp_path, case):
    text, want = BAD[case]
    prog = tmp_path / "bad.ngc"
    prog.write_bytes(text.encode("latin-1"))
    trace = tmp_path / "trace.csv"
    p = run(["mlip-sim", "--config", MILL, "--trace", trace, prog], check=False)
    assert p.returncode == 1
    assert f"{prog}{want}" in p.stderr, p.stderr
    assert p.stderr.rstrip().endswith("1 error, program rejected: nothing was run")
    assert not trace.exists()  # a rejected program never starts moving


def test_all_errors_listed(tmp_path):
    prog = tmp_path / "bad.ngc"
    prog.write_text("G1 X1 F600\nG1 X1.2.3\nG1 X2\nG41\nG1 X3000\n")
    p = run(["mlip-sim", "--config", MILL, prog], check=False)
    assert p.returncode == 1
    errors = [l for l in p.stderr.splitlines() if ": error: " in l]
    assert [e.split(":")[1] for e in errors] == ["2", "4", "5"]
    assert "3 errors, program rejected" in p.stderr


def test_bad_config(tmp_path):
    cfg = tmp_path / "m.ini"
    cfg.write_text(MILL.read_text().replace("MAX_ACCELERATION", "MAX_ACCEL", 1))
    p = run(["mlip-sim", "--config", cfg, ROOT / "examples" / "demo.ngc"], check=False)
    assert p.returncode == 1
    assert "error: unknown key MAX_ACCEL in [AXIS_X] (did you mean MAX_ACCELERATION?)" in p.stderr
    assert f"{cfg}:" in p.stderr
    cfg.write_text(MILL.read_text().replace("MAX_ACCELERATION = 1000", "MAX_ACCELERATION = -5", 1))
    p = run(["mlip-sim", "--config", cfg, ROOT / "examples" / "demo.ngc"], check=False)
    assert p.returncode == 1 and "MAX_ACCELERATION must be > 0, got -5" in p.stderr


@pytest.mark.parametrize("opts,msg", [
    (["--strategy", "fast"], "not one of mpct, bisector, stop"),
    (["--accel", "0"], "--accel"),
    (["--accel", "1000,1000"], "2 values for 3 axes"),
    (["--vmax", "-1"], "--vmax"),
    (["--override", "250"], "above 200"),
    (["--lookahead", "1000"], "power of two"),
])
def test_bad_options(opts, msg):
    p = run(["mlip-sim", *opts, ROOT / "examples" / "demo.ngc"], check=False)
    assert p.returncode != 0 and msg in p.stderr, p.stderr


def test_summary_fields_and_feed_option(tmp_path):
    demo = ROOT / "examples" / "demo.ngc"
    s = json.loads(run(["mlip-sim", "-q", "--config", MILL, "--summary", "-", demo]).stdout)
    for key in ("total_time_s", "blocks", "segments", "path_length_mm", "max_speed_mm_s",
                "max_axis_accel", "max_contour_error_mm", "strategy"):
        assert key in s
    assert len(s["max_axis_accel"]) == 3 and s["strategy"] == "mpct"
    slow = json.loads(run(["mlip-sim", "-q", "--config", MILL, "--feed", "20", "--summary", "-",
                           demo]).stdout)
    assert slow["max_speed_mm_s"] <= 20 * (1 + 1e-9)
    assert slow["total_time_s"] > 2 * s["total_time_s"]


def test_axes_from_file_without_config(tmp_path):
    prog = tmp_path / "xz.ngc"
    prog.write_text("G1 X1 Z-1 F600\nX2 Z0\n")
    trace = tmp_path / "t.csv"
    run(["mlip-sim", "-q", "--trace", trace, prog])
    assert trace.read_text().splitlines()[0] == "t,x,z"


def test_lookahead_depth_matters():
    """A shallow look-ahead cannot see far enough to brake from full speed:
    the same program takes longer, and stays within the limits."""
    f = TOOLPATHS / "flower-spiral-2d.ngc"
    deep = json.loads(run(["mlip-sim", "-q", "--accel", "1000", "--feed", "200", "--summary", "-",
                           f]).stdout)
    shallow = json.loads(run(["mlip-sim", "-q", "--accel", "1000", "--feed", "200",
                              "--lookahead", "16", "--summary", "-", f]).stdout)
    assert shallow["total_time_s"] > 1.05 * deep["total_time_s"]
    assert max(shallow["max_axis_accel"]) <= 1000 * (1 + 1e-9)


def test_summary_names_any_file(tmp_path):
    """The summary's "file" is the program's path as given, whatever bytes it
    holds (quotes, a backslash, a newline, a byte that is not UTF-8): the
    JSON parses, and the path comes back byte for byte (os.fsencode of the
    decoded string, Python's surrogateescape)."""
    name = b'a "quoted"\\ name\nwith \xff and \xc3\xa9.ngc'
    prog = tmp_path.joinpath(os.fsdecode(name))
    prog.write_text("G1 X1 Y2 F600\n")
    summary = tmp_path / "s.json"
    run(["mlip-sim", "-q", "--config", MILL, "--summary", summary, prog])
    d = json.loads(summary.read_text(encoding="utf-8"))
    assert os.fsencode(d["file"]) == os.fsencode(prog)
    assert d["violations"] == 0 and d["blocks"] == 1
