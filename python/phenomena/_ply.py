"""Read the binary little-endian PLY files phenomena writes (point caches and snow
meshes) into numpy arrays."""

from typing import Dict

import numpy as np

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "<i2", "int16": "<i2", "ushort": "<u2", "uint16": "<u2",
    "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4",
    "float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8",
}


def read_ply(data: bytes) -> Dict[str, Dict[str, np.ndarray]]:
    """Each element of the file (``vertex``, ``face``) as a dict of columns; a face's
    vertex list (triangles only) as an (N, 3) ``vertex_indices`` array."""
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        raise ValueError("not a PLY file")
    header = data[:end].decode("ascii").splitlines()
    if "format binary_little_endian 1.0" not in header:
        raise ValueError("only binary little-endian PLY is read")
    elements = []
    for line in header:
        words = line.split()
        if words[:1] == ["element"]:
            elements.append((words[1], int(words[2]), []))
        elif words[:1] == ["property"]:
            elements[-1][2].append(words[1:])
    offset = end + len(b"end_header\n")
    out = {}
    for name, count, props in elements:
        fields = []
        for p in props:
            if p[0] == "list":
                # phenomena writes triangles only: a count of 3, then three indices.
                fields += [(p[3] + "_count", _TYPES[p[1]]), (p[3], _TYPES[p[2]], (3,))]
            else:
                fields.append((p[1], _TYPES[p[0]]))
        dtype = np.dtype(fields)
        rows = np.frombuffer(data, dtype=dtype, count=count, offset=offset)
        offset += dtype.itemsize * count
        columns = {}
        for field in dtype.names:
            if field.endswith("_count"):
                if count and not np.all(rows[field] == 3):
                    raise ValueError(f"{name}: only triangles are read")
                continue
            columns[field] = np.ascontiguousarray(rows[field])
        out[name] = columns
    return out
