"""Flight control of a quadrotor: cascaded position and attitude control, mixer, and landing on a robot.

Owns: the airframe the controller assumes (QuadrotorParams), its gains, the landing state machine and
the autopilot a FlyingBody runs. Must not know: MuJoCo or any simulator (this module imports only math,
numpy and rescuemesh.body, so a robot process without physics can fly a real drone with it), the brain.

Theory of operation. Every control step (the simulated body calls `Autopilot.step` before every
physics step: 160 Hz at the World's 6.25 ms, 200 Hz at 5 ms) runs one cascade, after the PX4 multicopter controller (position P -> velocity
PI -> acceleration; docs.px4.io "Controller Diagrams") with the geometric attitude law of Lee, Leok &
McClamroch 2010 / Mellinger & Kumar 2011:

    position error --Kp--> velocity setpoint (+ feed-forward, clamped) --PI--> acceleration
    acceleration + g  --m-->  thrust vector F (tilt-limited)  -> desired body z = F/|F|, collective F.b3
    desired body z + yaw -> desired rotation R_d -> e_R, e_omega -> torques J(-Kr e_R - Kw omega) + w x Jw
    [collective, torques] --inverse mixer--> four rotor thrusts, clipped to [0, max] (yaw gives way first)

Above the cascade sit two guidance layers that turn commands into setpoints: the Autopilot's FLY/HOLD
(climb vertically to the goal's height, then cross level; hover) and the LandingController, whose
transitions are the table `LANDING_TRANSITIONS` (FLY -> ALIGN -> DESCEND -> TOUCHDOWN -> LANDED, with
a go-around DESCEND -> ALIGN). State comes in as `FlightState` (map-frame position and velocity, body
attitude quaternion (w, x, y, z), body-frame angular velocity: what MuJoCo's free joint gives and what
an EKF such as PX4's gives); time comes in as `now` (s), never from a clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from rescuemesh.body import FlightPhase, LandingTarget

Vec3 = tuple[float, float, float]
Thrusts = tuple[float, float, float, float]
ZERO3: Vec3 = (0.0, 0.0, 0.0)
OFF: Thrusts = (0.0, 0.0, 0.0, 0.0)
GRAVITY = 9.81  # m/s^2 (MuJoCo's default gravity)


# ---------------------------------------------------------------------------------- airframe


@dataclass(frozen=True)
class QuadrotorParams:
    """The airframe: a 250-class X quadrotor (0.25 m motor-to-motor diagonal, 5-inch propellers), 0.5 kg.

    Mass and inertia after the AscTec Hummingbird (0.5 kg; Ixx 3.65e-3, Iyy 3.68e-3, Izz 7.03e-3 kg m^2,
    arm 0.17 m; RotorPy `hummingbird_params.py`) with the inertia scaled by (0.125 / 0.17)^2 to our
    arm length at the same mass. The yaw moment per newton of thrust is the Hummingbird's k_m / k_eta
    (1.36e-7 / 5.57e-6 = 0.0244 m) scaled by propeller diameter (5 in / 8 in). Thrust-to-weight 2 (a
    conservative 250-class; racers exceed 5): 2.45 N per rotor. Rotor order and spin after PX4's quad X:
    1 front-right CCW, 2 rear-left CCW, 3 front-left CW, 4 rear-right CW; a CCW rotor's drag twists the
    frame clockwise (-z).
    """

    mass: float = 0.5  # kg, all-up (frame, motors, battery, flight controller)
    inertia: Vec3 = (1.97e-3, 1.99e-3, 3.80e-3)  # kg m^2 about the body x, y, z axes at the centre of mass
    arm_length: float = 0.125  # m from the centre to each rotor axis
    yaw_moment: float = 0.0153  # m: yaw reaction torque (N m) per newton of rotor thrust
    thrust_to_weight: float = 2.0
    gear_height: float = 0.06  # m from the centre of mass down to the bottom of the feet
    gravity: float = GRAVITY

    @property
    def max_rotor_thrust(self) -> float:
        """Thrust limit of one rotor in N."""
        return self.thrust_to_weight * self.mass * self.gravity / 4.0

    @property
    def rotors(self) -> tuple[tuple[float, float, float], ...]:
        """(x, y, spin) of rotors 1..4 in the body frame: position in m; spin -1 CCW, +1 CW seen from above,
        which is also the sign of the yaw torque its drag puts on the frame."""
        a = self.arm_length / math.sqrt(2.0)
        return ((a, -a, -1.0), (-a, a, -1.0), (a, a, 1.0), (-a, -a, 1.0))


@lru_cache(maxsize=8)
def allocation(params: QuadrotorParams) -> tuple[tuple[float, ...], ...]:
    """The 4 x 4 inverse mixer: rotor thrusts = M @ (collective N, torque x, y, z in N m)."""
    rows = [[1.0] * 4, [y for _, y, _ in params.rotors], [-x for x, _, _ in params.rotors],
            [s * params.yaw_moment for _, _, s in params.rotors]]
    return tuple(tuple(float(v) for v in row) for row in np.linalg.inv(np.array(rows)))


def mix(params: QuadrotorParams, collective: float, torque: Vec3) -> Thrusts:
    """Rotor thrusts in N for a collective thrust (N) and body torques (N m), each within [0, max].

    Yaw gives way first (roll and pitch keep the drone upright; yaw can wait), as in PX4's mixer: the
    yaw torque is scaled down to the largest part that keeps every rotor in range; what still does
    not fit is clipped. (At hover a 0.5 kg drone has only 0.075 N m of yaw torque to spare.)
    """
    m, hi = allocation(params), params.max_rotor_thrust
    tx, ty, tz = torque
    base = [r[0] * collective + r[1] * tx + r[2] * ty for r in m]
    scale = 1.0  # of the yaw torque: rotor i gets base_i + scale * dz_i, which must stay in [0, hi]
    for b, r in zip(base, m):
        dz = r[3] * tz
        if dz > 0.0:
            scale = min(scale, (hi - b) / dz)
        elif dz < 0.0:
            scale = min(scale, b / -dz)
    scale = max(scale, 0.0)
    return tuple(min(max(b + r[3] * tz * scale, 0.0), hi) for b, r in zip(base, m))  # type: ignore[return-value]


# ---------------------------------------------------------------------------------- cascade


@dataclass(frozen=True, slots=True)
class FlightState:
    """Where the drone is: `position` m and `velocity` m/s in the map frame, `quaternion` (w, x, y, z)
    body to map, `angular_velocity` rad/s in the body frame."""

    position: Vec3
    velocity: Vec3
    quaternion: tuple[float, float, float, float]
    angular_velocity: Vec3


@dataclass(frozen=True, slots=True)
class Setpoint:
    """Where it should be: `position` m and `yaw` rad in the map frame, with optional feed-forward
    `velocity` m/s and `acceleration` m/s^2 (a moving target's)."""

    position: Vec3
    yaw: float
    velocity: Vec3 = ZERO3
    acceleration: Vec3 = ZERO3


@dataclass(frozen=True)
class FlightGains:
    """Gains of the cascade, in units that do not depend on the airframe (the attitude law is scaled by
    the inertia). Position to velocity: wn = sqrt(Kp Kv) = 2.8 rad/s, damping Kv / (2 wn) = 0.71.
    Attitude: roll/pitch wn = 20 rad/s with damping 0.8 (an eighth of the 160 Hz loop rate); yaw 6 rad/s."""

    pos_p_xy: float = 2.0  # 1/s: position error -> velocity setpoint
    pos_p_z: float = 2.0  # 1/s
    vel_p_xy: float = 4.0  # 1/s: velocity error -> acceleration
    vel_p_z: float = 6.0  # 1/s
    vel_i_xy: float = 0.4  # 1/s^2
    vel_i_z: float = 4.0  # 1/s^2: trims the hover thrust when the mass is not what the model says
    integral_limit: float = 2.0  # m/s^2, the most the integrators may add to the acceleration
    integrate_below: float = 0.05  # m/s: integrate an axis only while this slow relative to the feed-forward
    max_speed_xy: float = 1.0  # m/s
    max_climb: float = 1.0  # m/s
    max_descent: float = 0.8  # m/s
    max_tilt: float = math.radians(35.0)  # rad (PX4 MPC_TILTMAX_AIR defaults to 45 deg)
    min_thrust_ratio: float = 0.3  # the least collective the position loop asks for, as a fraction of weight
    att_p_rp: float = 400.0  # 1/s^2 (times the inertia: N m per rad)
    att_d_rp: float = 32.0  # 1/s
    att_p_yaw: float = 36.0  # 1/s^2
    att_d_yaw: float = 10.0  # 1/s


def _clamp(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else hi if v > hi else v


def acceleration_setpoint(state: FlightState, sp: Setpoint, integral: Vec3, gains: FlightGains) -> tuple[Vec3, Vec3]:
    """The outer loops: (acceleration setpoint in m/s^2, velocity error in m/s to integrate).

    The error to integrate is zero on an axis (horizontal, vertical) whose velocity setpoint was clamped
    or that moves faster than `integrate_below` relative to the feed-forward: climbs, crossings and the
    braking at their end do not charge the integrator, which trims only steady errors (a hover sag
    from a wrong mass, however large), so it leaves no slow tail after each manoeuvre.
    """
    g = gains
    (x, y, z), (vx, vy, vz) = state.position, state.velocity
    (px, py, pz), (fx, fy, fz) = sp.position, sp.velocity
    ux, uy = fx + g.pos_p_xy * (px - x), fy + g.pos_p_xy * (py - y)
    speed = math.hypot(ux, uy)
    clamped_xy = speed > g.max_speed_xy
    if clamped_xy:
        ux, uy = ux * g.max_speed_xy / speed, uy * g.max_speed_xy / speed
    uz_free = fz + g.pos_p_z * (pz - z)
    uz = _clamp(uz_free, -g.max_descent, g.max_climb)
    ex, ey, ez = ux - vx, uy - vy, uz - vz
    ax, ay, az = sp.acceleration
    accel = (ax + g.vel_p_xy * ex + g.vel_i_xy * integral[0],
             ay + g.vel_p_xy * ey + g.vel_i_xy * integral[1],
             az + g.vel_p_z * ez + g.vel_i_z * integral[2])
    steady_xy = not clamped_xy and math.hypot(vx - fx, vy - fy) < g.integrate_below
    steady_z = uz == uz_free and abs(vz - fz) < g.integrate_below
    return accel, (ex if steady_xy else 0.0, ey if steady_xy else 0.0, ez if steady_z else 0.0)


def thrust_vector(params: QuadrotorParams, accel: Vec3, gains: FlightGains) -> Vec3:
    """F = m (a + g z) in N, with its vertical part at least `min_thrust_ratio` of the weight and its
    tilt at most `max_tilt` (altitude keeps priority over horizontal acceleration, as in PX4)."""
    m = params.mass
    fz = max(m * (accel[2] + params.gravity), gains.min_thrust_ratio * m * params.gravity)
    fx, fy = m * accel[0], m * accel[1]
    horizontal, limit = math.hypot(fx, fy), fz * math.tan(gains.max_tilt)
    if horizontal > limit:
        fx, fy = fx * limit / horizontal, fy * limit / horizontal
    return (fx, fy, fz)


def rotation(q: tuple[float, float, float, float]) -> tuple[Vec3, Vec3, Vec3]:
    """Body axes (b1, b2, b3) in the map frame: the columns of the rotation matrix of unit quaternion
    (w, x, y, z)."""
    w, x, y, z = q
    return ((1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)),
            (2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)),
            (2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)))


