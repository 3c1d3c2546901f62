"""phenomena in Blender: snow that piles up where it can land and slides past its angle
of repose on the selected objects, a flame as an OpenVDB volume sequence, the aurora as
the world's sky, sparkle glints as emissive points. Every operator goes through the
``phenomena`` Python package (python/ in the repository), so its results are the
``phenomena`` command's for the same scene.

Enable it as a legacy add-on (Blender 3.4+: Preferences > Add-ons > Install, or this
folder under ``scripts/addons``) with the package importable: installed in Blender's
Python, in ``_vendor/`` beside this file (``pip install --target _vendor phenomena``),
or in the folder named by ``PHENOMENA_PYTHON_PATH``. Blender 4.2+ installs it as an
extension (``blender_manifest.toml``) with the wheel inside.

Coordinates: phenomena is y-up, Blender z-up; Blender (x, y, z) is phenomena
(x, z, -y). The aurora sky is turned so its north is on +Y.
"""

bl_info = {
    "name": "phenomena",
    "author": "phenomena developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > phenomena",
    "description": "Snow cover, flame volumes, aurora skies and glints from phenomena",
    "category": "Object",
}

import math
import os
import sys
import tempfile
import threading

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, IntProperty, PointerProperty, StringProperty

_HERE = os.path.dirname(os.path.abspath(__file__))


def _package():
    """The phenomena package: importable already, or from _vendor/ or
    PHENOMENA_PYTHON_PATH."""
    for path in (os.path.join(_HERE, "_vendor"), os.environ.get("PHENOMENA_PYTHON_PATH")):
        if path and os.path.isdir(path) and path not in sys.path:
            sys.path.append(path)
    try:
        import phenomena
    except ImportError as e:
        raise RuntimeError(
            "the phenomena Python package is not installed for Blender's Python: "
            f"pip install --target {os.path.join(_HERE, '_vendor')} phenomena ({e})"
        ) from e
    return phenomena


def to_blender(points):
    """phenomena (x, y, z), y up, as Blender (x, -z, y), z up."""
    import numpy as np

    p = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    return np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)


def to_phenomena(points):
    """Blender (x, y, z) as phenomena (x, z, -y)."""
    import numpy as np

    p = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    return np.stack([p[:, 0], p[:, 2], -p[:, 1]], axis=1)


def _output_dir(context, name):
    """``//phenomena/<name>`` beside the .blend file, or a temporary folder for an
    unsaved one."""
    base = bpy.path.abspath("//") if bpy.data.filepath else tempfile.gettempdir()
    path = os.path.join(base, "phenomena", name)
    os.makedirs(path, exist_ok=True)
    return path


def _scene_for(phenomena, path, kind):
    """The scene file at ``path`` (already absolute: worker threads do not touch bpy),
    or the phenomenon's starter."""
    if path:
        return phenomena.Scene(path)
    return phenomena.Scene.from_toml(phenomena.starter(kind), name=f"{kind}.toml")


def _abspath(path):
    """A panel's path made absolute (``//`` is the .blend file's folder); empty stays empty."""
    return bpy.path.abspath(path) if path else ""


# ---------------------------------------------------------------- background work


