"""Headless rendering of a MuJoCo camera, sized for many tiny frames.

MuJoCo renders off screen through EGL (``MUJOCO_GL=egl``, set here unless
the environment chose another backend; Debian's ``libegl1``,
``libegl-mesa0`` and ``libgl1-mesa-dri`` on a machine without a GPU, where
Mesa's llvmpipe draws). A frame of a few pixels costs what MuJoCo does
around it, not the pixels: shadows, reflections, the skybox, fog, haze and
multisampling are off, and the frames of a batch are drawn side by side into
one framebuffer (``tiles`` x ``tiles`` viewports) and read back at once.
A ``plane`` geom is drawn as a grid of quads and costs more than the rest of
a small scene together: a model meant to be rendered fast leaves it out (or
puts it in a geom group above 2, which the eye does not draw).
"""
from __future__ import annotations

import atexit
import ctypes
import os

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

EGL_PACKAGES = "libegl1 libegl-mesa0 libgl1-mesa-dri"
INSTALL_HINT = (f"headless rendering needs EGL and Mesa's drivers: sudo apt-get install -y "
                f"{EGL_PACKAGES} (scripts/bootstrap.sh installs them when run as root)")
# Luminance of an RGB sample (ITU-R BT.601 weights).
_LUMA = np.array([0.299, 0.587, 0.114])


def rendering_problem() -> str | None:
    """Why MuJoCo cannot render here (None: it can): the package or EGL is missing."""
    try:
        import mujoco  # noqa: F401
    except ImportError as error:
        return f"the mujoco package is not installed ({error}): bash scripts/bootstrap.sh"
    if os.environ.get("MUJOCO_GL", "egl") == "egl":
        try:
            load_egl()
        except OSError as error:
            return f"no EGL ({error}); {INSTALL_HINT}"
    return None


def load_egl() -> None:
    """Load the EGL library the ``egl`` backend needs (OSError: none here)."""
    ctypes.CDLL("libEGL.so.1")


class TiledRenderer:
    """Frames ``(B, height, width, channels)`` uint8 of camera ``camera_id``
    (top row first), ``channels`` 1 (luminance) or 3 (RGB)."""

    def __init__(self, model, camera_id: int, width: int, height: int, channels: int,
                 tiles: int = 8, supersample: int = 1, blur: float = 0.0):
        import mujoco

        problem = rendering_problem()
        if problem is not None:
            raise RuntimeError(f"MuJoCo cannot render: {problem}")
        self.mujoco = mujoco
        self.supersample = int(supersample)
        self.blur = float(blur)
        self.out_width, self.out_height = int(width), int(height)
        self.filters = (_pixel_filter(self.out_height, self.supersample, blur),
                        _pixel_filter(self.out_width, self.supersample, blur))
        width, height = self.supersample * int(width), self.supersample * int(height)
        self.width, self.height, self.channels = int(width), int(height), int(channels)
        self.tiles = max(1, min(int(tiles), 4096 // max(self.width, self.height)))
        model.vis.quality.offsamples = 0
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, self.width * self.tiles)
        model.vis.global_.offheight = max(model.vis.global_.offheight, self.height * self.tiles)
        try:
            self.gl = mujoco.GLContext(self.width * self.tiles, self.height * self.tiles)
            self.gl.make_current()
            self.context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        except Exception as error:           # EGL errors come as several types
            raise RuntimeError(f"MuJoCo cannot render: {error}; {INSTALL_HINT}") from None
        # Freed before MuJoCo's EGL display is terminated at exit (atexit runs the
        # latest registered first), not by the garbage collector after it.
        atexit.register(self.close)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self.context)
        self.scene = mujoco.MjvScene(model, maxgeom=max(100, 2 * model.ngeom))
        for flag in range(mujoco.mjtRndFlag.mjNRNDFLAG):
            self.scene.flags[flag] = 0
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self.camera.fixedcamid = int(camera_id)
        self.option = mujoco.MjvOption()
        self.buffer = np.empty((self.height * self.tiles, self.width * self.tiles, 3), np.uint8)
        self.frames = 0
        self.model = model

    def close(self) -> None:
        """Free the GL context (idempotent)."""
        context, self.context = getattr(self, "context", None), None
        gl, self.gl = getattr(self, "gl", None), None
        if context is not None:
            context.free()
        if gl is not None:
            gl.free()

    def render(self, data, count: int, pose_row) -> np.ndarray:
        """``count`` frames; ``pose_row(i)`` puts ``data`` in the state of frame
        ``i`` (kinematics and cameras computed) before it is drawn."""
        mujoco = self.mujoco
        self.gl.make_current()
        out = np.empty((count, self.height, self.width, 3), np.uint8)
        per_read = self.tiles * self.tiles
        w, h = self.width, self.height
        for start in range(0, count, per_read):
            stop = min(count, start + per_read)
            for i in range(start, stop):
                pose_row(i)
                tile = i - start
                mujoco.mjv_updateScene(self.model, data, self.option, None, self.camera,
                                       mujoco.mjtCatBit.mjCAT_ALL, self.scene)
                mujoco.mjr_render(mujoco.MjrRect((tile % self.tiles) * w, (tile // self.tiles) * h,
                                                 w, h), self.scene, self.context)
            rows = -(-(stop - start) // self.tiles)
            view = self.buffer[:rows * h]
            mujoco.mjr_readPixels(view, None, mujoco.MjrRect(0, 0, self.tiles * w, rows * h),
                                  self.context)
            # (rows, h, tiles, w, 3) -> frames; OpenGL rows run bottom-up.
            tiles = view.reshape(rows, h, self.tiles, w, 3).swapaxes(1, 2)
            out[start:stop] = tiles.reshape(-1, h, w, 3)[:stop - start, ::-1]
        self.frames += count
        return self._pixels(out)

    def _pixels(self, samples: np.ndarray) -> np.ndarray:
        """The pixels ``(B, height, width, channels)`` uint8 of the rendered
        samples ``(B, k height, k width, 3)``: with ``channels`` 1 the
        luminance of each sample, then each pixel the filtered light of its
        samples (``_pixel_filter``), rounded once."""
        if self.channels == 1:
            planes = (samples @ _LUMA)[:, None]                            # (n, 1, y, x)
        else:
            planes = np.moveaxis(samples, -1, 1).astype(np.float64)        # (n, 3, y, x)
        if self.supersample > 1 or self.blur > 0:
            rows, columns = self.filters
            planes = rows @ planes @ columns.T
        return np.clip(np.rint(np.moveaxis(planes, 1, -1)), 0, 255).astype(np.uint8)

def _pixel_filter(pixels: int, supersample: int, blur: float) -> np.ndarray:
    """``(pixels, supersample * pixels)``: the weights of the samples each pixel
    gathers: its own ``supersample`` samples (the light its area receives),
    spread by a Gaussian of ``blur`` pixels (an out-of-focus lens; 0: none),
    each row summing to 1."""
    samples = (np.arange(pixels * supersample) + 0.5) / supersample
    centres = np.arange(pixels) + 0.5
    if blur > 0:
        weights = np.exp(-0.5 * ((samples[None] - centres[:, None]) / blur) ** 2)
    else:
        weights = (np.abs(samples[None] - centres[:, None]) < 0.5).astype(float)
    return weights / weights.sum(axis=1, keepdims=True)