def _cross(a: Vec3, b: Vec3) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a: Vec3, b: Vec3) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _unit(a: Vec3) -> Vec3:
    n = math.sqrt(_dot(a, a))
    return (a[0] / n, a[1] / n, a[2] / n)


def desired_axes(force: Vec3, yaw: float) -> tuple[Vec3, Vec3, Vec3]:
    """Desired body axes: z along the thrust vector, x as close to heading `yaw` as z allows
    (Mellinger & Kumar 2011, eq. 6)."""
    b3 = _unit(force)
    b2 = _unit(_cross(b3, (math.cos(yaw), math.sin(yaw), 0.0)))
    return (_cross(b2, b3), b2, b3)


def attitude_torque(params: QuadrotorParams, axes: tuple[Vec3, Vec3, Vec3], desired: tuple[Vec3, Vec3, Vec3],
                    omega: Vec3, gains: FlightGains) -> Vec3:
    """Body torques in N m: tau = J (-Kr e_R - Kw omega) + omega x J omega, with the attitude error
    e_R = vee(R_d^T R - R^T R_d) / 2 (Lee et al. 2010) and a zero angular velocity setpoint."""
    (b1, b2, b3), (d1, d2, d3) = axes, desired
    e = (0.5 * (_dot(d3, b2) - _dot(d2, b3)), 0.5 * (_dot(d1, b3) - _dot(d3, b1)), 0.5 * (_dot(d2, b1) - _dot(d1, b2)))
    jx, jy, jz = params.inertia
    wx, wy, wz = omega
    g = gains
    gyro = _cross(omega, (jx * wx, jy * wy, jz * wz))
    return (jx * (-g.att_p_rp * e[0] - g.att_d_rp * wx) + gyro[0],
            jy * (-g.att_p_rp * e[1] - g.att_d_rp * wy) + gyro[1],
            jz * (-g.att_p_yaw * e[2] - g.att_d_yaw * wz) + gyro[2])