class _Work:
    """Work that runs either at once (scripts, ``blender -b``) or in a thread with
    Blender's progress bar, cancellable with Esc. Subclasses give ``prepare`` (main
    thread: read Blender's data), ``compute`` (any thread: no bpy) and ``finish`` (main
    thread: make Blender's data)."""

    _thread = None
    _timer = None

    def execute(self, context):
        try:
            job = self.prepare(context)
            result = self.compute(job, lambda done, total: True)
            self.finish(context, job, result)
        except Exception as e:  # reported to the user, as Blender shows operator errors
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background:
            return self.execute(context)
        try:
            self._job = self.prepare(context)
        except Exception as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self._state = {"done": 0, "total": 1, "cancel": False, "result": None, "error": None}
        state = self._state
        # The thread gets plain Python values only: the operator is Blender's data.
        compute, job = self.compute, self._job

        def progress(done, total):
            state["done"], state["total"] = done, max(total, 1)
            return not state["cancel"]

        def run():
            try:
                state["result"] = compute(job, progress)
            except BaseException as e:  # includes the cancel (KeyboardInterrupt)
                state["error"] = e

        self._thread = threading.Thread(target=run, daemon=True)
        self._thread.start()
        wm = context.window_manager
        wm.progress_begin(0, 1000)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        state = self._state
        if event.type == "ESC":
            state["cancel"] = True
            return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        wm = context.window_manager
        wm.progress_update(int(1000 * state["done"] / state["total"]))
        if self._thread.is_alive():
            return {"PASS_THROUGH"}
        self._stop_reporting(context)
        if state["error"] is not None:
            cancelled = isinstance(state["error"], KeyboardInterrupt)
            self.report({"WARNING" if cancelled else "ERROR"}, "cancelled" if cancelled else str(state["error"]))
            return {"CANCELLED"}
        try:
            self.finish(context, self._job, state["result"])
        except Exception as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return {"FINISHED"}

    def _stop_reporting(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
            wm.progress_end()

    def cancel(self, context):
        """Blender ends the operator (a file loaded, the window closed): stop the work
        and the progress bar; the thread ends at its next frame."""
        self._state["cancel"] = True
        self._stop_reporting(context)


# ---------------------------------------------------------------- snow


class PhenomenaSnowSettings(bpy.types.PropertyGroup):
    """The snow panel's settings (the ``[snow]`` table of the scene the operator makes)."""

    hours: FloatProperty(name="Hours of snowfall", default=2.0, min=0.0, max=1000.0,
                         description="How long the snow falls")
    depth_cm: FloatProperty(name="Depth (cm)", default=0.0, min=0.0, max=1000.0,
                            description="Snow depth fallen instead of hours (0: use the hours)")
    rate_cm_per_h: FloatProperty(name="Rate (cm/h)", default=2.0, min=0.01, max=100.0)
    wind_deg: FloatVectorProperty(name="Wind tilt", size=2, default=(0.0, 0.0), min=-60.0, max=60.0,
                                  description="Mean tilt of the snowfall towards +X and +Y, degrees")
    spread_deg: FloatProperty(name="Spread", default=10.0, min=0.0, max=45.0,
                              description="Standard deviation of the snowfall's tilt, degrees")
    repose_deg: FloatProperty(name="Angle of repose", default=45.0, min=1.0, max=89.0,
                              description="Snow slides off slopes steeper than this (fresh dry snow 40-50)")
    resolution: IntProperty(name="Resolution", default=128, min=16, max=2048,
                            description="Texels per side of each snow map")
    receivers: EnumProperty(name="Snow on", default="SELECTED", items=[
        ("SELECTED", "Selected", "Snow only on the selected objects; the rest of the scene occludes"),
        ("ALL", "All", "Snow on every visible mesh"),
    ])
    seed: IntProperty(name="Seed", default=1, min=0)
    export_dir: StringProperty(name="Save scene to", subtype="DIR_PATH", default="",
                               description="Also write the scene made (snow.toml and geometry.obj) to this folder, "
                               "for `phenomena export snow-mesh` or a farm")


def _scene_geometry(context, exclude):
    """Every visible mesh object but ``exclude`` as world-space triangles: vertices
    (Blender axes), triangles, an object index per triangle, and the objects."""
    import numpy as np

    depsgraph = context.evaluated_depsgraph_get()
    verts, tris, ids, objects = [], [], [], []
    offset = 0
    for obj in context.visible_objects:
        if obj.type != "MESH" or obj in exclude or obj.get("phenomena_snow"):
            continue
        evaluated = obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        try:
            mesh.calc_loop_triangles()
            co = np.empty(len(mesh.vertices) * 3, np.float32)
            mesh.vertices.foreach_get("co", co)
            tri = np.empty(len(mesh.loop_triangles) * 3, np.int64)
            mesh.loop_triangles.foreach_get("vertices", tri)
        finally:
            evaluated.to_mesh_clear()
        if not len(tri):
            continue
        m = np.array(obj.matrix_world, dtype=np.float64)
        co = co.reshape(-1, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
        tri = tri.reshape(-1, 3)
        if np.linalg.det(m[:3, :3]) < 0:
            tri = tri[:, ::-1]  # a mirrored object: keep its faces facing out
        verts.append(co.astype(np.float32))
        tris.append(tri + offset)
        ids.append(np.full(len(tri), len(objects)))
        objects.append(obj)
        offset += len(co)
    if not objects:
        raise RuntimeError("no visible mesh objects to put snow on")
    return np.concatenate(verts), np.concatenate(tris), np.concatenate(ids), objects


def _keep_over(cover_positions, cover_triangles, verts, tris, ids, receivers):
    """Triangles of the snow whose solid lies mostly over a receiver object: a ray down
    from each triangle's centre finds the surface beneath, and a solid (triangles
    connected through shared corners, corners at the same place being one) is kept
    or dropped whole, so what is kept stays closed. A solid spanning a receiver and
    another object goes with the one under most of it."""
    import numpy as np
    from mathutils import Vector
    from mathutils.bvhtree import BVHTree

    original = cover_triangles
    tree = BVHTree.FromPolygons([tuple(v) for v in verts.tolist()], [tuple(t) for t in tris.tolist()])
    # The export gives each texel's sides and bottom their own corners: weld by place.
    _, welded = np.unique(np.round(cover_positions / 1e-6).astype(np.int64), axis=0, return_inverse=True)
    cover_triangles = welded.reshape(-1)[cover_triangles]
    parent = list(range(int(welded.max()) + 1 if len(welded) else 0))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for a, b, c in cover_triangles.tolist():
        ra, rb, rc = find(a), find(b), find(c)
        parent[rb] = ra
        parent[find(rc)] = ra
    piece = np.array([find(t[0]) for t in cover_triangles.tolist()])
    centres = cover_positions[original].mean(axis=1)
    over = np.zeros(len(cover_triangles), bool)
    down = Vector((0.0, 0.0, -1.0))
    for k, c in enumerate(centres.tolist()):
        hit = tree.ray_cast(Vector((c[0], c[1], c[2] + 1e-4)), down)
        over[k] = hit[2] is not None and ids[hit[2]] in receivers
    keep = np.zeros(len(cover_triangles), bool)
    for p in np.unique(piece):
        members = piece == p
        keep[members] = over[members].mean() > 0.5
    return keep


def _snow_material():
    mat = bpy.data.materials.get("Phenomena Snow") or bpy.data.materials.new("Phenomena Snow")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    if bsdf is not None:
        bsdf.inputs["Base Color"].default_value = (0.9, 0.93, 0.97, 1.0)
        bsdf.inputs["Roughness"].default_value = 0.55
        if "Subsurface" in bsdf.inputs:  # 3.x; 4.x names it Subsurface Weight
            bsdf.inputs["Subsurface"].default_value = 0.15
        elif "Subsurface Weight" in bsdf.inputs:
            bsdf.inputs["Subsurface Weight"].default_value = 0.15
    return mat


class PHENOMENA_OT_snow_cover(_Work, bpy.types.Operator):
    """Snow on the selected objects (the rest of the scene occludes), made by phenomena's
    snow simulation with the panel's settings; re-running replaces the snow"""

    bl_idname = "phenomena.snow_cover"
    bl_label = "Snow Cover"
    bl_options = {"REGISTER", "UNDO"}

    def prepare(self, context):
        s = context.scene.phenomena_snow
        selected = [o for o in context.selected_objects if o.type == "MESH" and not o.get("phenomena_snow")]
        if s.receivers == "SELECTED" and not selected:
            raise RuntimeError("select the mesh objects to put snow on")
        verts, tris, ids, objects = _scene_geometry(context, exclude=())
        receivers = {k for k, o in enumerate(objects) if s.receivers == "ALL" or o in selected}
        snow = {
            "map_resolution": s.resolution,
            "rate_cm_per_h": s.rate_cm_per_h,
            "main_tilt_deg": [s.wind_deg[0], -s.wind_deg[1]],
            "spread_deg": s.spread_deg,
            "repose_deg": s.repose_deg,
        }
        timing = {"depth_cm": s.depth_cm} if s.depth_cm > 0 else {"hours": s.hours}
        return {"verts": verts, "tris": tris, "ids": ids, "receivers": receivers, "snow": snow,
                "timing": timing, "seed": s.seed, "all": s.receivers == "ALL",
                "export_dir": bpy.path.abspath(s.export_dir) if s.export_dir else ""}

    def compute(self, job, progress):
        phenomena = _package()
        return phenomena.snow_cover(to_phenomena(job["verts"]), job["tris"], job["ids"], seed=job["seed"],
                                    snow=job["snow"], progress=progress, **job["timing"])

    def finish(self, context, job, cover):
        positions = to_blender(cover.positions)
        triangles = cover.triangles
        if not job["all"]:
            keep = _keep_over(positions, triangles, job["verts"], job["tris"], job["ids"], job["receivers"])
            triangles = triangles[keep]
        obj = next((o for o in context.scene.objects if o.get("phenomena_snow")), None)
        mesh = bpy.data.meshes.new("Snow")
        used = sorted(set(triangles.reshape(-1).tolist()))
        remap = {v: k for k, v in enumerate(used)}
        mesh.from_pydata(positions[used].tolist(), [], [[remap[i] for i in t] for t in triangles.tolist()])
        mesh.validate()
        mesh.materials.append(_snow_material())
        if obj is None:
            obj = bpy.data.objects.new("Snow", mesh)
            obj["phenomena_snow"] = True
            context.scene.collection.objects.link(obj)
        else:
            old = obj.data
            obj.data = mesh
            if old.users == 0:
                bpy.data.meshes.remove(old)
        obj["phenomena_scene"] = cover.scene_toml
        obj["phenomena_hours"] = cover.hours
        if job["export_dir"]:
            os.makedirs(job["export_dir"], exist_ok=True)
            for name, data in (("snow.toml", cover.scene_toml.encode()), ("geometry.obj", cover.geometry_obj)):
                with open(os.path.join(job["export_dir"], name), "wb") as f:
                    f.write(data)
        self.report({"INFO"}, f"snow: {len(triangles)} triangles after {cover.hours:.2f} h ({cover.steps} steps)")


# ---------------------------------------------------------------- flame


class PhenomenaFlameSettings(bpy.types.PropertyGroup):
    scene_path: StringProperty(name="Scene", subtype="FILE_PATH", default="",
                               description="A phenomena flame scene (empty: the starter flame)")
    frames: IntProperty(name="Frames", default=48, min=1, max=100000)
    voxel_m: FloatProperty(name="Voxel (m)", default=0.01, min=0.001, max=1.0)
    emission_strength: FloatProperty(name="Emission", default=4.0, min=0.0)


def _flame_material():
    """The README's volume material: density from ``density``, emission colour from the
    ``emission`` grid."""
    mat = bpy.data.materials.get("Phenomena Flame") or bpy.data.materials.new("Phenomena Flame")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    volume = nodes.new("ShaderNodeVolumePrincipled")
    volume.inputs["Density Attribute"].default_value = "density"
    emission = nodes.new("ShaderNodeAttribute")
    emission.attribute_name = "emission"
    links.new(emission.outputs["Color"], volume.inputs["Emission Color"])
    links.new(volume.outputs["Volume"], out.inputs["Volume"])
    return mat


class PHENOMENA_OT_flame_volume(_Work, bpy.types.Operator):
    """A flame as an OpenVDB volume sequence synced to the timeline: the VDB files at
    filepath, or the panel's flame scene rendered to VDB first"""

    bl_idname = "phenomena.flame_volume"
    bl_label = "Flame Volume"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="VDB", subtype="FILE_PATH", default="",
                             description="The first .vdb of a sequence (empty: render the panel's scene)")

    def prepare(self, context):
        s = context.scene.phenomena_flame
        return {"filepath": _abspath(self.filepath),
                "scene": _abspath(s.scene_path), "frames": s.frames, "voxel_m": s.voxel_m,
                "out": _output_dir(context, "flame"), "strength": s.emission_strength}

    def compute(self, job, progress):
        if job["filepath"]:
            return sorted_sequence(job["filepath"])
        phenomena = _package()
        scene = _scene_for(phenomena, job["scene"], "flame")
        files = []
        for frame in range(job["frames"]):
            scene.step(1)
            data, _manifest = scene.volume_vdb(job["voxel_m"])
            path = os.path.join(job["out"], f"frame_{frame:05}.vdb")
            with open(path + ".tmp", "wb") as f:
                f.write(data)
            os.replace(path + ".tmp", path)
            files.append(path)
            if progress(frame + 1, job["frames"]) is False:
                raise KeyboardInterrupt("cancelled")
        return files

    def finish(self, context, job, files):
        if not files:
            raise RuntimeError(f"no .vdb file at {job['filepath']}")
        volume = bpy.data.volumes.new("Flame")
        volume.filepath = files[0]
        volume.is_sequence = len(files) > 1
        volume.frame_duration = len(files)
        volume.frame_start = context.scene.frame_start
        # Blender shows file number frame - frame_start + 1 + frame_offset: the
        # sequence's first file at the scene's first frame.
        volume.frame_offset = _file_number(files[0]) - 1
        volume.sequence_mode = "CLIP"
        volume.materials.append(_flame_material())
        mat = volume.materials[0]
        for node in mat.node_tree.nodes:
            if node.type == "PRINCIPLED_VOLUME":
                node.inputs["Emission Strength"].default_value = job["strength"]
        obj = bpy.data.objects.new("Flame", volume)
        obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # the file's y up as Blender's z up
        obj["phenomena_flame"] = files[0]
        context.scene.collection.objects.link(obj)
        self.report({"INFO"}, f"flame: {len(files)} VDB frames from {os.path.dirname(files[0])}")


def _file_number(path):
    """The number a sequence's file name ends in (0 if none)."""
    import re

    match = re.search(r"(\d+)\.vdb$", os.path.basename(path))
    return int(match.group(1)) if match else 0


def sorted_sequence(first):
    """The files of the numbered sequence ``first`` starts (``frame_00000.vdb``,
    ``frame_00001.vdb``, ...), or ``first`` alone when its name ends in no number."""
    import re

    folder, name = os.path.split(first)
    match = re.fullmatch(r"(.*?)(\d+)(\.vdb)", name)
    if not match:
        return [first] if os.path.isfile(first) else []
    stem, digits, ext = match.groups()
    files, number = [], int(digits)
    while os.path.isfile(path := os.path.join(folder, f"{stem}{number:0{len(digits)}}{ext}")):
        files.append(path)
        number += 1
    return files


# ---------------------------------------------------------------- aurora


class PhenomenaAuroraSettings(bpy.types.PropertyGroup):
    scene_path: StringProperty(name="Scene", subtype="FILE_PATH", default="",
                               description="A phenomena aurora scene (empty: the starter aurora)")
    frame: IntProperty(name="Frame", default=60, min=0, max=100000)
    width: IntProperty(name="Width", default=2048, min=16, max=16384,
                       description="Width of the panorama (its height is half)")
    use_site: BoolProperty(name="Set the site", default=False,
                           description="Use the latitude, longitude and time below instead of the scene's")
    latitude_deg: FloatProperty(name="Latitude", default=69.65, min=-90.0, max=90.0)
    longitude_deg: FloatProperty(name="Longitude", default=18.96, min=-180.0, max=180.0)
    utc: StringProperty(name="UTC", default="2027-01-15T21:00:00Z")
    strength: FloatProperty(name="Strength", default=1.0, min=0.0)


class PHENOMENA_OT_aurora_sky(_Work, bpy.types.Operator):
    """The aurora seen from the ground at the scene's site as an equirectangular EXR,
    set as the world's background (north along +Y)"""

    bl_idname = "phenomena.aurora_sky"
    bl_label = "Aurora Sky"
    bl_options = {"REGISTER", "UNDO"}

    def prepare(self, context):
        s = context.scene.phenomena_aurora
        site = {"latitude_deg": s.latitude_deg, "longitude_deg": s.longitude_deg, "utc": s.utc} if s.use_site else None
        return {"scene": _abspath(s.scene_path), "frame": s.frame, "width": s.width, "site": site,
                "out": os.path.join(_output_dir(context, "aurora"), f"aurora_sky_{s.frame:05}.exr"),
                "strength": s.strength}

    def compute(self, job, progress):
        phenomena = _package()
        scene = _scene_for(phenomena, job["scene"], "aurora").with_value("render.sky.camera", {"kind": "panorama"})
        for key, value in (job["site"] or {}).items():
            scene = scene.with_value(f"render.sky.site.{key}", value)
        scene.save_exr(job["out"], job["frame"], width=job["width"], height=job["width"] // 2,
                        layers=False, progress=progress)
        return job["out"]

    def finish(self, context, job, path):
        world = context.scene.world or bpy.data.worlds.new("World")
        context.scene.world = world
        world.use_nodes = True
        nodes, links = world.node_tree.nodes, world.node_tree.links
        nodes.clear()
        coords = nodes.new("ShaderNodeTexCoord")
        mapping = nodes.new("ShaderNodeMapping")
        # The panorama looks north at its centre with east to its right. Blender's
        # equirectangular centre looks along +X with -Y to its right, so the lookup
        # turns a quarter about Z: north lands on +Y and east on +X.
        mapping.inputs["Rotation"].default_value = (0.0, 0.0, -math.pi / 2)
        texture = nodes.new("ShaderNodeTexEnvironment")
        texture.image = bpy.data.images.load(path, check_existing=False)
        texture.image.colorspace_settings.name = "Linear" if bpy.app.version < (4, 0, 0) else "Linear Rec.709"
        background = nodes.new("ShaderNodeBackground")
        background.inputs["Strength"].default_value = job["strength"]
        out = nodes.new("ShaderNodeOutputWorld")
        links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
        links.new(texture.outputs["Color"], background.inputs["Color"])
        links.new(background.outputs["Background"], out.inputs["Surface"])
        world["phenomena_aurora"] = path
        self.report({"INFO"}, f"aurora sky: {path}")


# ---------------------------------------------------------------- sparkle


class PhenomenaSparkleSettings(bpy.types.PropertyGroup):
    scene_path: StringProperty(name="Scene", subtype="FILE_PATH", default="",
                               description="A phenomena sparkle scene (empty: the starter)")
    frame: IntProperty(name="Frame", default=10, min=0, max=100000)
    radius_m: FloatProperty(name="Radius (m)", default=0.002, min=0.00001, max=1.0)
    strength: FloatProperty(name="Emission", default=50.0, min=0.0)


def _glint_nodes(material, radius_m):
    """Geometry nodes that turn the glints' vertices into points with ``material``."""
    group = bpy.data.node_groups.new("Phenomena Glints", "GeometryNodeTree")
    if hasattr(group, "interface"):  # Blender 4.0+
        group.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
        group.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    else:
        group.inputs.new("NodeSocketGeometry", "Geometry")
        group.outputs.new("NodeSocketGeometry", "Geometry")
    nodes, links = group.nodes, group.links
    given, out = nodes.new("NodeGroupInput"), nodes.new("NodeGroupOutput")
    points = nodes.new("GeometryNodeMeshToPoints")
    points.inputs["Radius"].default_value = radius_m
    setter = nodes.new("GeometryNodeSetMaterial")
    setter.inputs["Material"].default_value = material
    links.new(given.outputs[0], points.inputs["Mesh"])
    links.new(points.outputs["Points"], setter.inputs["Geometry"])
    links.new(setter.outputs["Geometry"], out.inputs[0])
    return group


def _glint_material(strength):
    mat = bpy.data.materials.new("Phenomena Glints")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    emission = nodes.new("ShaderNodeEmission")
    intensity = nodes.new("ShaderNodeAttribute")
    intensity.attribute_name = "intensity"
    scale = nodes.new("ShaderNodeMath")
    scale.operation = "MULTIPLY"
    scale.inputs[1].default_value = strength
    links.new(intensity.outputs["Fac"], scale.inputs[0])
    links.new(scale.outputs["Value"], emission.inputs["Strength"])
    links.new(emission.outputs["Emission"], out.inputs["Surface"])
    return mat


class PHENOMENA_OT_sparkle_glints(_Work, bpy.types.Operator):
    """The glints of a sparkle scene at a frame as emissive points (position and
    intensity from the simulation)"""

    bl_idname = "phenomena.sparkle_glints"
    bl_label = "Sparkle Glints"
    bl_options = {"REGISTER", "UNDO"}

    def prepare(self, context):
        s = context.scene.phenomena_sparkle
        return {"scene": _abspath(s.scene_path), "frame": s.frame, "radius": s.radius_m, "strength": s.strength}

    def compute(self, job, progress):
        phenomena = _package()
        scene = _scene_for(phenomena, job["scene"], "sparkle")
        scene.step(job["frame"] + 1, progress)
        return scene.points()

    def finish(self, context, job, points):
        import numpy as np

        positions = to_blender(np.stack([points["x"], points["y"], points["z"]], axis=1))
        mesh = bpy.data.meshes.new("Glints")
        mesh.vertices.add(len(positions))
        mesh.vertices.foreach_set("co", positions.reshape(-1))
        attribute = mesh.attributes.new("intensity", "FLOAT", "POINT")
        attribute.data.foreach_set("value", points["intensity"].astype(np.float32))
        mesh.update()
        obj = bpy.data.objects.new("Glints", mesh)
        material = _glint_material(job["strength"])
        obj.data.materials.append(material)
        modifier = obj.modifiers.new("Glints", "NODES")
        modifier.node_group = _glint_nodes(material, job["radius"])
        obj["phenomena_glints"] = len(positions)
        context.scene.collection.objects.link(obj)
        self.report({"INFO"}, f"glints: {len(positions)} points")


# ---------------------------------------------------------------- panel


class PHENOMENA_PT_panel(bpy.types.Panel):
    bl_label = "phenomena"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "phenomena"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        box = layout.box()
        box.label(text="Snow cover")
        s = scene.phenomena_snow
        for name in ("hours", "depth_cm", "rate_cm_per_h", "wind_deg", "spread_deg", "repose_deg", "resolution",
                     "receivers", "seed", "export_dir"):
            box.prop(s, name)
        box.operator(PHENOMENA_OT_snow_cover.bl_idname)
        box = layout.box()
        box.label(text="Flame volume")
        for name in ("scene_path", "frames", "voxel_m", "emission_strength"):
            box.prop(scene.phenomena_flame, name)
        box.operator(PHENOMENA_OT_flame_volume.bl_idname)
        box = layout.box()
        box.label(text="Aurora sky")
        a = scene.phenomena_aurora
        for name in ("scene_path", "frame", "width", "strength", "use_site"):
            box.prop(a, name)
        if a.use_site:
            for name in ("latitude_deg", "longitude_deg", "utc"):
                box.prop(a, name)
        box.operator(PHENOMENA_OT_aurora_sky.bl_idname)
        box = layout.box()
        box.label(text="Sparkle glints")
        for name in ("scene_path", "frame", "radius_m", "strength"):
            box.prop(scene.phenomena_sparkle, name)
        box.operator(PHENOMENA_OT_sparkle_glints.bl_idname)


_SETTINGS = (
    ("phenomena_snow", PhenomenaSnowSettings),
    ("phenomena_flame", PhenomenaFlameSettings),
    ("phenomena_aurora", PhenomenaAuroraSettings),
    ("phenomena_sparkle", PhenomenaSparkleSettings),
)
_CLASSES = [c for _, c in _SETTINGS] + [
    PHENOMENA_OT_snow_cover,
    PHENOMENA_OT_flame_volume,
    PHENOMENA_OT_aurora_sky,
    PHENOMENA_OT_sparkle_glints,
    PHENOMENA_PT_panel,
]


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    for name, cls in _SETTINGS:
        setattr(bpy.types.Scene, name, PointerProperty(type=cls))


def unregister():
    for name, _ in _SETTINGS:
        delattr(bpy.types.Scene, name)
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
