"""Uncompress an x86 bzImage (vmlinuz) into the kernel ELF (vmlinux).

    python3 tools/vcan/extract_vmlinux.py VMLINUZ VMLINUX

QEMU boots the ELF directly through its PVH entry point, which skips the
in-guest decompression (~5 s under software emulation). Handles xz (Debian's
choice) and gzip payloads. Exit code 1 when no ELF kernel is found.
"""

import lzma
import os
import sys
import zlib

FORMATS = (
    (b"\xfd7zXZ\x00", lambda: lzma.LZMADecompressor(lzma.FORMAT_XZ), lzma.LZMAError),
    (b"\x1f\x8b\x08", lambda: zlib.decompressobj(31), zlib.error),
)


def extract(data):
    for magic, make, error in FORMATS:
        off = data.find(magic)
        while off >= 0:
            try:
                elf = make().decompress(data[off:])
            except error:
                elf = b""
            if elf[:4] == b"\x7fELF" and b"Linux version " in elf:
                return elf
            off = data.find(magic, off + 1)
    return None


def main():
    src, dst = sys.argv[1], sys.argv[2]
    with open(src, "rb") as f:
        elf = extract(f.read())
    if elf is None:
        print(f"extract_vmlinux: no kernel ELF found in {src}", file=sys.stderr)
        return 1
    tmp = dst + ".part"
    with open(tmp, "wb") as f:
        f.write(elf)
    os.replace(tmp, dst)
    return 0


if __name__ == "__main__":
    sys.exit(main())
