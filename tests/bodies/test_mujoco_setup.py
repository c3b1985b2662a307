"""What a machine that cannot render MuJoCo is told (runs everywhere: no
rendering here)."""
import numpy as np
import pytest

from sensorispace_ros.bodies import mujoco_render


def _without_egl(monkeypatch, backend):
    def missing():
        raise OSError("libEGL.so.1: cannot open shared object file")

    monkeypatch.setenv("MUJOCO_GL", backend)
    monkeypatch.setattr(mujoco_render, "load_egl", missing)
    return mujoco_render.rendering_problem()


def test_no_egl_says_what_to_install(monkeypatch):
    problem = _without_egl(monkeypatch, "egl")
    assert problem is not None and "libEGL.so.1" in problem
    assert "sudo apt-get install -y libegl1 libegl-mesa0 libgl1-mesa-dri" in problem


def test_another_backend_is_not_asked_for_egl(monkeypatch):
    problem = _without_egl(monkeypatch, "osmesa")
    assert problem is None or "EGL" not in problem


def test_the_bootstrap_installs_or_names_the_same_packages():
    from shared import REPO
    text = (REPO / "scripts" / "bootstrap.sh").read_text()
    assert f'EGL_PACKAGES="{mujoco_render.EGL_PACKAGES}"' in text
    assert "apt-get install -y $EGL_PACKAGES" in text


def test_pixels_become_an_image_rows_first():
    from sensorispace_ros import messages
    header = messages.make_header("camera", 5)
    gray = messages.pixels_to_image(np.arange(6.0) * 50, 3, 2, header)
    assert (gray.width, gray.height, gray.encoding, gray.step) == (3, 2, "mono8", 3)
    assert bytes(gray.data) == bytes([0, 50, 100, 150, 200, 250])
    rgb = messages.pixels_to_image(np.arange(18.0), 3, 2, header)
    assert (rgb.encoding, rgb.step, len(rgb.data)) == ("rgb8", 9, 18)
    with pytest.raises(ValueError, match="no 3 x 2 gray or RGB image"):
        messages.pixels_to_image(np.arange(12.0), 3, 2, header)
