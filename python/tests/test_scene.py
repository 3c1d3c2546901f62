"""The module against the ``phenomena`` command: same pixels, same particles, same
volumes, checkpoints that continue bit for bit, errors located as the command locates
them."""

import threading

import numpy as np
import OpenEXR
import pytest

import phenomena
from phenomena._ply import read_ply


def read_exr(path):
    with OpenEXR.File(str(path), separate_channels=True) as f:
        channels = f.channels()
        rgb = np.stack([channels[c].pixels for c in "RGB"], axis=-1)
        others = {name: ch.pixels for name, ch in channels.items() if name not in "RGB"}
    return rgb.astype(np.float32), others


@pytest.mark.parametrize("name, frame", [("flame-paper", 12), ("aurora-scene2", 3), ("sparkle-leaf-glitter", 2)])
def test_render_equals_the_commands_exr(repo, cli, tmp_path, name, frame):
    cli("render", repo / f"scenes/{name}.toml", "--frames", f"{frame}..{frame + 1}", "--width", 64, "--height", 36,
        "--format", "exr", "--out", tmp_path)
    want, want_layers = read_exr(tmp_path / f"frame_{frame:05}.exr")
    scene = phenomena.Scene(repo / f"scenes/{name}.toml")
    image, layers = scene.render(frame, width=64, height=36, layers=True)
    assert image.shape == (36, 64, 3) and image.dtype == np.float32
    assert image.max() > 0, "the frame is not black"
    np.testing.assert_array_equal(image, want)
    assert sorted(layers) == sorted(want_layers)
    for key, plane in layers.items():
        np.testing.assert_array_equal(plane, want_layers[key])


def test_points_equal_the_commands_ply_cache(repo, cli, tmp_path):
    cli("render", repo / "scenes/flame-paper.toml", "--frames", "20..21", "--format", "ply", "--out", tmp_path)
    want = read_ply((tmp_path / "frame_00020.ply").read_bytes())["vertex"]
    scene = phenomena.Scene(repo / "scenes/flame-paper.toml")
    scene.step(21)
    got = scene.points()
    assert len(got["x"]) > 100
    assert sorted(got) == sorted(want)
    for key in want:
        np.testing.assert_array_equal(got[key], want[key])


def test_volume_leaves_are_the_commands_vdb(repo, cli, tmp_path):
    cli("render", repo / "scenes/flame-paper.toml", "--frames", "20..21", "--format", "vdb", "--out", tmp_path)
    scene = phenomena.Scene(repo / "scenes/flame-paper.toml")
    scene.step(21)
    data, manifest = scene.volume_vdb()
    assert data == (tmp_path / "frame_00020.vdb").read_bytes()
    grids = scene.volume()
    assert sorted(grids) == sorted(g["name"] for g in manifest["grids"])
    for entry in manifest["grids"]:
        grid = grids[entry["name"]]
        values = grid.values if grid.values.ndim == 4 else np.linalg.norm(grid.values, axis=-1)
        # The manifest is what OpenVDB reports of the file: active voxels are the
        # non-zero ones, and the leaves hold its smallest and largest value.
        assert np.count_nonzero(values) == entry["active_voxels"]
        flat = grid.values.reshape(len(grid.origins), 512, -1)
        active = flat[np.any(flat != 0, axis=-1)]
        np.testing.assert_array_equal(active.min(axis=0), np.atleast_1d(entry["min"]))
        np.testing.assert_array_equal(active.max(axis=0), np.atleast_1d(entry["max"]))
        dense, lo = grid.to_dense()
        assert dense.sum() == pytest.approx(float(grid.values.sum(dtype=np.float64)), rel=1e-5)
        assert np.all(lo % 8 == 0)


def test_a_checkpoint_continues_bit_for_bit(repo):
    path = repo / "scenes/flame-paper.toml"
    first = phenomena.Scene(path)
    first.step(10)
    checkpoint = first.state()
    straight = first.render(19, width=48, height=27)
    second = phenomena.Scene(path)
    assert second.restore(checkpoint) == 10
    np.testing.assert_array_equal(second.render(19, width=48, height=27), straight)


def test_a_passed_frame_and_a_new_size_give_a_fresh_renders_pixels(repo):
    path = repo / "scenes/flame-paper.toml"
    scene = phenomena.Scene(path)
    scene.render(15, width=32, height=18)
    back = scene.render(8, width=32, height=18)  # behind the state: simulated again
    np.testing.assert_array_equal(back, phenomena.Scene(path).render(8, width=32, height=18))
    resized = scene.render(8, width=40, height=20)  # same state, new size
    np.testing.assert_array_equal(resized, phenomena.Scene(path).render(8, width=40, height=20))
    assert scene.frames_done == 9


def test_errors_carry_the_file_line_and_column():
    text = "[scene]\nframes = 10\n\n[flame]\nmode = \"paper\"\n[flame.emitter]\nrate_per_s = -5.0\n"
    with pytest.raises(phenomena.SceneError) as caught:
        phenomena.Scene.from_toml(text, name="fire.toml")
    (problem,) = caught.value.problems
    assert (problem.file, problem.line) == ("fire.toml", 7)
    assert "rate_per_s" in problem.message and str(problem) in str(caught.value)
    with pytest.raises(phenomena.SceneError) as caught:
        phenomena.Scene.from_toml("[scene]\nwidth = 'wide'\n[flame]\n", name="w.toml")
    assert caught.value.problems[0][:3] == ("w.toml", 2, 9)


