"""Blender as the real client of phenomena's outputs: import a flame OpenVDB
frame as a volume object and render it with Cycles (the image must not be black), a
flame PLY particle cache as a point mesh, and a snow GLB, checking what was imported
against the files themselves (grid names, vertex counts, bounds); and, when given, a
flame VDB with the air around it, whose `velocity` grid Blender must take as the grid
it motion-blurs the volume by.

Run with Debian's Blender 3.4, headless:
  blender -b --python-exit-code 1 --python tools/blender-check/check.py -- \
      FLAME.vdb FLAME.ply SNOW.glb OUT_DIR [AIR_FLAME.vdb]
Exits non-zero (through --python-exit-code) on the first failed check.
"""

import json
import math
import os
import struct
import sys

import numpy

# Blender 3.4's glTF importer still calls numpy.bool, which Debian's numpy 1.24 removed.
if "bool" not in numpy.__dict__:
    numpy.bool = bool

import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402


def fail(message):
    print(f"FAIL {message}", file=sys.stderr)
    raise SystemExit(1)


def expect(cond, message):
    if not cond:
        fail(message)


def clear_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def world_bounds(objects):
    lo = Vector((math.inf,) * 3)
    hi = Vector((-math.inf,) * 3)
    for o in objects:
        for corner in o.bound_box:
            w = o.matrix_world @ Vector(corner)
            lo = Vector(map(min, lo, w))
            hi = Vector(map(max, hi, w))
    return lo, hi


def close(a, b, tol):
    return all(abs(x - y) <= tol for x, y in zip(a, b))


def check_volume(path, out_dir):
    """Import the VDB, check its grids, render it with Cycles: not black."""
    clear_scene()
    manifest = json.load(open(path + ".json"))
    bpy.ops.object.volume_import(filepath=path, align="WORLD", location=(0, 0, 0))
    vols = [o for o in bpy.context.scene.objects if o.type == "VOLUME"]
    expect(len(vols) == 1, f"{path}: {len(vols)} volume objects imported")
    vol = vols[0]
    grids = vol.data.grids
    expect(grids.load(), f"{path}: Blender could not load the grids: {grids.error_message}")
    names = sorted(g.name for g in grids)
    want = sorted(g["name"] for g in manifest["grids"])
    expect(names == want, f"{path}: grids {names}, expected {want}")
    # Blender bounds a volume by its tree's leaves (8 voxels a side): the bounds must
    # hold the manifest's voxel bounding box and exceed it by less than a leaf.
    lo, hi = world_bounds([vol])
    size = manifest["grids"][0]["voxel_size_m"]
    blo = [min(g["bbox"][0][a] for g in manifest["grids"]) * size for a in range(3)]
    bhi = [max(g["bbox"][1][a] for g in manifest["grids"]) * size for a in range(3)]
    holds = all(lo[a] <= blo[a] + size and hi[a] >= bhi[a] - size for a in range(3))
    tight = close(lo, blo, 9 * size) and close(hi, bhi, 9 * size)
    expect(holds and tight, f"{path}: bounds {lo} {hi}, voxels span {blo} {bhi}")

    # An emissive volume: density from `density`, emission colour from `emission`.
    mat = bpy.data.materials.new("flame")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    pv = nodes.new("ShaderNodeVolumePrincipled")
    pv.inputs["Density Attribute"].default_value = "density"
    emission = nodes.new("ShaderNodeAttribute")
    emission.attribute_name = "emission"
    links.new(emission.outputs["Color"], pv.inputs["Emission Color"])
    pv.inputs["Emission Strength"].default_value = 20.0
    links.new(pv.outputs["Volume"], out.inputs["Volume"])
    vol.data.materials.append(mat)

    # A camera looking at the volume's centre from its front (Blender is z up; the
    # flame's y, up in the file, is Blender's y here, as the VDB has no axis change).
    centre = (lo + hi) / 2
    extent = max(hi - lo)
    cam_data = bpy.data.cameras.new("cam")
    cam = bpy.data.objects.new("cam", cam_data)
    bpy.context.scene.collection.objects.link(cam)
    cam.location = centre + Vector((0, 0, 2.5 * extent))
    direction = centre - cam.location
    cam.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene = bpy.context.scene
    scene.camera = cam
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    scene.render.resolution_x, scene.render.resolution_y = 160, 160
    scene.render.image_settings.file_format = "PNG"
    image_path = os.path.join(out_dir, "blender-flame-vdb.png")
    scene.render.filepath = image_path
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(image_path)
    pixels = numpy.array(img.pixels[:]).reshape(-1, 4)
    brightest = float(pixels[:, :3].max())
    lit = int((pixels[:, :3].max(axis=1) > 0.05).sum())
    expect(brightest > 0.2 and lit > 50, f"{path}: the Cycles render is black (max {brightest}, {lit} lit pixels)")
    return f"volume {os.path.basename(path)}: grids {names}, Cycles render max {brightest:.2f}, {lit} lit pixels"


