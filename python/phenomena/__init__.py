"""phenomena from Python: scene files rendered and simulated by the same code as the
``phenomena`` command, frames as numpy arrays of linear radiance, state and exports.

>>> import phenomena
>>> scene = phenomena.Scene("scenes/flame-paper.toml")      # doctest: +SKIP
>>> image = scene.render(frame=30, width=320, height=180)   # (180, 320, 3) float32
>>> cache = scene.points()                                  # {"x": array, ...}

Snow on geometry held in memory (no files)::

    cover = phenomena.snow_cover(vertices, triangles, hours=2.0)
    cover.positions, cover.normals, cover.triangles

Long calls release the GIL; ``progress(done, total)`` is called between frames and
stops the work by returning ``False``; Ctrl+C stops it between frames.
"""

import json
import os
from dataclasses import dataclass
from typing import Callable, Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np

from . import _native
from ._errors import Problem, SceneError
from ._ply import read_ply

__all__ = ["Scene", "SceneError", "Problem", "Grid", "SnowCover", "snow_cover", "phenomena", "starter"]

Progress = Optional[Callable[[int, int], Optional[bool]]]


def _budget(max_memory_gib: Optional[float]) -> Optional[int]:
    """The memory budget in bytes: ``max_memory_gib``, or three quarters of the
    machine's memory as the ``phenomena`` command allows by default."""
    if max_memory_gib is not None:
        if not (max_memory_gib > 0 and np.isfinite(max_memory_gib)):
            raise ValueError(f"max_memory_gib {max_memory_gib} is out of range: expected a positive number")
        return int(max_memory_gib * (1 << 30))
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") // 4 * 3
    except (ValueError, OSError, AttributeError):
        return None


def phenomena() -> List[dict]:
    """The phenomena a scene can hold: name, what it is, its exports."""
    return json.loads(_native.phenomena())


def starter(name: str) -> str:
    """A phenomenon's starter scene (every default, commented), as ``phenomena new`` writes."""
    return _native.starter(name)


@dataclass
class Grid:
    """One grid of a volume as OpenVDB holds it: 8x8x8 leaves at ``origins`` (voxel
    indices, (N, 3) int32) with ``values`` (N, 8, 8, 8) float32 (or (N, 8, 8, 8, 3) for
    a vector grid), indexed [leaf, i, j, k]; voxel (i, j, k) lies at
    ``translation_m + voxel_m * (i, j, k)`` metres."""

    name: str
    grid_class: str
    voxel_m: float
    translation_m: Tuple[float, float, float]
    origins: np.ndarray
    values: np.ndarray

    def to_dense(self) -> Tuple[np.ndarray, np.ndarray]:
        """The grid as one dense array over its leaves' bounding box, indexed [i, j, k]
        (zero outside the leaves), and the voxel index of its [0, 0, 0]."""
        tail = self.values.shape[4:]
        if len(self.origins) == 0:
            return np.zeros((0, 0, 0) + tail, np.float32), np.zeros(3, np.int32)
        lo = self.origins.min(axis=0)
        hi = self.origins.max(axis=0) + 8
        dense = np.zeros(tuple(hi - lo) + tail, np.float32)
        for origin, leaf in zip(self.origins - lo, self.values):
            i, j, k = origin
            dense[i:i + 8, j:j + 8, k:k + 8] = leaf
        return dense, lo


