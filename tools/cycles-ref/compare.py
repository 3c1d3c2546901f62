"""The snow renderer beside Blender Cycles: the same scene, snow, camera and sun.

`phenomena export snow-scene` writes the scene's objects, the snow, the camera and the
sun as one GLB, with the renderer's light settings in the scene's extras. This script
imports it into Blender 3.4, lights it as the snow renderer does (a sun of the same
colour and strength: Lambert radiance albedo · E / π with E = π · sun_strength · sun_rgb;
a uniform sky of sky_strength · sky_rgb for the light and of background_rgb where the
camera sees it; rough diffuse materials without a specular lobe), renders it with Cycles
and compares the image with ours: both decoded from sRGB to linear luminance and each
divided by its mean (the two tone curves differ in exposure), then the mean SSIM over
7 × 7 windows (Wang et al. 2004, C1 = (0.01 L)², C2 = (0.03 L)², L = 4, the range of
the normalised images). Fails below the floor given.

  blender -b --python-exit-code 1 --python tools/cycles-ref/compare.py -- \
      SCENE.glb OURS.png OUT_DIR WIDTH HEIGHT FLOOR
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


def fail(message):
    print(f"FAIL {message}", file=sys.stderr)
    raise SystemExit(1)


def glb_json(path):
    with open(path, "rb") as f:
        data = f.read()
    length, kind = struct.unpack_from("<II", data, 12)
    if data[:4] != b"glTF" or kind != 0x4E4F534A:
        fail(f"{path} is not a GLB")
    return json.loads(data[20 : 20 + length])


def light_the_scene(extras):
    scene = bpy.context.scene
    cameras = [o for o in scene.objects if o.type == "CAMERA"]
    suns = [o for o in scene.objects if o.type == "LIGHT"]
    if len(cameras) != 1 or len(suns) != 1:
        fail(f"expected one camera and one sun, found {len(cameras)} and {len(suns)}")
    scene.camera = cameras[0]
    sun = suns[0].data
    rgb = extras["sun_rgb"]
    peak = max(rgb)
    sun.color = [c / peak for c in rgb]
    sun.energy = math.pi * extras["sun_strength"] * peak
    sun.angle = math.radians(0.5)
    for material in bpy.data.materials:
        if not material.use_nodes:
            continue
        for node in material.node_tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                node.inputs["Specular"].default_value = 0.0
                node.inputs["Roughness"].default_value = 1.0
    world = bpy.data.worlds.new("sky")
    scene.world = world
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    nodes.clear()
    light = nodes.new("ShaderNodeBackground")
    light.inputs["Color"].default_value = [c * extras["sky_strength"] for c in extras["sky_rgb"]] + [1.0]
    seen = nodes.new("ShaderNodeBackground")
    seen.inputs["Color"].default_value = list(extras["background_rgb"]) + [1.0]
    path = nodes.new("ShaderNodeLightPath")
    mix = nodes.new("ShaderNodeMixShader")
    out = nodes.new("ShaderNodeOutputWorld")
    links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    links.new(light.outputs["Background"], mix.inputs[1])
    links.new(seen.outputs["Background"], mix.inputs[2])
    links.new(mix.outputs["Shader"], out.inputs["Surface"])


def render(out_dir, width, height):
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 128
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 4
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = os.path.join(out_dir, "cycles.png")
    bpy.ops.render.render(write_still=True)
    return scene.render.filepath


def luminance(path, width, height):
    image = bpy.data.images.load(path)
    image.colorspace_settings.name = "Non-Color"
    if tuple(image.size) != (width, height):
        fail(f"{path} is {tuple(image.size)}, not {(width, height)}")
    px = numpy.array(image.pixels[:], dtype=numpy.float64).reshape(height, width, 4)[:, :, :3]
    linear = numpy.where(px <= 0.04045, px / 12.92, ((px + 0.055) / 1.055) ** 2.4)
    y = linear @ numpy.array([0.2126, 0.7152, 0.0722])
    return y / y.mean()


def box(a, k=7):
    """Mean over k × k windows (valid part only), by summed-area tables."""
    s = numpy.pad(a, ((1, 0), (1, 0))).cumsum(0).cumsum(1)
    return (s[k:, k:] - s[:-k, k:] - s[k:, :-k] + s[:-k, :-k]) / (k * k)


def ssim(x, y, dynamic_range=4.0):
    c1, c2 = (0.01 * dynamic_range) ** 2, (0.03 * dynamic_range) ** 2
    mx, my = box(x), box(y)
    vx, vy, cxy = box(x * x) - mx * mx, box(y * y) - my * my, box(x * y) - mx * my
    s = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    return float(s.mean())


def main():
    argv = sys.argv[sys.argv.index("--") + 1 :]
    glb, ours, out_dir, width, height, floor = argv[0], argv[1], argv[2], int(argv[3]), int(argv[4]), float(argv[5])
    extras = glb_json(glb)["scenes"][0]["extras"]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=glb)
    light_the_scene(extras)
    cycles = render(out_dir, width, height)
    a, b = luminance(ours, width, height), luminance(cycles, width, height)
    score = ssim(a, b)
    correlation = float(numpy.corrcoef(a.ravel(), b.ravel())[0, 1])
    with open(os.path.join(out_dir, "cycles-compare.json"), "w") as f:
        json.dump({"ssim": score, "correlation": correlation, "floor": floor}, f)
    print(f"snow renderer vs Cycles: SSIM {score:.3f} (floor {floor}), luminance correlation {correlation:.3f}")
    if not score >= floor:
        fail(f"SSIM {score:.3f} is below the floor {floor}")


main()
