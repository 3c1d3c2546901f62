#!/usr/bin/python3
"""Read a .vdb with OpenVDB's own Python module and compare it with expectations.

Usage: /usr/bin/python3 check.py FILE.vdb FILE.json [FILE.vdb FILE.json ...]

Run it with Debian's /usr/bin/python3 (package python3-openvdb, module pyopenvdb,
OpenVDB 10), not a pyenv python. The JSON (written by crates/core/examples/vdb_sample.rs)
holds the file metadata and, per grid: name, type, class, active voxel count, min and
max, bounding box, voxel size, the world position of one index, probe voxels, metadata,
and optionally a dump of every active voxel (little-endian int32 x, y, z then the
value's float32 components) compared voxel by voxel. Anything OpenVDB prints while
reading (a warning, say) is a failure too. Exits 1 with a message on the first file
that differs, 0 when all match.
"""

import json
import math
import os
import struct
import sys
import tempfile

import pyopenvdb as vdb


class Mismatch(Exception):
    pass


def f32(x):
    """x rounded to float32, as the file stores it."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def same_value(got, want):
    """Values as float32: a number or a 3-tuple."""
    if isinstance(want, list):
        return len(got) == len(want) and all(f32(g) == f32(w) for g, w in zip(got, want))
    return f32(got) == f32(want)


def close(a, b, tol):
    return all(abs(x - y) <= tol * max(1.0, abs(y)) for x, y in zip(a, b))


def expect(cond, what):
    if not cond:
        raise Mismatch(what)


class Captured:
    """Everything written to file descriptors 1 and 2 (OpenVDB logs warnings through
    log4cplus to standard output) while the block runs; the text is in `.text`."""

    def __enter__(self):
        sys.stdout.flush()
        sys.stderr.flush()
        self.file = tempfile.TemporaryFile(mode="w+b")
        self.saved = [os.dup(1), os.dup(2)]
        os.dup2(self.file.fileno(), 1)
        os.dup2(self.file.fileno(), 2)
        return self

    def __exit__(self, *exc):
        sys.stdout.flush()
        sys.stderr.flush()
        for fd, saved in zip((1, 2), self.saved):
            os.dup2(saved, fd)
            os.close(saved)
        self.file.seek(0)
        self.text = self.file.read().decode(errors="replace")
        self.file.close()
        return False


def check_meta(got, want, where):
    for key, value in want.items():
        expect(key in got, f"{where}: metadata {key!r} missing (has {sorted(got)})")
        g = got[key]
        if isinstance(value, float):
            ok = isinstance(g, float) and f32(g) == f32(value)
        elif isinstance(value, list):
            ok = list(g) == value
        else:
            ok = g == value
        expect(ok, f"{where}: metadata {key!r} is {g!r}, expected {value!r}")


def check_dump(grid, path, components, where):
    record = struct.Struct("<3i%df" % components)
    with open(path, "rb") as f:
        data = f.read()
    expect(len(data) % record.size == 0, f"{where}: dump {path} is not whole records")
    want = {}
    for x, y, z, *v in record.iter_unpack(data):
        want[(x, y, z)] = v
    seen = 0
    for item in grid.iterOnValues():
        expect(item.count == 1 and item.min == item.max, f"{where}: a tile at {item.min}, expected only voxels")
        ijk = tuple(item.min)
        value = item.value if components > 1 else [item.value]
        expect(ijk in want, f"{where}: active voxel {ijk} = {value} is not in the dump")
        expect(same_value(list(value), want[ijk]), f"{where}: voxel {ijk} is {value}, expected {want[ijk]}")
        seen += 1
    expect(seen == len(want), f"{where}: {seen} active voxels read, the dump has {len(want)}")
    return seen


def check_grid(grid, e, folder, where):
    expect(grid.valueTypeName == e["type"], f"{where}: type {grid.valueTypeName}, expected {e['type']}")
    expect(grid.gridClass == e["class"], f"{where}: class {grid.gridClass!r}, expected {e['class']!r}")
    count = grid.activeVoxelCount()
    expect(count == e["active_voxel_count"], f"{where}: {count} active voxels, expected {e['active_voxel_count']}")
    lo, hi = grid.evalMinMax()
    expect(same_value(lo, e["min"]), f"{where}: min {lo}, expected {e['min']}")
    expect(same_value(hi, e["max"]), f"{where}: max {hi}, expected {e['max']}")
    if e["bbox"] is not None:
        bbox = [list(c) for c in grid.evalActiveVoxelBoundingBox()]
        expect(bbox == e["bbox"], f"{where}: bounding box {bbox}, expected {e['bbox']}")
    size = grid.transform.voxelSize()
    expect(close(size, [e["voxel_size"]] * 3, 1e-12), f"{where}: voxel size {size}, expected {e['voxel_size']}")
    index = e["index_to_world"]["index"]
    world = grid.transform.indexToWorld(tuple(index))
    want = e["index_to_world"]["world"]
    expect(close(world, want, 1e-12), f"{where}: index {index} is at {world}, expected {want}")
    acc = grid.getConstAccessor()
    for p in e["probes"]:
        ijk = tuple(p["ijk"])
        value = acc.getValue(ijk)
        expect(same_value(value, p["value"]), f"{where}: voxel {ijk} is {value}, expected {p['value']}")
        on = acc.isValueOn(ijk)
        expect(on == p["active"], f"{where}: voxel {ijk} active {on}, expected {p['active']}")
    meta = grid.metadata
    want_keys = set(e["metadata"]) | {"name", "class", "file_mem_bytes"}
    expect(set(meta) == want_keys, f"{where}: metadata keys {sorted(meta)}, expected {sorted(want_keys)}")
    check_meta(meta, dict(e["metadata"], name=e["name"], **{"class": e["class"]}), where)
    seen = None
    if "dump" in e:
        components = 1 if e["type"] == "float" else 3
        seen = check_dump(grid, os.path.join(folder, e["dump"]), components, where)
    # Every leaf buffer has been read now: OpenVDB's own memory count should be the one
    # the writer recorded.
    if seen is not None or count <= 1:
        if count == 1:
            acc.getValue(tuple(e["bbox"][0]))
        mem = grid.memUsage()
        expect(mem == meta["file_mem_bytes"], f"{where}: memUsage {mem}, file_mem_bytes {meta['file_mem_bytes']}")
    return count, seen


def check_file(vdb_path, json_path):
    with open(json_path) as f:
        e = json.load(f)
    folder = os.path.dirname(json_path)
    grids, metadata = vdb.readAll(vdb_path)
    name = os.path.basename(vdb_path)
    expect(dict(metadata) == e["file_metadata"], f"{name}: file metadata {metadata}, expected {e['file_metadata']}")
    expect(len(grids) == len(e["grids"]), f"{name}: {len(grids)} grids, expected {len(e['grids'])}")
    by_name = {}
    for g in grids:
        expect(g.name not in by_name, f"{name}: two grids named {g.name!r}")
        by_name[g.name] = g
    lines = []
    for ge in e["grids"]:
        where = f"{name}:{ge['name']}"
        expect(ge["name"] in by_name, f"{where}: no such grid (has {sorted(by_name)})")
        count, seen = check_grid(by_name[ge["name"]], ge, folder, where)
        compared = f", all {seen} values compared" if seen is not None else ""
        lines.append(f"  {ge['name']} ({ge['type']}, {ge['class']}): {count} active voxels{compared}")
    return lines


def main(args):
    if len(args) == 0 or len(args) % 2:
        sys.exit(__doc__)
    vdb.setLoggingLevel("warn")
    print(f"pyopenvdb {'.'.join(map(str, vdb.LIBRARY_VERSION))}, file format {vdb.FILE_FORMAT_VERSION}")
    for vdb_path, json_path in zip(args[::2], args[1::2]):
        # Leaf buffers load when first touched, so OpenVDB may print at any point of the
        # check: all of it runs captured.
        failure = None
        with Captured() as out:
            try:
                lines = check_file(vdb_path, json_path)
            except Mismatch as m:
                failure = str(m)
            except Exception as ex:  # OpenVDB's exceptions: the file does not parse
                failure = f"{os.path.basename(vdb_path)}: {type(ex).__name__}: {ex}"
        if failure is None and out.text.strip():
            failure = f"{os.path.basename(vdb_path)}: OpenVDB printed while reading:\n{out.text}"
        if failure is not None:
            print(f"FAIL {failure}", file=sys.stderr)
            sys.exit(1)
        print(f"ok {os.path.basename(vdb_path)}")
        for line in lines:
            print(line)


if __name__ == "__main__":
    main(sys.argv[1:])