class FlightController:
    """The cascade with its one piece of memory, the velocity integrator (m/s s, clamped).

    `step` maps (state, setpoint) to four rotor thrusts; `integrate=False` freezes the integrator (on
    the ground, where the error says nothing about the thrust trim).
    """

    def __init__(self, params: QuadrotorParams = QuadrotorParams(), gains: FlightGains = FlightGains()) -> None:
        self.params = params
        self.gains = gains
        self.integral: Vec3 = ZERO3

    def reset(self) -> None:
        self.integral = ZERO3

    def step(self, state: FlightState, sp: Setpoint, dt: float, integrate: bool = True) -> Thrusts:
        p, g = self.params, self.gains
        accel, err = acceleration_setpoint(state, sp, self.integral, g)
        if integrate:
            limits = [g.integral_limit / k if k > 0.0 else 0.0 for k in (g.vel_i_xy, g.vel_i_xy, g.vel_i_z)]
            self.integral = tuple(  # type: ignore[assignment]
                _clamp(i + e * dt, -lim, lim) for i, e, lim in zip(self.integral, err, limits))
        force = thrust_vector(p, accel, g)
        axes = rotation(state.quaternion)
        collective = _clamp(_dot(force, axes[2]), 0.0, 4.0 * p.max_rotor_thrust)
        torque = attitude_torque(p, axes, desired_axes(force, sp.yaw), state.angular_velocity, g)
        return mix(p, collective, torque)