class Scene:
    """A scene file as ``phenomena`` reads it, with its simulation and renderer.

    ``Scene(path)`` reads a file (files it names are read beside it);
    :meth:`Scene.from_toml` takes the text. Problems raise :class:`SceneError` with each
    problem's file, line and column. ``max_memory_gib`` is the memory budget (default:
    three quarters of the machine's, as the command's).
    """

    def __init__(self, path: "os.PathLike[str] | str", *, max_memory_gib: Optional[float] = None):
        self._native = _native.NativeScene.load(os.fspath(path), _budget(max_memory_gib))
        self.path = os.fspath(path)

    @classmethod
    def from_toml(
        cls,
        text: str,
        *,
        name: str = "scene.toml",
        files: Optional[Dict[str, bytes]] = None,
        base_dir: "Optional[os.PathLike[str] | str]" = None,
        max_memory_gib: Optional[float] = None,
    ) -> "Scene":
        """A scene from its TOML text; ``name`` names it in messages. The files it names
        come from ``files`` (name to bytes: no file is read) or from ``base_dir``
        (default: the folder of ``name``)."""
        scene = cls.__new__(cls)
        base = os.fspath(base_dir) if base_dir is not None else None
        files = {k: bytes(v) for k, v in files.items()} if files is not None else None
        scene._native = _native.NativeScene.from_toml(text, name, files, base, _budget(max_memory_gib))
        scene.path = None
        return scene

    def _info(self) -> dict:
        return json.loads(self._native.info())

    @property
    def phenomenon(self) -> str:
        """``flame``, ``aurora``, ``snow``, ``sparkle`` or ``shot``."""
        return self._info()["phenomenon"]

    @property
    def settings(self) -> dict:
        """The ``[scene]`` table: frames, width, height, seed, exposure, tone map."""
        return self._info()["scene"]

    @property
    def frames(self) -> int:
        """Frames the scene renders (``[scene] frames``)."""
        return self.settings["frames"]

    @property
    def size(self) -> Tuple[int, int]:
        """Width and height, pixels."""
        s = self.settings
        return s["width"], s["height"]

    @property
    def frame_time_s(self) -> float:
        """Simulated seconds per frame."""
        return self._info()["frame_time_s"]

    @property
    def exports(self) -> List[dict]:
        """What :meth:`export` can write: name, what it holds, formats."""
        return self._info()["exports"]

    @property
    def frames_done(self) -> int:
        """Frames simulated so far."""
        return self._native.frames_done()

    def to_dict(self) -> dict:
        """The scene's tables."""
        return json.loads(self._native.to_json())

    def to_toml(self) -> str:
        """The scene as TOML text (what ``phenomena`` reads)."""
        return self._native.to_toml()

    def with_value(self, path: str, value) -> "Scene":
        """A new scene with ``path`` (``"snow.repose_deg"``) set to ``value``, validated
        (its simulation starts from frame 0)."""
        scene = Scene.__new__(Scene)
        scene._native = self._native.with_value(path, json.dumps(value))
        scene.path = self.path
        return scene

    def validate(self) -> dict:
        """Everything ``phenomena validate`` checks, without building the simulation;
        raises :class:`SceneError`. Returns warnings and the memory estimate."""
        return json.loads(self._native.validate())

    def warnings(self) -> List[str]:
        """Warnings found while building (a scene that can show nothing, ...)."""
        return self._native.warnings()

    def step(self, count: int = 1, progress: Progress = None) -> List[dict]:
        """Simulate ``count`` frames; returns each frame's record (timings, counters)."""
        return [json.loads(r) for r in self._native.step(count, progress)]

    def render(
        self,
        frame: Optional[int] = None,
        *,
        width: Optional[int] = None,
        height: Optional[int] = None,
        layers: bool = False,
        progress: Progress = None,
    ):
        """Frame ``frame`` (the state after ``frame + 1`` steps, as the command numbers
        frames; default the current state) as linear radiance, (H, W, 3) float32: the
        RGB of the command's EXR of that frame. Simulates forward as needed; a frame
        already passed is simulated again from frame 0. A new ``width``/``height`` keeps
        the simulation's state and becomes the scene's size (:attr:`size`) for later
        calls. With ``layers``, also the renderer's extra planes (the EXR's other
        channels) by name."""
        rgb, w, h, extra = self._native.render(frame, width, height, progress)
        image = np.frombuffer(rgb, dtype="<f4").reshape(h, w, 3)
        if not layers:
            return image
        return image, {name: np.frombuffer(v, dtype="<f4").reshape(h, w) for name, v in extra}

    def save_exr(
        self,
        path: "os.PathLike[str] | str",
        frame: Optional[int] = None,
        *,
        width: Optional[int] = None,
        height: Optional[int] = None,
        layers: bool = True,
        progress: Progress = None,
    ) -> None:
        """Render as :meth:`render` and write the frame as the ``exr`` format does
        (32-bit float linear RGB with, unless ``layers`` is false, the renderer's
        layers: an RGB-only file is what an environment texture wants), atomically."""
        self._native.save_exr(os.fspath(path), frame, width, height, progress, layers)

    def iter_frames(self, start: int = 0, stop: Optional[int] = None, **render) -> Iterator[Tuple[int, np.ndarray]]:
        """``(frame, image)`` for frames ``start`` to ``stop`` (default the scene's
        frames), simulating forward."""
        for frame in range(start, self.frames if stop is None else stop):
            yield frame, self.render(frame, **render)

    def state(self) -> bytes:
        """The whole simulation state as a checkpoint file (what ``--checkpoint-every``
        writes)."""
        return self._native.state()

    def restore(self, checkpoint: bytes) -> int:
        """Continue from a checkpoint of this scene; returns the frames simulated."""
        return self._native.restore(bytes(checkpoint))

    def points(self) -> Dict[str, np.ndarray]:
        """The particles now, one array per column (the ``ply`` format's cache:
        flame x, y, z, vx, vy, vz, temperature, density, id; aurora feet, ...)."""
        return read_ply(self._native.points())["vertex"]

    def export(self, name: str, format: Optional[str] = None) -> bytes:
        """Export ``name`` (see :attr:`exports`) of the current state as a file's bytes,
        as ``phenomena export`` writes it; ``format`` defaults to the export's first."""
        if format is None:
            kinds = [e for e in self.exports if e["name"] == name]
            if not kinds:
                raise ValueError(f"{self.phenomenon} scenes export {[e['name'] for e in self.exports]}, not {name!r}")
            format = kinds[0]["formats"][0]
        data, _summary = self._native.export(name, format)
        return data

    def mesh(self, name: str = "snow-mesh") -> Dict[str, np.ndarray]:
        """A mesh export as arrays: ``positions`` (N, 3), ``normals`` (N, 3) float32,
        ``triangles`` (M, 3) uint32 (metres, y up)."""
        ply = read_ply(self._native.export(name, "ply")[0])
        v = ply["vertex"]
        return {
            "positions": np.stack([v["x"], v["y"], v["z"]], axis=1),
            "normals": np.stack([v["nx"], v["ny"], v["nz"]], axis=1),
            "triangles": ply["face"]["vertex_indices"].reshape(-1, 3),
        }

    def volume(self, voxel_m: Optional[float] = None) -> Dict[str, Grid]:
        """The volume of the current state (the ``vdb`` format's grids) by name."""
        _manifest, grids, _ = self._native.volume(voxel_m, False)
        out = {}
        for name, grid_class, components, voxel, translation, origins, values in grids:
            origins = np.frombuffer(origins, dtype="<i4").reshape(-1, 3)
            shape = (len(origins), 8, 8, 8) + ((3,) if components == 3 else ())
            out[name] = Grid(name, grid_class, voxel, tuple(translation), origins,
                             np.frombuffer(values, dtype="<f4").reshape(shape))
        return out

    def volume_vdb(self, voxel_m: Optional[float] = None) -> Tuple[bytes, dict]:
        """The volume of the current state as a ``.vdb`` file's bytes and its manifest."""
        manifest, _, data = self._native.volume(voxel_m, True)
        return data, json.loads(manifest)

    def __repr__(self) -> str:
        w, h = self.size
        where = f" from {self.path!r}" if self.path else ""
        return f"<phenomena.Scene {self.phenomenon}{where}: {self.frames} frames at {w}x{h}, {self.frames_done} done>"


