"""The notebook-style example runs as written (so it cannot rot)."""

import subprocess
import sys


def test_the_tour_runs(repo, tmp_path):
    done = subprocess.run([sys.executable, str(repo / "python/examples/tour.py"), str(tmp_path)],
                          capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "broken.toml:2:10: scene.frames = 0" in done.stdout
    for name in ("flame_00030.exr", "snow.toml", "geometry.obj"):
        assert (tmp_path / name).is_file()