def yaw_of(q: tuple[float, float, float, float]) -> float:
    """Heading in rad of the body x axis projected on the floor, for quaternion (w, x, y, z)."""
    w, x, y, z = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


# ---------------------------------------------------------------------------------- landing


@dataclass(frozen=True)
class LandingConfig:
    """The landing manoeuvre. Heights are of the feet above the target's top unless said otherwise."""

    cruise_altitude: float = 1.2  # m above the floor: 0.7 m over the office's 0.5 m walls and furniture
    climb_first_below: float = 0.15  # m: lower than the altitude by this much, climb vertically first
    align_radius: float = 0.3  # m: FLY -> ALIGN within this horizontal distance of the (predicted) target
    align_tolerance: float = 0.04  # m: ALIGN -> DESCEND within this ...
    align_speed_tolerance: float = 0.1  # m/s ... and this relative horizontal speed ...
    align_hold_s: float = 0.4  # s ... held this long
    descent_rate: float = 0.5  # m/s while high
    final_descent_rate: float = 0.2  # m/s within `final_height` of the top
    final_height: float = 0.25  # m
    go_around_error: float = 0.1  # m: DESCEND -> ALIGN (climb back) when the drone is this far off the target
    touchdown_height: float = 0.015  # m: TOUCHDOWN without a contact signal below this height ...
    touchdown_speed: float = 0.3  # m/s ... at at most this vertical speed
    settle_s: float = 0.3  # s of continuous contact after the rotors stop: TOUCHDOWN -> LANDED
    lost_contact_s: float = 1.0  # s without contact after the rotors stop: TOUCHDOWN -> OFF (slid off)
    max_prediction_s: float = 1.0  # s: a target estimate is extrapolated at most this far


@dataclass
class _Ctx:
    """What the transition guards read, built once per step."""

    now: float
    state: FlightState
    touching: bool
    target: Vec3  # predicted centre of the target's top, m
    error_xy: float  # horizontal distance drone -> predicted target, m
    rel_speed_xy: float  # horizontal speed relative to the target, m/s
    height: float  # feet above the target's top, m


