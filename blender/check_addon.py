"""The add-on in a real Blender, headless (run by .ci/run):

    PHENOMENA_PYTHON_PATH=SITE blender -b --factory-startup --python-exit-code 1 \\
        --python blender/check_addon.py -- PHENOMENA_BINARY OUT_DIR

enables blender/phenomena_blender as a legacy add-on from the repository (Blender 3.4)
or, with PHENOMENA_EXTENSION_ZIP set, installs that zip (blender/package.sh) as an
extension with its own wheel (Blender 4.2+, e.g. the bpy module from the package index:
`python blender/check_addon.py -- ...`), and runs each operator on a small scene: snow on top of a cube over a plane (and only there), snow
equal to `phenomena export snow-mesh` of the scene the add-on saved, a flame volume
object whose VDB frames follow the timeline, the world lit by an aurora panorama, glints
as points. Any failed check raises, and Blender exits with status 1.
"""

import math
import os
import subprocess
import sys
import tempfile

import bpy  # first: as a module (Blender 4.x from the package index) it puts addon_utils on the path
import addon_utils  # noqa: E402
import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
argv = sys.argv[sys.argv.index("--") + 1:]
BINARY, OUT = os.path.abspath(argv[0]), os.path.abspath(argv[1])
os.makedirs(OUT, exist_ok=True)


def check(condition, message):
    if not condition:
        raise AssertionError(message)
    print(f"ok: {message}")


def enable_from_the_repository():
    """The repository's add-on folder linked into a scripts folder's addons/, then enable."""
    scripts = tempfile.mkdtemp(prefix="phenomena-scripts-")
    os.makedirs(os.path.join(scripts, "addons"))
    os.symlink(os.path.join(REPO, "blender", "phenomena_blender"), os.path.join(scripts, "addons", "phenomena_blender"))
    paths = bpy.context.preferences.filepaths
    if hasattr(paths, "script_directories"):  # Blender 3.6+: a list of folders
        paths.script_directories.new().directory = scripts
    else:
        paths.script_directory = scripts
    bpy.utils.refresh_script_paths()
    addon_utils.modules_refresh()
    bpy.ops.preferences.addon_enable(module="phenomena_blender")
    check(addon_utils.check("phenomena_blender")[1], "the add-on is enabled from the repository")


def install_the_extension(zip_path):
    """The packaged extension installed and enabled as Blender 4.2+ does it; the
    phenomena package must then come from the wheel inside it."""
    result = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    check(result == {"FINISHED"}, f"the extension installs from {os.path.basename(zip_path)}")
    check("bl_ext.user_default.phenomena_blender" in bpy.context.preferences.addons, "and is enabled")
    import phenomena

    check(os.sep + "extensions" + os.sep in phenomena.__file__,
          f"with the phenomena package from its own wheel ({phenomena.__file__})")


def empty_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)


def cube_over_plane():
    empty_scene()
    bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0.0, 0.0, 0.0))
    plane = bpy.context.active_object
    plane.scale.x = -1.0  # mirrored: its faces must still face up
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.5))
    cube = bpy.context.active_object
    return plane, cube


def snow_object():
    found = [o for o in bpy.context.scene.objects if o.get("phenomena_snow")]
    check(len(found) == 1, f"one snow object (found {len(found)})")
    return found[0]


