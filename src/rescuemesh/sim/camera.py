"""Forward RGB cameras of the ground robots, rendered offscreen by MuJoCo (OpenGL; EGL when headless).

Owns: CameraConfig, the choice of GL backend, one offscreen renderer per World (made on the first
image) and the capture of one robot's image. Must not know when images are asked for nor who
reads them (the World wires `SimBody.camera()` to `Cameras.capture`).
"""

# Theory of operation
# ===================
#
# Every ground robot's MJCF carries a fixed <camera> (`mjcf.camera_name`), at the front edge of the
# robot, CAMERA_HEIGHT above the floor, looking along the robot's x axis. Nothing is rendered until a
# brain asks: `capture(robot, stamp)` refreshes the kinematics of the current state (the World's
# MjData holds those of the start of the last physics step), renders that camera into an offscreen
# buffer and reads the pixels back. It does not touch qpos, qvel or anything a physics step reads,
# so taking pictures never changes a trajectory.
#
# The GL context. `mujoco.Renderer` picks its OpenGL backend once, when `mujoco` is imported, from
# MUJOCO_GL, and without it falls back to GLFW, which needs a display. A GLFW failure inside
# mjr_makeContext can leave the process unable to make any other context (we saw a later EGL
# attempt abort the interpreter). So this module does the few calls of mujoco.Renderer itself, with
# a backend chosen when the first camera is used: MUJOCO_GL if set (egl, osmesa, glfw; "disable"
# means no rendering), else EGL on a Linux without DISPLAY or WAYLAND_DISPLAY, else GLFW. Any
# failure becomes NoRendererError, which `Body.camera()` passes to the brain; a World whose renderer
# failed never tries again, and after a failure inside MuJoCo's own context set-up no World in the
# process tries again (the reason above).

from __future__ import annotations

import importlib
import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from rescuemesh.body import CameraImage, NoRendererError
from rescuemesh.geometry import Pose2D
from rescuemesh.sim import mjcf

__all__ = ["CameraConfig", "Cameras", "NoRendererError", "OffscreenRenderer", "gl_backend", "make_renderer"]

_DISABLED = frozenset({"disable", "disabled", "off", "false", "0"})
_AUTO = frozenset({"", "enable", "enabled", "on", "true", "1"})
_BACKEND_MODULES = {"egl": "mujoco.egl", "osmesa": "mujoco.osmesa", "glfw": "mujoco.glfw", "glx": "mujoco.glfw",
                    "cgl": "mujoco.cgl"}
#: Set when MuJoCo's own context set-up failed once in this process: nothing is tried again after it.
_process_failure: str | None = None


@dataclass(frozen=True)
class CameraConfig:
    """The forward camera of every ground robot.

    - `width`, `height`: image size in pixels (160 x 120: rendering and the radio both cost per pixel).
    - `fov_h`: horizontal field of view in rad (58 deg, between a Kinect's 57 and an Astra's 60);
      the vertical one follows from the aspect ratio (45.1 deg at 4:3; Kinect 43, Astra 49.5).
    - `shadows`: render shadows (off: a shadow map costs more than the scene at this size).
    - `multisamples`: MSAA samples of the offscreen buffer (4, MuJoCo's default; 0 is a little faster).
    """

    width: int = 160
    height: int = 120
    fov_h: float = mjcf.CAMERA_FOV_H
    shadows: bool = False
    multisamples: int = 4

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if not (isinstance(value, int) and 8 <= value <= 4096):
                raise ValueError(f"CameraConfig.{name} must be an int in 8..4096 pixels, got {value!r}")
        if not (math.isfinite(self.fov_h) and 0.0 < self.fov_h < math.pi):
            raise ValueError(f"CameraConfig.fov_h must be in (0, pi) rad, got {self.fov_h!r}")
        if not (isinstance(self.multisamples, int) and 0 <= self.multisamples <= 16):
            raise ValueError(f"CameraConfig.multisamples must be an int in 0..16, got {self.multisamples!r}")

    @property
    def fovy_deg(self) -> float:
        """Vertical field of view in degrees (what MuJoCo's camera takes) for `fov_h` at this aspect ratio."""
        return 2.0 * math.degrees(math.atan(math.tan(0.5 * self.fov_h) * self.height / self.width))


def gl_backend() -> str:
    """The OpenGL backend the next renderer will use: 'egl', 'osmesa', 'glfw', 'cgl' or 'disabled'."""
    value = os.environ.get("MUJOCO_GL", "").strip().lower()
    if value in _DISABLED:
        return "disabled"
    if value in _AUTO:
        if sys.platform == "darwin":
            return "cgl"
        display = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
        headless = sys.platform.startswith("linux") and not display
        return "egl" if headless else "glfw"
    return "glfw" if value == "glx" else value