# (from phase, to phase, guard): the first guard of a phase that holds moves the machine; one move per step.
# Everything that changes the landing phase lives in this table and the guards it names.
LANDING_TRANSITIONS: tuple[tuple[FlightPhase, FlightPhase, str], ...] = (
    (FlightPhase.FLY, FlightPhase.ALIGN, "over_target"),
    (FlightPhase.ALIGN, FlightPhase.DESCEND, "aligned"),
    (FlightPhase.DESCEND, FlightPhase.TOUCHDOWN, "touched_down"),
    (FlightPhase.DESCEND, FlightPhase.ALIGN, "drifted"),
    (FlightPhase.TOUCHDOWN, FlightPhase.LANDED, "settled"),
    (FlightPhase.TOUCHDOWN, FlightPhase.OFF, "slid_off"),
)


@dataclass(frozen=True, slots=True)
class FlightCommand:
    """One control step's output: rotor thrusts in N (rotors 1..4), the phase, the setpoint (None: rotors off)."""

    thrusts: Thrusts
    phase: FlightPhase
    setpoint: Setpoint | None


class LandingController:
    """Lands on a (moving) target: FLY to above it at cruise altitude (climbing vertically first when
    low), ALIGN over it matching its velocity, DESCEND onto it (fast, then slow near the top, going
    around when it drifts off), TOUCHDOWN (contact, or feet within `touchdown_height` at low vertical
    speed: rotors off), LANDED once the contact has held `settle_s`.

    The target is predicted from its last estimate: centre + velocity * (now - when it was given),
    capped at `max_prediction_s`; the same velocity is the setpoint's feed-forward.
    """

    def __init__(self, target: LandingTarget, now: float, state: FlightState,
                 controller: FlightController | None = None, config: LandingConfig = LandingConfig()) -> None:
        self.controller = controller or FlightController()
        self.config = config
        self.phase = FlightPhase.FLY
        self.target, self.target_time = target, now
        self._yaw = yaw_of(state.quaternion)
        x, y, z = state.position
        low = z < config.cruise_altitude - config.climb_first_below
        self._climb: Vec3 | None = (x, y, config.cruise_altitude) if low else None
        self._since = now  # when the present phase began
        self._aligned_since: float | None = None
        self._touch_since: float | None = None
        self._z_setpoint = z

    def update_target(self, target: LandingTarget, now: float) -> None:
        """A fresh estimate of the target (at `now` s)."""
        self.target, self.target_time = target, now

    # ----------------------------------------------------------------- guards (see LANDING_TRANSITIONS)

    def over_target(self, c: _Ctx) -> bool:
        return (self._climb is None and c.error_xy < self.config.align_radius
                and abs(c.state.position[2] - self.config.cruise_altitude) < self.config.climb_first_below)

    def aligned(self, c: _Ctx) -> bool:
        cfg = self.config
        if c.error_xy < cfg.align_tolerance and c.rel_speed_xy < cfg.align_speed_tolerance:
            if self._aligned_since is None:
                self._aligned_since = c.now
            return c.now - self._aligned_since >= cfg.align_hold_s
        self._aligned_since = None
        return False

    def touched_down(self, c: _Ctx) -> bool:
        cfg = self.config
        return c.touching or (c.height < cfg.touchdown_height and abs(c.state.velocity[2]) < cfg.touchdown_speed)

    def drifted(self, c: _Ctx) -> bool:
        return c.error_xy > self.config.go_around_error

    def settled(self, c: _Ctx) -> bool:
        if not c.touching:
            self._touch_since = None
            return False
        if self._touch_since is None:
            self._touch_since = c.now
        return c.now - self._touch_since >= self.config.settle_s

    def slid_off(self, c: _Ctx) -> bool:
        return self._touch_since is None and c.now - self._since >= self.config.lost_contact_s

    # ----------------------------------------------------------------- the step

    def predicted_target(self, now: float) -> tuple[Vec3, Vec3]:
        """(centre of the target's top in m, its velocity in m/s) at `now` s."""
        t = self.target
        age = _clamp(now - self.target_time, 0.0, self.config.max_prediction_s)
        return (t.x + t.vx * age, t.y + t.vy * age, t.z), (t.vx, t.vy, 0.0)

    def step(self, now: float, state: FlightState, touching: bool, dt: float) -> FlightCommand:
        """One control step: move the phase along the table, then fly the phase's setpoint."""
        (tx, ty, tz), tv = self.predicted_target(now)
        (x, y, z), (vx, vy, _) = state.position, state.velocity
        ctx = _Ctx(now, state, touching, (tx, ty, tz), math.hypot(tx - x, ty - y),
                   math.hypot(vx - tv[0], vy - tv[1]), z - self.controller.params.gear_height - tz)
        for src, dst, guard in LANDING_TRANSITIONS:
            if src is self.phase and getattr(self, guard)(ctx):
                self._enter(dst, ctx)
                break
        sp = self._setpoint(ctx, tv, dt)
        if sp is None:
            self.controller.reset()
            return FlightCommand(OFF, self.phase, None)
        return FlightCommand(self.controller.step(state, sp, dt, integrate=not touching), self.phase, sp)

    def _enter(self, phase: FlightPhase, c: _Ctx) -> None:
        self.phase, self._since = phase, c.now
        self._aligned_since = self._touch_since = None
        if phase is FlightPhase.DESCEND:
            self._z_setpoint = c.state.position[2]
        elif phase is FlightPhase.TOUCHDOWN and c.touching:
            self._touch_since = c.now

    def _setpoint(self, c: _Ctx, tv: Vec3, dt: float) -> Setpoint | None:
        cfg, phase = self.config, self.phase
        tx, ty, tz = c.target
        if phase is FlightPhase.FLY:
            if self._climb is not None:
                if c.state.position[2] > cfg.cruise_altitude - cfg.climb_first_below:
                    self._climb = None
                else:
                    return Setpoint(self._climb, self._yaw)
            near = c.error_xy < 2.0 * cfg.align_radius
            return Setpoint((tx, ty, cfg.cruise_altitude), self._yaw, tv if near else ZERO3)
        if phase is FlightPhase.ALIGN:
            return Setpoint((tx, ty, cfg.cruise_altitude), self._yaw, tv)
        if phase is FlightPhase.DESCEND:
            rate = cfg.descent_rate if c.height > cfg.final_height else cfg.final_descent_rate
            floor = tz + self.controller.params.gear_height - 0.05  # aim a little below the top: it touches
            self._z_setpoint = max(floor, self._z_setpoint - rate * dt)
            vz = -rate if self._z_setpoint > floor else 0.0
            return Setpoint((tx, ty, self._z_setpoint), self._yaw, (tv[0], tv[1], vz))
        return None  # TOUCHDOWN, LANDED, OFF: rotors off


