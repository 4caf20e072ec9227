"""The forward camera: renders the office, sees another robot, follows the robot, reports a missing
renderer, and never changes the physics."""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest

from rescuemesh.body import Body, NoRendererError
from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel, load_map, office_map_path
from rescuemesh.robot.sensor_codec import image_is_informative
from rescuemesh.sim import World, camera as camera_module, mjcf
from rescuemesh.sim.camera import CameraConfig, make_renderer


@pytest.fixture(scope="module")
def office() -> MapModel:
    return load_map(office_map_path())


@pytest.fixture(scope="module")
def gl() -> None:
    """Skips a rendering test only where this machine cannot make a bare OpenGL context of the
    backend the cameras would use (no EGL library, no device). Where it can, every NoRendererError
    is a failure: the probe does not go through the code under test."""
    backend = camera_module.gl_backend()
    if backend == "disabled":
        pytest.skip("MUJOCO_GL disables rendering")
    try:
        context = importlib.import_module(camera_module._BACKEND_MODULES[backend]).GLContext(8, 8)
    except Exception as exc:  # noqa: BLE001 - whatever the platform raises
        pytest.skip(f"no OpenGL context with {backend} on this machine: {exc}")
    context.free()


@pytest.fixture(scope="module")
def team(office: MapModel, gl) -> World:
    """The default starts: robot_2 looks along +x at robot_1 1.5 m ahead; robot_1 looks down the hall
    opening with no robot ahead."""
    world = World(office, office.starts)
    yield world
    world.close()


def _orange(rgb: np.ndarray) -> np.ndarray:
    """Pixels of a robot's chassis colour (mjcf.ROBOT_RGBA, orange) under any of the scene's lights."""
    r, g, b = (rgb[..., i].astype(int) for i in range(3))
    return (r > 120) & (r - b > 70) & (g > b) & (r > g + 25)


def _centre(rgb: np.ndarray) -> np.ndarray:
    h, w = rgb.shape[:2]
    return rgb[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4]


def test_the_camera_renders_a_scene_from_a_start(team: World) -> None:
    body = team.bodies["robot_1"]
    image = body.camera()
    assert image.rgb.shape == (120, 160, 3) and image.rgb.dtype == np.uint8
    assert (image.width, image.height) == (160, 120)
    assert image_is_informative(image.rgb)  # floor, walls and sky: not blank, not one colour
    # sky above, floor below: the top rows are brighter and bluer than the bottom rows
    top, bottom = image.rgb[:10].astype(float).mean(axis=(0, 1)), image.rgb[-10:].astype(float).mean(axis=(0, 1))
    assert top.sum() > bottom.sum() + 60
    assert image.stamp == team.time
    pose = body.pose()
    assert image.origin.x == pytest.approx(pose.x + mjcf.CAMERA_X * math.cos(pose.yaw), abs=1e-3)
    assert image.origin.y == pytest.approx(pose.y + mjcf.CAMERA_X * math.sin(pose.yaw), abs=1e-3)
    assert math.cos(image.origin.yaw - pose.yaw) > 0.9999
    assert image.z == pytest.approx(mjcf.CAMERA_HEIGHT, abs=0.01)
    assert image.fov_h == pytest.approx(math.radians(58.0))


def test_another_robot_in_front_appears_in_the_middle_of_the_image(team: World) -> None:
    behind = team.bodies["robot_2"].camera().rgb  # robot_1 is 1.5 m ahead of robot_2
    assert _orange(_centre(behind)).mean() > 0.05
    ahead = team.bodies["robot_1"].camera().rgb  # nothing orange down the hall opening
    assert _orange(ahead).sum() == 0


def test_the_camera_turns_with_the_robot(office: MapModel, gl) -> None:
    pose = Pose2D(4.0, 4.0, math.radians(120.0))
    world = World(office, {"r": pose, "other": Pose2D(4.0 - 0.75, 4.0 + 1.3, 0.0)})
    image = world.bodies["r"].camera()
    world.close()
    assert math.cos(image.origin.yaw - pose.yaw) > 0.9999
    assert image.origin.x == pytest.approx(pose.x + mjcf.CAMERA_X * math.cos(pose.yaw), abs=1e-3)
    assert _orange(_centre(image.rgb)).mean() > 0.05  # the robot put 1.5 m along the new heading