def vertices(obj):
    co = np.empty(len(obj.data.vertices) * 3, np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def open_edges(obj):
    """Edges of the mesh not shared by exactly two triangles, corners at one place
    being one corner (the export gives each texel's sides their own corners)."""
    v = vertices(obj)
    _, welded = np.unique(np.round(v / 1e-6).astype(np.int64), axis=0, return_inverse=True)
    faces = np.empty(len(obj.data.polygons) * 3, np.int64)
    obj.data.polygons.foreach_get("vertices", faces)
    t = welded.reshape(-1)[faces.reshape(-1, 3)]
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return int(np.sum(counts != 2))


def check_snow():
    plane, cube = cube_over_plane()
    s = bpy.context.scene.phenomena_snow
    s.hours, s.resolution, s.receivers = 1.0, 64, "SELECTED"
    bpy.ops.object.select_all(action="DESELECT")
    cube.select_set(True)
    check(bpy.ops.phenomena.snow_cover() == {"FINISHED"}, "snow_cover runs headless")
    v = vertices(snow_object())
    check(len(v) > 0, f"snow on the cube ({len(v)} vertices)")
    # 1 h of 2 cm/h: the top 2 cm over the cube's top at z = 1, nothing on the plane.
    check(abs(v[:, 2].max() - 1.02) < 0.005, f"the snow's top is 2 cm over the cube (z {v[:, 2].max():.4f})")
    check(v[:, 2].min() > 0.9, f"no snow on the plane with only the cube selected (lowest z {v[:, 2].min():.3f})")
    check(np.abs(v[:, :2]).max() < 0.5 + 0.05, "the snow stays on the cube's top")
    check(open_edges(snow_object()) == 0, "and it is closed")
    # Re-run in place: one snow object, now on everything, and the scene saved.
    s.receivers = "ALL"
    s.export_dir = os.path.join(OUT, "snow-scene")
    check(bpy.ops.phenomena.snow_cover() == {"FINISHED"}, "snow_cover runs again in place")
    snow = snow_object()
    v = vertices(snow)
    check(np.any(v[:, 2] < 0.1), "with every object, snow lies on the (mirrored) plane too")
    check(open_edges(snow) == 0, "closed too")
    ply = os.path.join(OUT, "snow-cli.ply")
    subprocess.run([BINARY, "export", "snow-mesh", os.path.join(s.export_dir, "snow.toml"), "--format", "ply",
                    "--time-h", str(snow["phenomena_hours"]), "--out", ply], check=True)
    from phenomena._ply import read_ply

    cli = read_ply(open(ply, "rb").read())
    x, y, z = (cli["vertex"][k] for k in "xyz")
    want = np.stack([x, -z, y], axis=1)  # phenomena's y up as Blender's z up
    check(v.shape == want.shape and np.array_equal(v, want),
          f"the add-on's snow equals `phenomena export snow-mesh` of its scene ({len(v)} vertices)")
    faces = np.empty(len(snow.data.polygons) * 3, np.int64)
    snow.data.polygons.foreach_get("vertices", faces)
    check(np.array_equal(faces.reshape(-1, 3), cli["face"]["vertex_indices"].astype(np.int64)),
          "and its triangles are the export's")


def check_flame():
    empty_scene()
    f = bpy.context.scene.phenomena_flame
    f.frames = 3
    check(bpy.ops.phenomena.flame_volume() == {"FINISHED"}, "flame_volume renders the starter flame headless")
    obj = next(o for o in bpy.context.scene.objects if o.type == "VOLUME")
    grids = obj.data.grids
    for frame, number in ((1, 0), (3, 2)):
        bpy.context.scene.frame_set(frame)
        grids.load()
        check(grids.frame_filepath.endswith(f"frame_{number:05}.vdb"),
              f"at frame {frame} the volume shows frame_{number:05}.vdb ({os.path.basename(grids.frame_filepath)})")
    names = {g.name for g in grids}
    check({"density", "temperature", "emission"} <= names, f"the flame's grids are there ({sorted(names)})")
    check(obj.data.materials[0].name.startswith("Phenomena Flame"), "with the emission/density material")
    # A sequence the command rendered, by filepath.
    out = os.path.join(OUT, "flame-cli")
    subprocess.run([BINARY, "render", os.path.join(REPO, "scenes/flame-paper.toml"), "--frames", "5..8",
                    "--format", "vdb", "--out", out], check=True)
    before = {o.name for o in bpy.data.objects}
    bpy.ops.phenomena.flame_volume(filepath=os.path.join(out, "frame_00005.vdb"))
    new = [o for o in bpy.data.objects if o.name not in before]
    check(len(new) == 1 and new[0].data.frame_duration == 3, "filepath= imports the command's 3-frame sequence")
    bpy.context.scene.frame_set(2)
    new[0].data.grids.load()
    shown = os.path.basename(new[0].data.grids.frame_filepath)
    check(shown == "frame_00006.vdb", f"its second file at the second frame ({shown})")


def check_aurora():
    a = bpy.context.scene.phenomena_aurora
    a.frame, a.width = 3, 128
    check(bpy.ops.phenomena.aurora_sky() == {"FINISHED"}, "aurora_sky renders headless")
    world = bpy.context.scene.world
    textures = [n for n in world.node_tree.nodes if n.type == "TEX_ENVIRONMENT"]
    check(len(textures) == 1 and textures[0].image is not None, "the world has an environment image")
    image = textures[0].image
    pixels = np.array(image.pixels[:])  # loads the file
    check(tuple(image.size) == (128, 64), f"an equirectangular 2:1 image ({tuple(image.size)})")
    pixels = pixels.reshape(64, 128, 4)
    check(pixels[..., :3].max() > 0, "the sky is not black")
    # North on +Y, east on +X: a panorama red at its centre (north) and green a
    # quarter to the right (east), seen by a camera looking each way.
    marks = np.zeros((64, 128, 4), np.float32)
    marks[..., 3] = 1.0
    marks[:, 60:68, 0] = 1.0
    marks[:, 92:100, 1] = 1.0
    image.pixels[:] = marks.reshape(-1)
    image.pack()
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = 8
    camera = bpy.data.objects.new("Look", bpy.data.cameras.new("Look"))
    camera.data.angle = math.radians(10)
    scene.collection.objects.link(camera)
    scene.camera = camera
    for heading, (name, channel) in ((0.0, ("north", 0)), (-math.pi / 2, ("east", 1))):
        camera.rotation_euler = (math.pi / 2, 0.0, heading)  # level, looking along +Y turned by heading
        scene.render.filepath = os.path.join(OUT, f"sky-{name}.exr")
        scene.render.image_settings.file_format = "OPEN_EXR"
        bpy.ops.render.render(write_still=True)
        seen = bpy.data.images.load(scene.render.filepath)
        rgb = np.array(seen.pixels[:]).reshape(8, 8, 4)[3:5, 3:5, :3].mean(axis=(0, 1))
        check(rgb[channel] > 0.5 and rgb[1 - channel] < 0.1, f"the panorama's {name} is seen looking {name} ({rgb})")


def check_sparkle():
    s = bpy.context.scene.phenomena_sparkle
    s.frame = 3
    check(bpy.ops.phenomena.sparkle_glints() == {"FINISHED"}, "sparkle_glints runs headless")
    obj = next(o for o in bpy.context.scene.objects if o.get("phenomena_glints") is not None)
    check(obj["phenomena_glints"] > 0 and len(obj.data.vertices) == obj["phenomena_glints"],
          f"the glints are points ({obj['phenomena_glints']})")
    check(obj.modifiers[0].type == "NODES", "drawn as points by geometry nodes with an emissive material")


if os.environ.get("PHENOMENA_EXTENSION_ZIP"):
    install_the_extension(os.path.abspath(os.environ["PHENOMENA_EXTENSION_ZIP"]))
else:
    enable_from_the_repository()
print(f"Blender {bpy.app.version_string}")
check_snow()
check_flame()
check_aurora()
check_sparkle()
print("phenomena add-on: every check passed")
