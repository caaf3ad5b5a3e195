#!/usr/bin/env python3
"""seeds.py - the seed corpora of the two fuzz targets (called by fuzz/run.sh).

    seeds.py TOOLPATHS_DIR GCODE_OUT CONFIG_OUT

G-code: every toolpath (and examples/demo.ngc) cut at line boundaries into
chunks of at most CHUNK bytes; the first chunk (the preamble) and up to
PER_FILE - 1 others spread evenly over the file. Each seed starts with the
selector byte of fuzz_gcode.c: 0x02 (mill, initial feed as the tools use it),
0x03 for a file that moves an A axis, and for each first chunk also 0x00 (no
initial feed) and 0x0E (the sink refuses every 3rd block). Plus fuzz/regress/*.
Config: config/*.ini, mutated variants of them, fuzz/regress/*, and one raw
struct mlip_machine (the 0xFF mode of fuzz_config.c). Only the standard
library; file names are stable so that a rerun overwrites, never duplicates.
"""
import os
import re
import struct
import sys

CHUNK = 4000
PER_FILE = 32
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def chunks(data):
    out, cur = [], b""
    for line in data.splitlines(keepends=True):
        if cur and len(cur) + len(line) > CHUNK:
            out.append(cur)
            cur = b""
        cur += line[:CHUNK]
    if cur:
        out.append(cur)
    return out


def uses_a(data):
    text = re.sub(rb"\([^)\n]*\)|;[^\n]*", b"", data)
    return re.search(rb"(?<![A-Za-z])[Aa]\s*[-+.0-9]", text) is not None


def write(d, name, data):
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def gcode_seeds(toolpaths, out):
    files = []
    if toolpaths and os.path.isdir(toolpaths):
        # every program below the folder (senders/ holds the senders' jobs)
        for d, subdirs, names in sorted(os.walk(toolpaths)):
            subdirs.sort()
            files += [os.path.join(d, n) for n in sorted(names)
                      if not n.endswith((".md", ".txt"))]
    files.append(os.path.join(ROOT, "examples", "demo.ngc"))
    n = 0
    for path in files:
        with open(path, "rb") as f:
            data = f.read()
        base = re.sub(r"[^A-Za-z0-9.-]", "_", os.path.basename(path))
        sel = 0x03 if uses_a(data) else 0x02
        cs = chunks(data)
        step = max(1, len(cs) // PER_FILE)
        picked = sorted(set([0] + list(range(0, len(cs), step))[:PER_FILE - 1]))
        for k in picked:
            write(out, "seed-%s-%04d" % (base, k), bytes([sel]) + cs[k])
            n += 1
        write(out, "seed-%s-nofeed" % base, bytes([sel & 1]) + cs[0])
        write(out, "seed-%s-refuse" % base, bytes([0x0C | 0x02 | (sel & 1)]) + cs[0])
        n += 2
    n += regress_seeds(out, [b"\x02", b"\x03"])
    return n


def regress_seeds(out, prefixes):
    d = os.path.join(ROOT, "fuzz", "regress")
    n = 0
    for name in sorted(os.listdir(d)) if os.path.isdir(d) else []:
        with open(os.path.join(d, name), "rb") as f:
            data = f.read()
        for p in prefixes:
            write(out, "regress-%s-%s" % (name, p.hex()), p + data)
            n += 1
    return n


def mutations(text):
    """Variants that walk the reader's less travelled paths."""
    lines = text.split(b"\n")
    yield "crlf", text.replace(b"\n", b"\r\n")
    yield "bom", b"\xef\xbb\xbf" + text
    yield "tabs", text.replace(b" = ", b"\t=\t")
    yield "nocomments", b"\n".join(l.split(b"#")[0].rstrip() for l in lines
                                     if not l.lstrip().startswith((b"#", b";")))
    yield "reversed", b"\n".join(reversed(lines))
    yield "nonl", text.rstrip(b"\n")
    for k, l in enumerate(lines):
        if b"=" in l and not l.lstrip().startswith(b"#"):
            yield "del%02d" % k, b"\n".join(lines[:k] + lines[k + 1:])
    values = [b"1e308", b"-0", b"1e-320", b"0x7FF", b"00012", b"+.5", b"5.", b"1e309", b"0",
              b"-1", b"9" * 40, b"nan", b"200mm", b"4096"]
    keyed = [k for k, l in enumerate(lines) if b"=" in l and not l.lstrip().startswith(b"#")]
    for j, k in enumerate(keyed):
        key = lines[k].split(b"=")[0]
        v = values[j % len(values)]
        yield "val%02d" % k, b"\n".join(lines[:k] + [key + b"= " + v] + lines[k + 1:])
    yield "dupkey", b"\n".join(lines + [lines[keyed[-1]]]) if keyed else text
    yield "lowerkey", text.replace(b"MAX_VELOCITY", b"max_velocity", 1)


def raw_machine():
    """The 0xFF mode: struct mlip_machine of the 3-axis mill, x86-64 layout."""
    axis = b""
    for i, (letter, lo, hi) in enumerate([(b"X", -1000, 1000), (b"Y", -1000, 1000),
                                          (b"Z", -500, 500)]):
        axis += struct.pack("<c3xi5di4xd", letter, 0, 1000.0, 200.0, lo, hi, 0.0, i + 1,
                            1000.0)
    axis += bytes(64 * 3)
    return b"\xff" + struct.pack("<i4x", 3) + axis + struct.pack("<4d", 200.0, 360.0, 0.01,
                                                                   0.001)


def config_seeds(out):
    d = os.path.join(ROOT, "config")
    n = 0
    for name in sorted(os.listdir(d)):
        if not name.endswith(".ini"):
            continue
        with open(os.path.join(d, name), "rb") as f:
            text = f.read()
        base = name[:-4]
        write(out, "seed-%s" % base, text)
        n += 1
        for tag, data in mutations(text):
            write(out, "seed-%s-%s" % (base, tag), data)
            n += 1
    write(out, "seed-raw-machine", raw_machine())
    return n + 1 + regress_seeds(out, [b""])


def main():
    toolpaths, gout, cout = sys.argv[1:4]
    os.makedirs(gout, exist_ok=True)
    os.makedirs(cout, exist_ok=True)
    ng = gcode_seeds(toolpaths, gout)
    nc = config_seeds(cout)
    print("seeds: %d G-code, %d config" % (ng, nc))


if __name__ == "__main__":
    main()