def test_a_missing_file_is_located_before_anything_is_built(tmp_path):
    scene = phenomena.Scene.from_toml("[scene]\n[geometry]\nmesh = \"gone.obj\"\n[snow]\n", name="s.toml", files={})
    with pytest.raises(phenomena.SceneError) as caught:
        scene.validate()
    assert caught.value.problems[0][:3] == ("s.toml", 3, 8)
    with pytest.raises(phenomena.SceneError):
        scene.step()


def test_progress_is_reported_and_can_stop_the_work(repo):
    scene = phenomena.Scene(repo / "scenes/flame-paper.toml")
    seen = []
    scene.step(5, progress=lambda done, total: seen.append((done, total)))
    assert [d for d, _ in seen] == [1, 2, 3, 4, 5]
    with pytest.raises(KeyboardInterrupt):
        scene.render(40, width=32, height=18, progress=lambda done, total: done < 3)
    assert scene.frames_done == 8  # stopped after three more frames
    with pytest.raises(ZeroDivisionError):
        scene.step(2, progress=lambda done, total: 1 / 0)


def test_the_gil_is_released_while_rendering(repo):
    scene = phenomena.Scene(repo / "scenes/aurora-scene2.toml")
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(1)
            stop.wait(0.001)

    thread = threading.Thread(target=count)
    thread.start()
    scene.render(4, width=320, height=180)
    stop.set()
    thread.join()
    # With the GIL held for the whole render the other thread would not run at all
    # until it returned; it ran throughout (a render of five aurora frames takes well
    # over 20 ms here).
    assert len(ticks) > 10


def test_exports_and_the_starters():
    names = {p["name"] for p in phenomena.phenomena()}
    assert {"flame", "aurora", "snow", "sparkle"} <= names
    scene = phenomena.Scene.from_toml(phenomena.starter("snow"), name="snow.toml")
    assert scene.phenomenon == "snow" and scene.frames == 120
    scene.step(3)
    glb = scene.export("snow-mesh")
    assert glb[:4] == b"glTF"
    mesh = scene.mesh()
    assert mesh["positions"].shape[1] == 3 and mesh["triangles"].max() < len(mesh["positions"])
    with pytest.raises(ValueError):
        scene.export("flame-volume")


def test_save_exr_writes_the_commands_file(repo, cli, tmp_path):
    cli("render", repo / "scenes/aurora-scene2.toml", "--frames", "2..3", "--width", 48, "--height", 27,
        "--format", "exr", "--out", tmp_path)
    scene = phenomena.Scene(repo / "scenes/aurora-scene2.toml")
    scene.save_exr(tmp_path / "mine.exr", 2, width=48, height=27)
    assert (tmp_path / "mine.exr").read_bytes() == (tmp_path / "frame_00002.exr").read_bytes()
    with pytest.raises(ValueError, match="frame"):
        scene.render(5_000_000)


def afterglow_aurora(frames=12):
    import re

    text = re.sub(r"^frames = \d+", f"frames = {frames}", phenomena.starter("aurora"), flags=re.M)
    text = text.replace("afterglow = false", "afterglow = true")
    return phenomena.Scene.from_toml(text, name="glow.toml")


def test_frames_that_depend_on_earlier_renders_match_a_straight_render():
    # The afterglow carries light from frame to frame: step() renders what it steps,
    # as the command does, so stepping then rendering equals rendering at once.
    stepped = afterglow_aurora()
    stepped.step(3)
    a = stepped.render(5, width=32, height=18)
    b = afterglow_aurora().render(5, width=32, height=18)
    np.testing.assert_array_equal(a, b)
    # The default frame is the current state's, also when a new size starts again.
    stepped.step(2)
    np.testing.assert_array_equal(stepped.render(width=40, height=20),
                                  afterglow_aurora().render(7, width=40, height=20))
    assert stepped.frames_done == 8


def test_a_size_that_cannot_be_built_changes_nothing(repo):
    scene = phenomena.Scene(repo / "scenes/flame-paper.toml", max_memory_gib=0.5)
    before = scene.render(4, width=32, height=18)
    with pytest.raises(phenomena.SceneError, match="memory"):
        scene.render(4, width=16000, height=16000)
    assert scene.size == (32, 18) and scene.frames_done == 5
    np.testing.assert_array_equal(scene.render(4), before)


def test_a_progress_callback_cannot_use_its_own_scene_and_threads_take_turns(repo):
    scene = phenomena.Scene(repo / "scenes/flame-paper.toml")
    with pytest.raises(RuntimeError, match="busy"):
        scene.step(2, progress=lambda done, total: scene.frames_done)
    # A second thread waits for the first's call instead of deadlocking on the GIL.
    results = []
    worker = threading.Thread(target=lambda: results.append(scene.render(40, width=64, height=36).shape))
    worker.start()
    seen = [scene.frames_done for _ in range(20)]
    worker.join(timeout=120)
    assert not worker.is_alive() and results == [(36, 64, 3)]
    assert all(0 <= s <= 41 for s in seen) and scene.frames_done == 41