@dataclass
class SnowCover:
    """Snow on a mesh: the closed snow solids as ``positions`` (N, 3), ``normals``
    (N, 3) float32 and ``triangles`` (M, 3) uint32, in metres (the input times its
    ``scale``) with the input's axes, and the scene that made them (``scene_toml``
    naming ``geometry.obj``, whose bytes are ``geometry_obj``):
    ``phenomena export snow-mesh snow.toml --time-h HOURS`` of that scene writes the
    same snow."""

    positions: np.ndarray
    normals: np.ndarray
    triangles: np.ndarray
    hours: float
    steps: int
    scene_toml: str
    geometry_obj: bytes


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float, np.integer, np.floating)):
        return repr(float(value)) if isinstance(value, (float, np.floating)) else str(int(value))
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise ValueError(f"cannot write {value!r} in a scene file")


def obj_text(vertices, triangles, objects: Optional[Sequence[int]] = None) -> bytes:
    """Wavefront OBJ of a triangle mesh, one ``o`` group per object id (what the snow
    uses to group surfaces); coordinates written exactly (float32 round trip)."""
    v = np.asarray(vertices, dtype=np.float32).reshape(-1, 3)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if len(t) and (t.min() < 0 or t.max() >= len(v)):
        raise ValueError(f"triangles index vertices 0..{len(v) - 1}, got {t.min()}..{t.max()}")
    ids = np.zeros(len(t), np.int64) if objects is None else np.asarray(objects, dtype=np.int64).reshape(-1)
    if len(ids) != len(t):
        raise ValueError(f"objects has {len(ids)} ids for {len(t)} triangles")
    lines = ["# geometry for phenomena's snow"]
    lines += ["v %.9g %.9g %.9g" % (x, y, z) for x, y, z in v.tolist()]
    for obj in sorted(set(ids.tolist())):
        lines.append(f"o object_{obj}")
        lines += ["f %d %d %d" % (a + 1, b + 1, c + 1) for a, b, c in t[ids == obj].tolist()]
    return ("\n".join(lines) + "\n").encode()


