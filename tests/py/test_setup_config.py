"""The listener's Setup (mlipcan.config) takes the machine from the C
reader (mlip-config --json): the same values for every shipped config and for
[CAN] / [DRIVES] sections, and the C reader's file:line:col error for a file
it refuses, with no second INI parser in the Python tools."""
import contextlib
import io
import json
import re

import pytest

from conftest import BUILD, CONFIG, ROOT, S, run
from mlipcan import demo_drives, listen
from mlipcan.config import Setup, UsageError


def c_reader(path):
    return json.loads(run(["mlip-config", "--json", path]).stdout)


def assert_same(s, js):
    m, can = js["machine"], js["can"]
    assert s.axes == list(m["coordinates"])
    assert s.nodes == [a["can_node"] for a in m["axes"]]
    assert s.cpu == [a["counts_per_unit"] for a in m["axes"]]
    assert s.period_s == m["period"]
    for key in ("profile", "bitrate", "data_bitrate", "sync_id", "rpdo_base", "packed_base",
                "fd_id", "status_id"):
        assert getattr(s, key) == can[key], key
    assert s.drives == js["drives"]["enable"]
    assert s.master_node == js["drives"]["master_node"]


@pytest.mark.parametrize("ini", sorted(p.name for p in CONFIG.glob("*.ini")))
def test_setup_equals_mlip_config(ini):
    assert_same(Setup.from_ini(CONFIG / ini, BUILD), c_reader(CONFIG / ini))


def test_can_and_drives_sections(tmp_path):
    """Values away from every default, so a key the JSON lost (or Setup did
    not take) shows; hex, decimal and inline comments as config.h allows."""
    text = (CONFIG / "mill-3axis.ini").read_text()
    text = re.sub(r"(?m)^CAN_NODE = 3$", "CAN_NODE = 9", text)
    text = re.sub(r"(?m)^PERIOD = .*$", "PERIOD = 0.002   # s", text)
    for key, val in (("PROFILE", "packed"), ("BITRATE", "500000"), ("DATA_BITRATE", "2000000"),
                     ("SYNC_ID", "0x081"), ("RPDO_BASE", "0x210"), ("PACKED_BASE", "0x320"),
                     ("FD_ID", "1100"), ("STATUS_ID", "0x190 ; status")):
        text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {val}", text)
        assert n == 1, key
    text += "\n[DRIVES]\nENABLE = 1\nMASTER_NODE = 100\nHEARTBEAT_MS = 50\n"
    cfg = tmp_path / "can-drives.ini"
    cfg.write_text(text)
    js = c_reader(cfg)
    s = Setup.from_ini(cfg, BUILD)
    assert_same(s, js)
    assert js["drives"]["heartbeat_ms"] == 50 and js["drives"]["heartbeat_timeout_ms"] == 300
    assert (s.nodes, s.period_s, s.profile, s.bitrate, s.data_bitrate) == \
        ([1, 2, 9], 0.002, "packed", 500000, 2000000)
    assert (s.sync_id, s.rpdo_base, s.packed_base, s.fd_id, s.status_id) == \
        (0x81, 0x210, 0x320, 1100, 0x190)
    assert (s.drives, s.master_node, s.source) == (True, 100, str(cfg))
    assert Setup.from_ini(CONFIG / "mill-3axis.ini", BUILD).drives is False


def test_invalid_config_gives_the_c_readers_error(tmp_path):
    """PACKED_BASE 0x17F puts packed frame 1 on the STATUS_ID: the Python
    reader this replaces accepted it; now Setup and the listener's CLI report
    the C reader's file:line:col error (exit 2), as mlip-config does."""
    text = (CONFIG / "mill-3axis.ini").read_text()
    text = text.replace("PROFILE = cia402", "PROFILE = packed")
    text = text.replace("PACKED_BASE = 0x300", "PACKED_BASE = 0x17F")
    cfg = tmp_path / "bad.ini"
    cfg.write_text(text)
    # the error names the line of one of the two colliding keys
    lines = "|".join(str(i) for i, ln in enumerate(text.splitlines(), 1)
                     if ln.startswith(("PACKED_BASE", "STATUS_ID")))
    c = run(["mlip-config", "--json", cfg], check=False)
    assert c.returncode == 1 and c.stdout == ""
    want = rf"{re.escape(str(cfg))}:({lines}):1: error: PACKED_BASE 0x17F .*STATUS_ID"
    assert re.match(want, c.stderr), c.stderr
    with pytest.raises(UsageError) as e:
        Setup.from_ini(cfg, BUILD)
    assert str(e.value) == c.stderr.strip()
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = listen.main(["--check-layout", "--config", str(cfg), "--dbc-cache", ""], settings=S)
    assert rc == 2 and re.search(want, err.getvalue()), err.getvalue()


def test_no_python_ini_parser_in_the_tools():
    for p in list((ROOT / "tools").rglob("*.py")) + list((ROOT / "python").rglob("*.py")):
        assert "configparser" not in p.read_text(), p


def test_drive_machine_and_the_demos_copy(tmp_path):
    """config/mill-3axis-drives.ini (docs/cia402.md: the starting point for a
    real machine) has [DRIVES] on and a 2 ms period; the drives stage of make demo
    (mlipcan.demo_drives) runs it at 40 ms, where mlip-config refuses
    the full accelerations (eq. 17: |A| T^2 / 8 > eps) and accepts the
    lowered ones, which keep |A| T^2 / 8 within eps but not far below it."""
    js = c_reader(CONFIG / "mill-3axis-drives.ini")
    assert js["drives"]["enable"] is True and js["machine"]["period"] == 0.002
    assert [a["can_node"] for a in js["machine"]["axes"]] == [1, 2, 3]
    full = re.sub(r"(?m)^PERIOD = .*$", "PERIOD = 0.04",
                  (CONFIG / "mill-3axis-drives.ini").read_text())
    (tmp_path / "full.ini").write_text(full)
    p = run(["mlip-config", "--json", tmp_path / "full.ini"], check=False)
    assert p.returncode != 0 and "is too long for CONTOUR_TOLERANCE" in p.stderr, p.stderr
    text, accel, dev = demo_drives.demo_machine(S, CONFIG / "mill-3axis-drives.ini", 0.04)
    (tmp_path / "demo.ini").write_text(text)
    m = c_reader(tmp_path / "demo.ini")["machine"]
    assert m["period"] == 0.04
    assert [a["max_acceleration"] for a in m["axes"]] == [accel] * 3
    eps = m["contour_tolerance"]
    assert 0.5 * eps < dev <= eps, dev
    assert abs(dev - (3 ** 0.5) * accel * 0.04 ** 2 / 8) < 1e-12