def test_the_resolution_is_a_setting_and_keeps_the_horizontal_field_of_view(office: MapModel, gl) -> None:
    config = CameraConfig(width=64, height=32)
    world = World(office, {"r": office.starts["robot_1"]}, camera=config)
    cam_id = world.model.camera(mjcf.camera_name("r")).id
    # 58 deg across 64 px is tan(29 deg) * 32 / 64 up and down: 2 atan(0.277) = 31.0 deg vertically
    assert world.model.cam_fovy[cam_id] == pytest.approx(math.degrees(2 * math.atan(math.tan(math.radians(29)) / 2)))
    assert world.bodies["r"].camera().rgb.shape == (32, 64, 3)
    world.close()


@pytest.mark.parametrize("bad", [dict(width=4), dict(height=5000), dict(width=160.0), dict(fov_h=0.0),
                                 dict(fov_h=math.pi), dict(multisamples=-1)])
def test_bad_camera_settings_are_refused(bad: dict) -> None:
    with pytest.raises(ValueError):
        CameraConfig(**bad)


def test_pictures_never_change_the_physics(office: MapModel, gl) -> None:
    def run(pictures: bool) -> np.ndarray:
        world = World(office, {"a": office.starts["robot_2"], "b": office.starts["robot_1"]})
        world.bodies["a"].set_velocity(0.4, 0.5)
        world.bodies["b"].set_velocity(0.2, -0.3)
        for _ in range(10):
            world.step(0.1)
            if pictures:
                world.bodies["a"].camera()
                world.bodies["b"].camera()
        world.close()
        return world.data.qpos.copy()

    assert np.array_equal(run(False), run(True))


# ---------------------------------------------------------------- no renderer


def test_a_world_without_cameras_and_a_plain_body_have_none(office: MapModel) -> None:
    world = World(office, {"r": office.starts["robot_1"]}, camera=None)
    assert world.bodies["r"].camera() is None
    assert Body.camera(world.bodies["r"]) is None  # the interface's default: no camera


def test_a_renderer_that_cannot_be_made_is_reported_once_and_never_as_a_blank_image(office, monkeypatch) -> None:
    calls = []

    def failing_factory(*args, **kwargs):
        calls.append(args)
        raise NoRendererError("no EGL display (test)")

    monkeypatch.setattr(camera_module, "make_renderer", failing_factory)
    world = World(office, {"a": office.starts["robot_1"], "b": office.starts["robot_2"]})
    for name in ("a", "b", "a"):
        with pytest.raises(NoRendererError, match="no EGL display"):
            world.bodies[name].camera()
    assert len(calls) == 1  # the World does not try again


def test_the_factory_turns_a_missing_gl_backend_into_no_renderer(office, monkeypatch) -> None:
    model = World(office, {"r": office.starts["robot_1"]}).model
    monkeypatch.setitem(camera_module._BACKEND_MODULES, "egl", "rescuemesh_test_no_such_gl_module")
    monkeypatch.setenv("MUJOCO_GL", "egl")
    with pytest.raises(NoRendererError, match="cannot create an OpenGL context with egl"):
        make_renderer(model, 160, 120)
    monkeypatch.setenv("MUJOCO_GL", "disable")
    with pytest.raises(NoRendererError, match="disabled"):
        make_renderer(model, 160, 120)


@pytest.mark.parametrize(("env", "backend"), [
    ({"MUJOCO_GL": "osmesa"}, "osmesa"),
    ({"MUJOCO_GL": "off"}, "disabled"),
    ({"DISPLAY": ""}, "egl"),  # headless Linux without MUJOCO_GL: EGL, not GLFW
    ({"DISPLAY": ":0"}, "glfw"),
])
def test_the_gl_backend_follows_mujoco_gl_and_picks_egl_when_headless(monkeypatch, env, backend) -> None:
    monkeypatch.setattr(camera_module.sys, "platform", "linux")
    for name in ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(name, raising=False)
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    assert camera_module.gl_backend() == backend