def snow_cover(
    vertices,
    triangles,
    objects: Optional[Sequence[int]] = None,
    *,
    hours: Optional[float] = None,
    depth_cm: Optional[float] = None,
    seed: int = 1,
    scale: float = 1.0,
    snow: Optional[dict] = None,
    progress: Progress = None,
    max_memory_gib: Optional[float] = None,
) -> SnowCover:
    """Snow on a mesh held in memory: ``vertices`` (N, 3) and ``triangles`` (M, 3) in
    metres (times ``scale``) with y up, ``objects`` an object id per triangle (default:
    one object). The snow falls for ``hours`` (or until ``depth_cm`` has fallen at the
    rate; default 1.2 h, twelve steps of 0.1 h), with ``snow`` any ``[snow]`` keys
    (``repose_deg``, ``main_tilt_deg`` for wind, ``map_resolution``, ...). Goes through
    the same scene layer as ``phenomena export snow-mesh`` of the scene it returns."""
    table = dict(snow or {})
    rate = float(table.get("rate_cm_per_h", 2.0))
    dt_h = float(table.get("time_step_h", 0.1))
    if hours is not None and depth_cm is not None:
        raise ValueError("give hours or depth_cm, not both")
    if depth_cm is not None:
        if not (depth_cm >= 0 and rate > 0):
            raise ValueError(f"depth_cm {depth_cm} is out of range: expected >= 0 (with a positive rate_cm_per_h)")
        hours = depth_cm / rate
    if hours is None:
        hours = 12 * dt_h
    if not (0 <= hours <= 1e5) or not dt_h > 0:
        raise ValueError(f"hours {hours} is out of range: expected hours in [0, 100000]")
    steps = int(round(hours / dt_h))
    lines = [
        "# Snow on a mesh from Python (phenomena.snow_cover).",
        "[scene]",
        f"frames = {max(steps, 1)}",
        f"seed = {int(seed)}",
        "[geometry]",
        'mesh = "geometry.obj"',
        f"scale = {_toml_value(float(scale))}",
        "[snow]",
    ] + [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    text = "\n".join(lines) + "\n"
    geometry = obj_text(vertices, triangles, objects)
    scene = Scene.from_toml(text, name="snow.toml", files={"geometry.obj": geometry}, max_memory_gib=max_memory_gib)
    if steps:
        scene.step(steps, progress)
    mesh = scene.mesh("snow-mesh")
    return SnowCover(mesh["positions"], mesh["normals"], mesh["triangles"], hours, steps, text, geometry)