class OffscreenRenderer:
    """One OpenGL context, MuJoCo scene and offscreen buffer, rendering fixed cameras of one model.

    What `mujoco.Renderer` does for RGB, with the GL context handed in (see the module comment).
    """

    def __init__(self, model: mujoco.MjModel, width: int, height: int, gl_context, *, shadows: bool = False) -> None:
        self._gl = gl_context
        self._con: mujoco.MjrContext | None = None
        self.width, self.height = width, height
        self._rect = mujoco.MjrRect(0, 0, width, height)
        self._scene = mujoco.MjvScene(model, maxgeom=max(1000, 2 * model.ngeom))
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = int(shadows)
        self._option = mujoco.MjvOption()
        self._option.geomgroup[:] = 1  # the floor, wheels and casters sit in a group hidden by default
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._pixels = np.empty((height, width, 3), dtype=np.uint8)
        gl_context.make_current()
        self._con = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_100.value)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN.value, self._con)

    def render(self, model: mujoco.MjModel, data: mujoco.MjData, camera_id: int) -> np.ndarray:
        """RGB (height, width, 3) uint8 of fixed camera `camera_id`, row 0 at the top."""
        if self._con is None:
            raise NoRendererError("the renderer was closed")
        self._gl.make_current()
        self._camera.fixedcamid = camera_id
        mujoco.mjv_updateScene(model, data, self._option, None, self._camera, mujoco.mjtCatBit.mjCAT_ALL.value,
                               self._scene)
        mujoco.mjr_render(self._rect, self._scene, self._con)
        mujoco.mjr_readPixels(self._pixels, None, self._rect, self._con)
        return np.flipud(self._pixels).copy()  # OpenGL reads bottom-up

    def close(self) -> None:
        """Free the MuJoCo render context and the GL context (idempotent)."""
        con, self._con = self._con, None
        gl, self._gl = self._gl, None
        try:
            if con is not None and gl is not None:
                gl.make_current()
                con.free()
        finally:
            if gl is not None:
                gl.free()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - at interpreter exit the GL library may be gone already
            pass


def make_renderer(model: mujoco.MjModel, width: int, height: int, *, shadows: bool = False,
                  multisamples: int = 4) -> OffscreenRenderer:
    """An offscreen renderer of `width` x `height` pixels for `model`, or NoRendererError saying why not.

    Enlarges the model's offscreen buffer (`model.vis.global_.offwidth/offheight`) when it is smaller.
    """
    global _process_failure
    backend = gl_backend()
    if backend == "disabled":
        raise NoRendererError(f"rendering is disabled (MUJOCO_GL={os.environ.get('MUJOCO_GL')!r})")
    if _process_failure is not None:
        raise NoRendererError(f"an earlier OpenGL set-up failed in this process: {_process_failure}")
    module = _BACKEND_MODULES.get(backend)
    if module is None:
        raise NoRendererError(f"unknown OpenGL backend MUJOCO_GL={backend!r} (use egl, osmesa or glfw)")
    vis = model.vis.global_
    vis.offwidth, vis.offheight = max(vis.offwidth, width), max(vis.offheight, height)
    model.vis.quality.offsamples = multisamples
    try:
        gl_context = importlib.import_module(module).GLContext(width, height)
    except Exception as exc:  # noqa: BLE001 - ImportError, OSError, RuntimeError, AttributeError ... all mean "no GL"
        raise NoRendererError(f"cannot create an OpenGL context with {backend} ({type(exc).__name__}: {exc}); "
                              "headless machines need EGL (MUJOCO_GL=egl) or OSMesa") from exc
    try:
        return OffscreenRenderer(model, width, height, gl_context, shadows=shadows)
    except Exception as exc:  # noqa: BLE001 - mujoco.FatalError and friends
        _process_failure = f"{backend}: {type(exc).__name__}: {exc}"
        try:
            gl_context.free()
        except Exception:  # noqa: BLE001
            pass
        raise NoRendererError(f"MuJoCo could not render with {backend} ({type(exc).__name__}: {exc})") from exc


class Cameras:
    """The forward cameras of the ground robots of one World, sharing one renderer made on first use.

    `robots`: names whose MJCF carries `mjcf.camera_name(robot)`. Sets every one of those cameras'
    vertical field of view for `config` (so any image size keeps `config.fov_h`).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, robots: Sequence[str], config: CameraConfig) -> None:
        self.config = config
        self._model, self._data = model, data
        self._ids = {name: model.camera(mjcf.camera_name(name)).id for name in robots}
        for cam_id in self._ids.values():
            model.cam_fovy[cam_id] = config.fovy_deg
        self._renderer: OffscreenRenderer | None = None
        self._failure: NoRendererError | None = None

    @property
    def robots(self) -> list[str]:
        return list(self._ids)

    def capture(self, robot: str, stamp: float) -> CameraImage:
        """What `robot`'s camera sees in the current state, stamped `stamp` s. NoRendererError if no GL."""
        cam_id = self._ids[robot]
        if self._renderer is None:
            if self._failure is not None:
                raise self._failure
            cfg = self.config
            try:
                self._renderer = make_renderer(self._model, cfg.width, cfg.height, shadows=cfg.shadows,
                                               multisamples=cfg.multisamples)
            except NoRendererError as exc:
                self._failure = exc
                raise
        m, d = self._model, self._data
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)
        rgb = self._renderer.render(m, d, cam_id)
        pos, xmat = d.cam_xpos[cam_id], d.cam_xmat[cam_id].reshape(3, 3)
        # A MuJoCo camera looks along its -z axis: the third column of its orientation matrix, negated.
        yaw = math.atan2(-float(xmat[1, 2]), -float(xmat[0, 2])) + 0.0  # + 0.0: no -0.0
        origin = Pose2D(float(pos[0]), float(pos[1]), yaw)
        return CameraImage(stamp=stamp, origin=origin, z=float(pos[2]), fov_h=self.config.fov_h, rgb=rgb)

    def close(self) -> None:
        """Free the renderer (a later capture makes a new one)."""
        renderer, self._renderer = self._renderer, None
        if renderer is not None:
            renderer.close()