def read_ply(path):
    """The vertex count and the x, y, z columns of a binary little-endian PLY."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().splitlines()
    count = next(int(l.split()[2]) for l in header if l.startswith("element vertex"))
    props = [l.split() for l in header if l.startswith("property")]
    fmt = {"float": "f4", "uint": "u4"}
    dtype = numpy.dtype([(p[2], "<" + fmt[p[1]]) for p in props])
    rows = numpy.frombuffer(data, dtype=dtype, count=count, offset=end)
    return count, numpy.stack([rows["x"], rows["y"], rows["z"]], axis=1)


def check_points(path):
    clear_scene()
    count, xyz = read_ply(path)
    bpy.ops.import_mesh.ply(filepath=path)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    expect(len(meshes) == 1, f"{path}: {len(meshes)} meshes imported")
    mesh = meshes[0].data
    expect(len(mesh.vertices) == count, f"{path}: {len(mesh.vertices)} vertices imported, the file has {count}")
    co = numpy.zeros(count * 3)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    expect(numpy.allclose(co.min(axis=0), xyz.min(axis=0), atol=1e-6), f"{path}: bounds {co.min(axis=0)} vs {xyz.min(axis=0)}")
    expect(numpy.allclose(co.max(axis=0), xyz.max(axis=0), atol=1e-6), f"{path}: bounds {co.max(axis=0)} vs {xyz.max(axis=0)}")
    return f"points {os.path.basename(path)}: {count} vertices, bounds as in the file"


def glb_positions(path):
    """Vertex count and bounds of every POSITION accessor of a GLB (its JSON chunk)."""
    with open(path, "rb") as f:
        data = f.read()
    length = struct.unpack_from("<I", data, 12)[0]
    gltf = json.loads(data[20 : 20 + length])
    count, lo, hi = 0, [math.inf] * 3, [-math.inf] * 3
    for mesh in gltf["meshes"]:
        for prim in mesh["primitives"]:
            acc = gltf["accessors"][prim["attributes"]["POSITION"]]
            count += acc["count"]
            lo = [min(a, b) for a, b in zip(lo, acc["min"])]
            hi = [max(a, b) for a, b in zip(hi, acc["max"])]
    return count, lo, hi


def check_mesh(path):
    clear_scene()
    count, lo, hi = glb_positions(path)
    bpy.ops.import_scene.gltf(filepath=path)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    expect(meshes, f"{path}: no mesh imported")
    verts = sum(len(o.data.vertices) for o in meshes)
    # Blender merges nothing on import (merge_vertices is off): the same vertices.
    expect(verts == count, f"{path}: {verts} vertices imported, the file has {count}")
    blo, bhi = world_bounds(meshes)
    # glTF is y up, Blender z up: (x, y, z) becomes (x, -z, y).
    want_lo = [lo[0], -hi[2], lo[1]]
    want_hi = [hi[0], -lo[2], hi[1]]
    expect(close(blo, want_lo, 1e-4) and close(bhi, want_hi, 1e-4), f"{path}: bounds {blo} {bhi}, file {want_lo} {want_hi}")
    return f"mesh {os.path.basename(path)}: {len(meshes)} object(s), {verts} vertices, bounds as in the file"


def check_velocity(path):
    """Import a VDB of the flame with the air around it: Blender finds its `velocity`
    grid (named in the manifest) as a three-channel vector grid, loads it, and takes it
    as the grid it motion-blurs the volume by."""
    clear_scene()
    manifest = json.load(open(path + ".json"))
    want = next((g for g in manifest["grids"] if g["name"] == "velocity"), None)
    expect(want is not None, f"{path}: the manifest has no velocity grid")
    bpy.ops.object.volume_import(filepath=path, align="WORLD", location=(0, 0, 0))
    vol = [o for o in bpy.context.scene.objects if o.type == "VOLUME"][0]
    grids = vol.data.grids
    expect(grids.load(), f"{path}: Blender could not load the grids: {grids.error_message}")
    velocity = next((g for g in grids if g.name == "velocity"), None)
    expect(velocity is not None, f"{path}: Blender found no velocity grid in {[g.name for g in grids]}")
    expect(velocity.data_type == "VECTOR_FLOAT" and velocity.channels == 3, f"{path}: velocity is {velocity.data_type}")
    expect(vol.data.velocity_grid == "velocity", f"{path}: Blender's velocity grid is {vol.data.velocity_grid!r}")
    expect(velocity.load(), f"{path}: Blender could not load the velocity grid")
    return f"volume {os.path.basename(path)}: velocity grid {velocity.data_type}, Blender's motion-blur grid"


def main():
    args = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    if len(args) not in (4, 5):
        fail(__doc__)
    vdb_path, ply_path, glb_path, out_dir = args[:4]
    os.makedirs(out_dir, exist_ok=True)
    print(f"Blender {bpy.app.version_string}")
    checks = [check_volume(vdb_path, out_dir), check_points(ply_path), check_mesh(glb_path)]
    if len(args) == 5:
        checks.append(check_velocity(args[4]))
    for line in checks:
        print("ok " + line)
    print("blender check passed")


main()
