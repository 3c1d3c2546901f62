#!/usr/bin/python3
"""Compare our .vdb with OpenVDB's rewrite of it (rewrite.cpp), byte for byte.

Usage: compare.py OURS.vdb OPENVDB.vdb

Equal must be: the header before the UUID (magic, format, library version, offsets
flag), the file metadata, each grid's type, compression flags and metadata (OpenVDB adds
`file_delayed_load`, a temporary `__delayedload` entry its reader drops; we write none),
and every byte of its transform, topology and leaf buffers. Grids are matched by name
(OpenVDB writes them back in name order). Exits 1 on the first difference.
"""

import struct
import sys


def parse(path):
    b = open(path, "rb").read()
    at = 57  # header: 8 + 4 + 4 + 4 + 1 bytes, then the 36-character UUID

    def u32():
        nonlocal at
        v = struct.unpack_from("<I", b, at)[0]
        at += 4
        return v

    def string():
        nonlocal at
        n = u32()
        v = b[at : at + n]
        at += n
        return v

    def metamap():
        return dict((string(), (string(), string())) for _ in range(u32()))

    file_meta = metamap()
    grids = {}
    for _ in range(u32()):
        name, typ, _parent = string(), string(), string()
        grid, block, end = struct.unpack_from("<qqq", b, at)
        at += 24
        if grid != at:
            sys.exit(f"{path}: grid {name!r} starts at {at}, its descriptor says {grid}")
        flags = u32()
        meta = metamap()
        meta.pop(b"file_delayed_load", None)
        grids[name] = (typ, flags, meta, b[at:end], block - at)
        at = end
    if at != len(b):
        sys.exit(f"{path}: {len(b) - at} bytes after the last grid")
    return b[:21], file_meta, grids


def main(ours, theirs):
    h1, f1, g1 = parse(ours)
    h2, f2, g2 = parse(theirs)
    fail = lambda what: sys.exit(f"FAIL {ours}: {what}")
    if h1 != h2:
        fail(f"header {h1.hex()} vs OpenVDB's {h2.hex()}")
    if f1 != f2:
        fail(f"file metadata {f1} vs OpenVDB's {f2}")
    if set(g1) != set(g2):
        fail(f"grids {sorted(g1)} vs OpenVDB's {sorted(g2)}")
    for name, a in g1.items():
        b = g2[name]
        label = name.decode(errors="replace")
        for what, x, y in [("type", a[0], b[0]), ("compression", a[1], b[1]), ("metadata", a[2], b[2])]:
            if x != y:
                fail(f"grid {label}: {what} {x} vs OpenVDB's {y}")
        if a[3] != b[3]:
            k = next(i for i, (p, q) in enumerate(zip(a[3], b[3])) if p != q) if len(a[3]) == len(b[3]) else None
            fail(f"grid {label}: transform and tree differ ({len(a[3])} vs {len(b[3])} bytes, first at {k})")
        print(f"  {label}: metadata and {len(a[3])} bytes of transform, topology and buffers identical")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
