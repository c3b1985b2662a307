"""What a machine that cannot render MuJoCo is told (runs everywhere: no
rendering here)."""
import ctypes

from sensorispace_ros.bodies import mujoco_render


def test_no_egl_says_what_to_install(monkeypatch):
    def missing(name, *args, **kwargs):
        raise OSError(f"{name}: cannot open shared object file")

    monkeypatch.setenv("MUJOCO_GL", "egl")
    monkeypatch.setattr(ctypes, "CDLL", missing)
    problem = mujoco_render.rendering_problem()
    assert problem is not None and "libEGL.so.1" in problem
    assert "sudo apt-get install -y libegl1 libegl-mesa0 libgl1-mesa-dri" in problem


def test_another_backend_is_not_asked_for_egl(monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    monkeypatch.setattr(ctypes, "CDLL", lambda *a, **k: (_ for _ in ()).throw(OSError("no")))
    assert mujoco_render.rendering_problem() is None or "EGL" not in \
        mujoco_render.rendering_problem()


def test_the_bootstrap_installs_or_names_the_same_packages():
    from shared import REPO
    text = (REPO / "scripts" / "bootstrap.sh").read_text()
    assert f'EGL_PACKAGES="{mujoco_render.EGL_PACKAGES}"' in text
    assert "apt-get install -y $EGL_PACKAGES" in text