# ---------------------------------------------------------------------------------- autopilot


@dataclass
class _Twist:
    linear: float  # m/s along the heading
    angular: float  # rad/s


class Autopilot:
    """What a flying body runs: turns the FlyingBody commands into a setpoint or a landing, every step.

    Modes: OFF/LANDED (rotors off), FLY -> HOLD (`fly_to`: via a vertical climb to the goal's height
    when below it, then level to the goal, HOLD within `arrive_radius`), HOLD with a twist (planar
    velocity at a held altitude, for `set_velocity`), and a LandingController's phases.
    """

    arrive_radius: float = 0.1  # m: FLY -> HOLD within this distance of the goal
    max_lead: float = 0.5  # m: a twist's carrot runs at most this far ahead of the drone

    def __init__(self, params: QuadrotorParams = QuadrotorParams(), gains: FlightGains = FlightGains(),
                 landing: LandingConfig = LandingConfig()) -> None:
        self.params = params
        self.landing_config = landing
        self.controller = FlightController(params, gains)
        self.phase = FlightPhase.OFF
        self._waypoints: list[Vec3] = []
        self._setpoint: Setpoint | None = None
        self._twist: _Twist | None = None
        self._landing: LandingController | None = None

    @property
    def rotors_running(self) -> bool:
        return self.phase not in (FlightPhase.OFF, FlightPhase.LANDED, FlightPhase.TOUCHDOWN)

    @property
    def idle(self) -> bool:
        """Rotors off with nothing to fly: `step` would return zero thrust without reading the state."""
        return self._landing is None and not self.rotors_running

    @property
    def setpoint(self) -> Setpoint | None:
        """The setpoint flown at the last step (None: rotors off)."""
        return self._setpoint

    # ----------------------------------------------------------------- commands

    def fly_to(self, goal: Vec3, yaw: float | None, state: FlightState) -> None:
        """Fly to `goal` (m, map frame) and hover there facing `yaw` rad (None: the present heading)."""
        x, y, z = state.position
        yaw = yaw_of(state.quaternion) if yaw is None else yaw
        self._waypoints = [goal]
        low = z < goal[2] - self.landing_config.climb_first_below
        if low and math.hypot(goal[0] - x, goal[1] - y) > self.arrive_radius:
            self._waypoints.insert(0, (x, y, goal[2]))  # climb vertically first
        self._setpoint = Setpoint(self._waypoints[0], yaw)
        self._twist = self._landing = None
        self.phase = FlightPhase.FLY

    def hold(self, state: FlightState) -> None:
        """Hover at the present position and heading (no-op with the rotors off)."""
        if self.rotors_running:
            self._waypoints, self._twist, self._landing = [], None, None
            self._setpoint = Setpoint(state.position, yaw_of(state.quaternion))
            self.phase = FlightPhase.HOLD

    def twist(self, linear: float, angular: float, state: FlightState) -> None:
        """Planar velocity: `linear` m/s along the heading, `angular` rad/s, at the present altitude.
        (0, 0) ends a twist (hover) and leaves any other mode alone; ignored with the rotors off."""
        if not self.rotors_running:
            return
        if linear == 0.0 and angular == 0.0:
            if self._twist is not None:
                self.hold(state)
            return
        if self._twist is None:
            self.hold(state)
        self._twist = _Twist(linear, angular)

    def land_on(self, target: LandingTarget, now: float, state: FlightState) -> None:
        """Start a landing on `target`, or update the target of the landing under way; ignored once LANDED."""
        if self.phase is FlightPhase.LANDED:
            return
        if self._landing is not None:
            self._landing.update_target(target, now)
            return
        self._waypoints, self._twist = [], None
        self._landing = LandingController(target, now, state, self.controller, self.landing_config)
        self.phase = self._landing.phase

    def rotors_off(self) -> None:
        """Rotors off now; anything but a landing's TOUCHDOWN (rotors already off, LANDED to follow) or
        LANDED becomes OFF."""
        if self.phase in (FlightPhase.TOUCHDOWN, FlightPhase.LANDED):
            return
        self.phase = FlightPhase.OFF
        self._waypoints, self._twist, self._landing, self._setpoint = [], None, None, None
        self.controller.reset()

    # ----------------------------------------------------------------- the step

    def step(self, now: float, state: FlightState, touching: bool, dt: float) -> Thrusts:
        """Rotor thrusts in N for the next `dt` s. `touching`: the feet touch something."""
        if self._landing is not None:
            cmd = self._landing.step(now, state, touching, dt)
            self.phase, self._setpoint = cmd.phase, cmd.setpoint
            if cmd.phase in (FlightPhase.LANDED, FlightPhase.OFF):
                self._landing = None
            return cmd.thrusts
        if not self.rotors_running or self._setpoint is None:
            self._setpoint = None
            self.controller.reset()
            return OFF
        if self._twist is not None:
            self._setpoint = self._advance_twist(state, dt)
        elif self.phase is FlightPhase.FLY:
            self._setpoint = self._advance_waypoints(state)
        return self.controller.step(state, self._setpoint, dt, integrate=not touching)

    def _advance_waypoints(self, state: FlightState) -> Setpoint:
        sp = self._setpoint
        assert sp is not None
        wp = self._waypoints[0]
        d = math.dist(state.position, wp)
        if len(self._waypoints) > 1 and abs(state.position[2] - wp[2]) < self.landing_config.climb_first_below:
            self._waypoints.pop(0)  # climbed: now level to the goal
        elif len(self._waypoints) == 1 and d < self.arrive_radius:
            self.phase = FlightPhase.HOLD
        return Setpoint(self._waypoints[0], sp.yaw)

    def _advance_twist(self, state: FlightState, dt: float) -> Setpoint:
        sp, tw = self._setpoint, self._twist
        assert sp is not None and tw is not None
        yaw = sp.yaw + tw.angular * dt
        vx, vy = tw.linear * math.cos(yaw), tw.linear * math.sin(yaw)
        px, py, pz = sp.position
        px, py = px + vx * dt, py + vy * dt
        x, y, _ = state.position
        lead = math.hypot(px - x, py - y)
        if lead > self.max_lead:  # the drone lags (a wall, a gust): do not wind the carrot up
            px, py = x + (px - x) * self.max_lead / lead, y + (py - y) * self.max_lead / lead
        return Setpoint((px, py, pz), yaw, (vx, vy, 0.0))
