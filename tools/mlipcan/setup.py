"""The machine INI as the CAN tools need it: axes, CAN nodes, counts per
unit, period, the [CAN] ids and profile. Standard library only (the
emulated test VM pays for every import)."""
import configparser
import math

LETTERS = "XYZABC"


class UsageError(Exception):
    pass


# --------------------------------------------------------------------- config

def parse_int(text, what):
    """Integer as mlip/config.h reads it: decimal digits or 0x hex (a leading 0
    is still decimal)."""
    t = text.strip()
    try:
        if t[:2] in ("0x", "0X"):
            return int(t[2:], 16)
        if not t.isdigit():
            raise ValueError
        return int(t, 10)
    except ValueError:
        raise UsageError(f"{what}: '{text}' is not an integer (decimal or 0x hex)")


def parse_num(text, what):
    try:
        v = float(text)
    except ValueError:
        raise UsageError(f"{what}: '{text}' is not a number")
    if not math.isfinite(v):
        raise UsageError(f"{what}: '{text}' is not finite")
    return v


class Setup:
    """What the listener needs of the machine: axes, nodes, counts, ids."""

    def __init__(self):
        self.axes = list("XYZ")
        self.nodes = [1, 2, 3]
        self.cpu = [1000.0] * 3
        self.period_s = 0.001
        self.profile = "cia402"
        self.bitrate = 1000000
        self.data_bitrate = 5000000
        self.sync_id = 0x080
        self.rpdo_base = 0x200
        self.packed_base = 0x300
        self.fd_id = 0x400
        self.status_id = 0x180
        self.drives = False      # [DRIVES] ENABLE: CiA 402 bring-up, 6-byte RPDOs
        self.master_node = 127   # [DRIVES] MASTER_NODE (heartbeat 0x700 + it)
        self.source = "defaults (X Y Z, nodes 1..3, 1000 counts/unit)"

    @classmethod
    def from_ini(cls, path):
        s = cls()
        cp = configparser.ConfigParser(inline_comment_prefixes=("#", ";"),
                                       comment_prefixes=("#", ";"),
                                       interpolation=None, strict=True)
        cp.optionxform = str  # keys are case-sensitive upper case
        try:
            with open(path, encoding="utf-8-sig") as fh:
                cp.read_file(fh)
        except (OSError, configparser.Error) as e:
            raise UsageError(f"{path}: {e}")
        if not cp.has_option("TRAJ", "COORDINATES"):
            raise UsageError(f"{path}: no [TRAJ] COORDINATES")
        axes = cp.get("TRAJ", "COORDINATES").split()
        if not 1 <= len(axes) <= 6 or any(a not in LETTERS for a in axes) or \
                len(set(axes)) != len(axes):
            raise UsageError(f"{path}: COORDINATES '{' '.join(axes)}' is not 1..6 distinct of XYZABC")
        s.axes = axes
        s.nodes, s.cpu = [], []
        for i, a in enumerate(axes):
            sec = "AXIS_" + a
            if not cp.has_section(sec):
                raise UsageError(f"{path}: no [{sec}]")
            s.nodes.append(parse_int(cp.get(sec, "CAN_NODE", fallback=str(i + 1)),
                                     f"{path}: [{sec}] CAN_NODE"))
            c = parse_num(cp.get(sec, "COUNTS_PER_UNIT", fallback="1000"),
                          f"{path}: [{sec}] COUNTS_PER_UNIT")
            if not c > 0:
                raise UsageError(f"{path}: [{sec}] COUNTS_PER_UNIT must be > 0")
            s.cpu.append(c)
        s.period_s = parse_num(cp.get("TRAJ", "PERIOD", fallback="0.001"), f"{path}: PERIOD")
        if cp.has_section("CAN"):
            g = lambda k, d: cp.get("CAN", k, fallback=d)
            s.profile = g("PROFILE", "cia402")
            s.bitrate = parse_int(g("BITRATE", "1000000"), f"{path}: [CAN] BITRATE")
            s.data_bitrate = parse_int(g("DATA_BITRATE", "5000000"), f"{path}: [CAN] DATA_BITRATE")
            for key in ("SYNC_ID", "RPDO_BASE", "PACKED_BASE", "FD_ID", "STATUS_ID"):
                setattr(s, key.lower(), parse_int(g(key, hex(getattr(s, key.lower()))),
                                                  f"{path}: [CAN] {key}"))
        if cp.has_section("DRIVES"):
            en = parse_int(cp.get("DRIVES", "ENABLE", fallback="0"), f"{path}: [DRIVES] ENABLE")
            if en not in (0, 1):
                raise UsageError(f"{path}: [DRIVES] ENABLE must be 0 or 1")
            s.drives = bool(en)
            s.master_node = parse_int(cp.get("DRIVES", "MASTER_NODE", fallback="127"),
                                      f"{path}: [DRIVES] MASTER_NODE")
        if len(set(s.nodes)) != len(s.nodes) or any(not 1 <= n <= 127 for n in s.nodes):
            raise UsageError(f"{path}: CAN_NODEs must be distinct, 1..127: {s.nodes}")
        s.source = str(path)
        return s
