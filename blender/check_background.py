"""The add-on's background work in a Blender with a window (run by .ci/run under Xvfb):

    PHENOMENA_PYTHON_PATH=SITE xvfb-run -a blender --factory-startup --enable-event-simulate \\
        --python blender/check_background.py

An operator invoked from the interface runs in a thread while Blender keeps drawing
(its timer keeps firing), shows progress, is cancelled by Esc leaving no object, and
when left to finish makes its object. Exits with status 1 on any failure.
"""

import os
import sys
import tempfile
import time

import addon_utils
import bpy

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
state = {"phase": "start", "ticks": 0}


def fail(message):
    print(f"FAILED: {message}", flush=True)
    os._exit(1)


def enable():
    scripts = tempfile.mkdtemp(prefix="phenomena-scripts-")
    os.makedirs(os.path.join(scripts, "addons"))
    os.symlink(os.path.join(REPO, "blender", "phenomena_blender"), os.path.join(scripts, "addons", "phenomena_blender"))
    bpy.context.preferences.filepaths.script_directory = scripts
    bpy.utils.refresh_script_paths()
    addon_utils.modules_refresh()
    bpy.ops.preferences.addon_enable(module="phenomena_blender")


def snow_objects():
    return [o for o in bpy.data.objects if o.get("phenomena_snow")]


def invoke(hours):
    window = bpy.context.window_manager.windows[0]
    area = next(a for a in window.screen.areas if a.type == "VIEW_3D")
    bpy.context.scene.phenomena_snow.hours = hours
    with bpy.context.temp_override(window=window, area=area):
        result = bpy.ops.phenomena.snow_cover("INVOKE_DEFAULT")
    if result != {"RUNNING_MODAL"}:
        fail(f"invoked from the interface the operator runs in the background (it returned {result})")
    print("ok: the operator runs in the background", flush=True)
    return window


def tick():
    state["ticks"] += 1
    phase = state["phase"]
    if phase == "start":
        window = bpy.context.window_manager.windows[0]
        area = next(a for a in window.screen.areas if a.type == "VIEW_3D")
        for obj in list(bpy.data.objects):
            bpy.data.objects.remove(obj)
        with bpy.context.temp_override(window=window, area=area):
            bpy.ops.mesh.primitive_plane_add(size=4.0)
            bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.0, 0.0, 0.5))
        bpy.context.scene.phenomena_snow.resolution = 256
        invoke(hours=500.0)  # long: 5000 steps
        state.update(phase="cancel", since=time.time(), ticks=0)
        return 0.5
    if phase == "cancel":
        # Blender kept running its timers while the snow fell; now Esc.
        if state["ticks"] < 3:
            return 0.5
        bpy.context.window_manager.windows[0].event_simulate(type="ESC", value="PRESS")
        state.update(phase="cancelled", since=time.time())
        return 0.5
    if phase == "cancelled":
        if time.time() - state["since"] > 60:
            fail("Esc did not stop the work within a minute")
        if bpy.context.window_manager.is_interface_locked:
            return 0.2
        if any(t.name.startswith("Thread") and t.is_alive() and t.daemon for t in __import__("threading").enumerate()):
            return 0.2
        if snow_objects():
            fail("a cancelled snow cover left a snow object")
        print(f"ok: Esc cancels the work and leaves no object ({state['ticks']} timer ticks while it ran)", flush=True)
        invoke(hours=1.0)
        state.update(phase="finish", since=time.time(), ticks=0)
        return 0.2
    if phase == "finish":
        if snow_objects():
            print(f"ok: left to finish, it makes the snow ({len(snow_objects()[0].data.vertices)} vertices, "
                  f"{state['ticks']} timer ticks while it ran)", flush=True)
            print("phenomena add-on background work: every check passed", flush=True)
            os._exit(0)
        if time.time() - state["since"] > 120:
            fail("the snow did not appear within two minutes")
        return 0.2
    return None


enable()
bpy.app.timers.register(tick, first_interval=1.0)
