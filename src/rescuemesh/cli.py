"""The `rescuemesh` command: run a scenario, list scenarios, run the benchmark, draw a radio map,
check the BLE transport.

Owns: argument parsing, progress display, the human summary, exit codes (0 success, 1 a scenario's
criteria failed, 2 bad input). Must not know: how scenarios or the simulation work inside. The radio
commands live in cli_radio.py, sweep and report in cli_experiments.py.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import os
import sys
from pathlib import Path

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


class UsageError(Exception):
    """A user's mistake on the command line: printed as one line, exit 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, no usage dump
        raise UsageError(message)


def _pose(text: str, *, with_yaw: bool) -> tuple[float, ...]:
    parts = text.split(",")
    want = 3 if with_yaw else 2
    if len(parts) not in ((2, 3) if with_yaw else (2,)):
        raise UsageError(f"expected {'X,Y[,YAW] in m and rad' if with_yaw else 'X,Y in m'}, got {text!r}")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        raise UsageError(f"not a number in {text!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise UsageError(f"not a finite number in {text!r}")
    return values + (0.0,) * (want - len(values))


def _starts(items: list[str]):
    from rescuemesh.geometry import Pose2D
    from rescuemesh.robot import robot_address

    starts = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise UsageError(f"--start takes NAME=X,Y,YAW, got {item!r}")
        try:
            robot_address(name)
        except ValueError as error:
            raise UsageError(str(error)) from None
        if name in starts:
            raise UsageError(f"--start {name} is given twice: give each robot one start")
        starts[name] = Pose2D(*_pose(value, with_yaw=True))
    return starts


#: Options whose value is coordinates: `--goal -7.95,0` is a value, not an option (argparse
#: would take a leading '-' for an option and say "expected one argument").
_COORDINATE_OPTIONS = frozenset({"--goal", "--start", "--from"})


def _join_negative_values(argv: list[str]) -> list[str]:
    """`--goal -7.95,0` -> `--goal=-7.95,0` (what argparse needs for a value that starts with '-')."""
    out, i = [], 0
    while i < len(argv):
        value = argv[i + 1] if i + 1 < len(argv) else ""
        if argv[i] in _COORDINATE_OPTIONS and value[:1] == "-" and value[1:2] in set("0123456789."):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def _folder(text: str) -> Path:
    if not text.strip():
        raise argparse.ArgumentTypeError("is empty: give a folder")
    return Path(text)


#: What each extra of pyproject.toml brings, as the modules a command imports.
_EXTRA_MODULES = {"sim": ("mujoco", "matplotlib", "mcap", "foxglove", "pyarrow"), "ble": ("bumble",)}
#: Commands and the extra they need; a robot process (`rescuemesh robot`) needs none.
_COMMAND_EXTRA = {"run": "sim", "world": "sim", "bench": "sim", "radio-map": "sim", "ble-check": "ble", "sweep": "sim",
                  "report": "sim", "check": "sim", "radio-validate": "sim"}


def _require_extra(command: str) -> None:
    """A one-line error naming the extra to install when a command's packages are missing."""
    extra = _COMMAND_EXTRA.get(command)
    if extra is None:
        return
    import importlib

    missing = []
    for module in _EXTRA_MODULES[extra]:
        try:
            importlib.import_module(module)
        except ImportError:
            missing.append(module)
    if missing:
        raise UsageError(f"`rescuemesh {command}` needs the {extra} extra ({', '.join(missing)} not installed): "
                         f"pip install 'rescuemesh[{extra}]'")


def _check_seed(seed: int) -> None:
    if not 0 <= seed < 2**63:
        raise UsageError(f"--seed must be a whole number from 0 to 2**63 - 1, got {seed}")


def _writable_folder(folder: Path) -> Path:
    """Create `folder` (and check it takes files) before a run, not after it."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        # a new file of a random name, created exclusively (O_EXCL: a planted symlink is never followed,
        # an existing file never truncated); this used to write through `.rescuemesh-write-test`
        import tempfile

        fd, probe = tempfile.mkstemp(prefix=".rescuemesh-write-test-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as error:
        raise UsageError(f"cannot write to output folder {str(folder)!r}: {error.strerror or error}") from None
    return folder


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="rescuemesh", description="Robots that command each other over a short-range mesh.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    run = sub.add_parser("run", help="run a scenario in the MuJoCo office")
    run.add_argument("scenario", help="scenario name (see `rescuemesh scenarios`)")
    run.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    run.add_argument("--out", type=_folder, default=None, help="output folder (default out/SCENARIO)")
    run.add_argument("--loss", type=float, default=0.0, help="per-frame loss probability in [0, 1) (default 0)")
    run.add_argument("--map", type=Path, default=None, help="map file: rescuemesh wall YAML or ROS map_server YAML")
    run.add_argument("--robots", type=int, default=None, metavar="N",
                     help="team size for convoy (2 to 254; default 6); placed automatically behind robot_1")
    run.add_argument("--radius", type=float, default=1.5, help="move-around radius in m (default 1.5)")
    run.add_argument("--start", action="append", default=[], metavar="NAME=X,Y[,YAW]",
                     help="a robot's start pose in m and rad (repeatable)")
    run.add_argument("--goal", default=None, metavar="X,Y[,YAW]",
                     help="where the mission heads, in m (YAW in rad, default 0): the leader's goal in follow, "
                          "stop, disconnect, spoof and convoy; robot_2's Goto pose in goto and return; the spot "
                          "to show in show-scan and show-cam")
    run.add_argument("--time-limit", type=float, default=None, help="simulated seconds before giving up")
    run.add_argument("--radio", choices=["ble", "disc"], default="ble",
                     help="channel model: ble (walls, path loss, fading; default) or disc (10 m disc)")
    run.add_argument("--no-relay", action="store_true", help="no robot relays frames (single-hop radio)")
    run.add_argument("--outage", type=float, default=None, metavar="S",
                     help="disconnect: seconds robot_1's radio stays silent (default 3)")
    run.add_argument("--key", type=Path, default=None, metavar="FILE",
                     help="team key file (rescuemesh keys new FILE); default: a key derived from the seed")
    run.add_argument("--insecure", action="store_true",
                     help="CRC-32 frames, no authentication or encryption (anyone on the radio can command)")
    run.add_argument("--quiet", action="store_true", help="no progress display")
    run.add_argument("--processes", action="store_true",
                     help="each robot in its own process, the world in this one (docs/processes.md)")
    run.add_argument("--control", choices=["pipes", "zenoh"], default=None,
                     help="with --processes: the world calls its robot processes over a pair of pipes each "
                          "(default, the fastest) or over Zenoh on loopback")
    run.add_argument("--realtime", action="store_true", help="pace the run to the wall clock (default: as fast as it goes)")
    run.add_argument("--live", action="store_true",
                     help="also serve the run's recording on a Foxglove WebSocket on 127.0.0.1 while it runs "
                          "(with --realtime to watch it at its own pace; docs/recording.md)")
    run.add_argument("--live-port", type=int, default=8765, metavar="PORT", help="port of --live (default 8765)")
    run.add_argument("--rosbag", action="store_true",
                     help="also write the run as a rosbag2 (MCAP, CDR) folder OUT/run.rosbag2 for ROS 2 tools "
                          "(docs/ros2.md)")
    world = sub.add_parser("world", parents=[run], add_help=False,
                           help="run a scenario's world and wait for robot processes started by hand")
    world.add_argument("--listen", default="tcp/127.0.0.1:7447", metavar="tcp/HOST:PORT",
                       help="where robots connect (default tcp/127.0.0.1:7447)")
    world.add_argument("--run-id", default="default", help="keeps several runs on one network apart")
    world.add_argument("--wait", type=float, default=120.0, metavar="S", help="how long to wait for the robots")
    robot = sub.add_parser("robot", help="run one robot's software: brain, navigation, protocol, mesh (for a "
                                         "simulated world; with --link zenoh on a real network: docs/networks.md)")
    robot.add_argument("--name", required=True, help="robot name, robot_1 .. robot_254")
    robot.add_argument("--connect", metavar="tcp/HOST:PORT", help="the world's endpoint")
    robot.add_argument("--control-fds", metavar="R,W", default=None,
                       help="instead of --connect: read the world's requests from inherited pipe R and answer "
                            "on W (what run --processes gives the robots it starts)")
    robot.add_argument("--run-id", default="default", help="the world's run id (default: default)")
    robot.add_argument("--key", type=Path, default=None, metavar="FILE", help="team key file, when the world uses one")
    robot.add_argument("--wait", type=float, default=30.0, metavar="S", help="how long to wait for the world")
    robot.add_argument("--link", choices=["zenoh"], default=None,
                       help="zenoh: a robot on a real network instead, frames over Zenoh (its own options, "
                            "--body, --listen, --follow, --goal ..., are listed below; docs/networks.md)")
    sub.add_parser("scenarios", help="list the scenarios")
    keys = sub.add_parser("keys", help="team keys")
    keys_sub = keys.add_subparsers(dest="keys_command", required=True, parser_class=_Parser)
    keys_new = keys_sub.add_parser("new", help="write a new random 128-bit team key to FILE (mode 600)")
    keys_new.add_argument("file", type=Path)
    radio_map = sub.add_parser("radio-map", help="draw where a transmitter is heard (radio_map.png)")
    radio_map.add_argument("--from", dest="origin", required=True, metavar="X,Y", help="transmitter position in m")
    radio_map.add_argument("--map", type=Path, default=None, help="map file (default: the office)")
    radio_map.add_argument("--out", type=Path, default=Path("out/radio-map"), help="output folder")
    radio_map.add_argument("--radio", choices=["ble", "disc"], default="ble", help="channel model (default ble)")
    radio_map.add_argument("--seed", type=int, default=0, help="seed of the shadowing field (default 0)")
    radio_map.add_argument("--power", action="store_true", help="plot mean received power instead of delivery")
    validate = sub.add_parser("radio-validate", help="check the BLE model against measured BLE data (docs/radio.md)")
    validate.add_argument("--data", choices=["kolakowski", "danis", "all"], default="all",
                          help="data set (default all)")
    validate.add_argument("--out", type=Path, default=Path("out/radio-validate"), help="output folder")
    ble = sub.add_parser("ble-check", help="run three endpoints over a real BLE host stack (bumble) in real time")
    ble.add_argument("--hci", action="append", default=[], metavar="SPEC",
                     help="an HCI transport per robot (e.g. usb:0); give it three times, or none for "
                          "bumble's virtual controllers")
    bench = sub.add_parser("bench", help="measure the real-time factor and the codec rate")
    bench.add_argument("--out", type=Path, default=Path("out/bench.json"), help="JSON file for the figures")
    bench.add_argument("--seed", type=int, default=0)
    from rescuemesh.cli_experiments import add_parsers as add_experiment_parsers

    add_experiment_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        return _main(argv)
    except BrokenPipeError:
        # The reader went away (`rescuemesh run follow | head -1`): the run itself is over. Point
        # stdout at nothing so that the interpreter's final flush does not fail again (Python
        # docs, "Note on SIGPIPE").
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno()) if hasattr(sys.stdout, "fileno") and _has_fd(sys.stdout) else None
        return EXIT_OK


def _has_fd(stream) -> bool:
    try:
        stream.fileno()
    except (OSError, ValueError, AttributeError):
        return False
    return True


def _main(argv: list[str] | None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["robot"] and any(a == "--link" or a.startswith("--link=") for a in argv):
        return _linked_robot(argv[1:])
    if argv[:1] == ["robot"] and any(a in ("-h", "--help") for a in argv):  # both kinds of robot process
        from rescuemesh.runtime.onboard.linked_robot import build_parser as linked_parser

        robot_parser = next(a for a in build_parser()._actions
                            if isinstance(a, argparse._SubParsersAction)).choices["robot"]
        print(robot_parser.format_help() + "\nA robot on a real network (rescuemesh robot --link zenoh|ble ...; "
              "docs/networks.md, docs/ros1.md, docs/ros2.md):\n\n" + linked_parser().format_help())
        return EXIT_OK
    try:
        args = build_parser().parse_args(_join_negative_values(argv))
        _require_extra(args.command)
        if args.command == "scenarios":
            return _list_scenarios()
        if args.command in ("radio-map", "radio-validate"):
            from rescuemesh import cli_radio

            return cli_radio.radio_map(args) if args.command == "radio-map" else cli_radio.radio_validate(args)
        if args.command == "keys":
            return _keys_new(args.file)
        if args.command == "ble-check":
            from rescuemesh.checks.ble_check import main_ble_check

            return main_ble_check(args.hci, sys.stdout, err=sys.stderr)
        if args.command == "robot":
            return _robot(args)
        if args.command in ("sweep", "report", "check"):
            return _experiments(args)
        if args.command == "bench":
            from rescuemesh.checks.bench import run_bench

            _check_seed(args.seed)
            _writable_folder(args.out.parent)
            if args.out.is_dir():
                raise UsageError(f"--out {str(args.out)!r} is a folder; give a file name such as out/bench.json")
            return run_bench(args.out, seed=args.seed)
        return _run(args)
    except UsageError as error:
        print(f"rescuemesh: error: {error}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("rescuemesh: interrupted", file=sys.stderr)
        return 130


def _experiments(args) -> int:
    from rescuemesh.cli_experiments import main_check, main_report, main_sweep
    from rescuemesh.experiments import SweepError

    try:
        return {"sweep": main_sweep, "report": main_report, "check": main_check}[args.command](args)
    except SweepError as error:
        raise UsageError(str(error)) from None


def _list_scenarios() -> int:
    from rescuemesh.scenarios import SCENARIOS

    for name, cls in SCENARIOS.items():
        print(f"{name:12s} {cls.summary}")
    return EXIT_OK


def _run(args) -> int:
    from rescuemesh.geometry import Pose2D
    from rescuemesh.maps import MapError
    from rescuemesh.runtime import RadioKind
    from rescuemesh.scenarios import ScenarioError, ScenarioOptions
    from rescuemesh.runtime.processes.control import ControlError

    if not (0.0 <= args.loss < 1.0):
        raise UsageError(f"--loss must be in [0, 1), got {args.loss}")
    if args.time_limit is not None and not (0 < args.time_limit < math.inf):
        raise UsageError(f"--time-limit must be a finite number of seconds > 0, got {args.time_limit}")
    if args.outage is not None and not (0 < args.outage < math.inf):
        raise UsageError(f"--outage must be a finite number of seconds > 0, got {args.outage}")
    _check_seed(args.seed)
    if args.goal is not None and not args.goal.strip():
        raise UsageError("--goal is empty: give X,Y[,YAW] in m and rad")
    goal = Pose2D(*_pose(args.goal, with_yaw=True)) if args.goal else None
    key, key_source = _team_key(args)
    options = ScenarioOptions(seed=args.seed, loss=args.loss, radius_m=args.radius, starts=_starts(args.start),
                              goal=goal, time_limit_s=args.time_limit, radio=RadioKind(args.radio),
                              relay=not args.no_relay, outage_s=args.outage, robots=args.robots, secure=not args.insecure,
                              team_key=key, key_source=key_source)
    name = args.scenario
    processes, scenario = None, None
    if args.control is not None and not (args.processes and args.command == "run"):
        raise UsageError("--control chooses how run --processes calls its robots"
                         + ("; robots started by hand call the world over Zenoh" if args.command == "world" else
                            ": add --processes"))
    if name.endswith((".yaml", ".yml")):  # a mission file (docs/missions.md)
        from rescuemesh.cli_experiments import mission_scenario
        from rescuemesh.experiments import SweepError

        try:
            options, scenario = mission_scenario(args, options)
        except SweepError as error:
            raise UsageError(str(error)) from None
        name = None
    out = _writable_folder(args.out or Path("out") / (name or scenario.name))
    if args.command == "world":
        from rescuemesh.runtime.processes.spawn import ProcessOptions

        if not 0 < args.wait < math.inf:
            raise UsageError(f"--wait must be a finite number of seconds > 0, got {args.wait}")
        processes = ProcessOptions(listen=_endpoint(args.listen), run_id=_run_id(args.run_id), spawn=False,
                                   key_file=args.key, join_timeout_s=args.wait)
        print(f"world {args.scenario}: waiting for robots at {args.listen} (run {args.run_id!r}); start each with\n"
              f"  rescuemesh robot --name robot_N --connect {args.listen}"
              + (f" --run-id {args.run_id}" if args.run_id != "default" else ""), file=sys.stderr)
    if getattr(args, "rosbag", False) and importlib.util.find_spec("rosbags") is None:
        raise UsageError("--rosbag needs the rosbags package: pip install 'rescuemesh[sim]'")
    if args.live and not 0 < args.live_port < 65536:
        raise UsageError(f"--live-port must be a port number from 1 to 65535, got {args.live_port}")
    if args.live:
        print(f"live: Foxglove WebSocket on ws://127.0.0.1:{args.live_port} while the run lasts "
              f"(Foxglove: Open connection, Foxglove WebSocket)", flush=True)
    if args.processes and args.command == "run":
        if name is None:
            raise UsageError("a mission file runs in one process; --processes takes a built-in scenario")
        processes, scenario = _early_team(args, options, out)  # before the world's imports: robots start
    from rescuemesh.scenarios.runner import run_scenario

    progress = None if args.quiet else _Progress(args.scenario)
    try:
        outcome = run_scenario(name, options, map_path=args.map, scenario=scenario, out_dir=out,
                               progress=progress, processes=processes, realtime=args.realtime,
                               live_port=args.live_port if args.live else None,
                               rosbag=getattr(args, "rosbag", False))
    except ControlError as error:
        if progress:
            progress.clear()
        print(f"rescuemesh: error: {error}", file=sys.stderr)
        return EXIT_FAILED
    except (ScenarioError, MapError, ValueError) as error:
        if progress:
            progress.clear()
        raise UsageError(str(error)) from None
    finally:
        if processes is not None and processes.team is not None:
            processes.team.close()
    if progress:
        progress.clear()
    _summary(outcome)
    return EXIT_OK if outcome.verdict.success else EXIT_FAILED


def _early_team(args, options, out: Path):
    """`run --processes`: the team's robot processes, started now at a free endpoint, before this
    process imports MuJoCo and builds the world (a robot takes about as long to import and connect).
    Returns the run's ProcessOptions and the scenario, built once for the team and the run."""
    from rescuemesh.maps import MapError, load_map, office_map_path
    from rescuemesh.runtime.processes.spawn import ControlCarrier, ProcessOptions, RobotProcesses, free_endpoint
    from rescuemesh.scenarios import ScenarioError, get_scenario

    try:
        cls = get_scenario(args.scenario)
        scenario = cls(options, load_map(args.map or office_map_path()))
        names = list(scenario.starts()) if cls.runs_as_processes else []
    except (ScenarioError, MapError, ValueError) as error:
        raise UsageError(str(error)) from None
    control = ControlCarrier(args.control or ControlCarrier.PIPES.value)
    listen = free_endpoint() if control is ControlCarrier.ZENOH else None
    team = RobotProcesses(listen, "default", out / "processes", key_file=args.key, control=control)
    for name in names:
        team.start(name)
    return ProcessOptions(listen=listen, key_file=args.key, team=team, control=control), scenario


def _endpoint(text: str) -> str:
    from rescuemesh.runtime.processes.control import check_endpoint

    try:
        return check_endpoint(text)
    except ValueError as error:
        raise UsageError(str(error)) from None


def _run_id(text: str) -> str:
    from rescuemesh.runtime.processes.control import Keys

    try:
        return Keys(text).run
    except ValueError as error:
        raise UsageError(str(error)) from None


def _robot(args) -> int:
    from rescuemesh.robot import robot_address
    from rescuemesh.runtime.processes.control import ControlError
    from rescuemesh.runtime.processes.robot_process import serve_robot

    try:
        robot_address(args.name)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if not 0 < args.wait < math.inf:
        raise UsageError(f"--wait must be a finite number of seconds > 0, got {args.wait}")
    key = None
    if args.key is not None:
        from rescuemesh.mesh.keys import KeyFileError, load_team_key

        try:
            key = load_team_key(args.key)
        except KeyFileError as error:
            raise UsageError(str(error)) from None
    try:
        if args.control_fds is not None:
            if args.connect is not None:
                raise UsageError("give --connect or --control-fds, not both")
            from rescuemesh.runtime.processes.robot_process import serve_robot_over_pipes

            requests_fd, replies_fd = _control_fds(args.control_fds)
            return serve_robot_over_pipes(args.name, requests_fd, replies_fd, team_key=key)
        if args.connect is None:
            raise UsageError("give the world's endpoint: --connect tcp/HOST:PORT")
        return serve_robot(args.name, _endpoint(args.connect), run=_run_id(args.run_id), team_key=key,
                           wait_s=args.wait)
    except ControlError as error:
        print(f"rescuemesh: error: {error}", file=sys.stderr)
        return EXIT_FAILED


def _control_fds(text: str) -> tuple[int, int]:
    """`--control-fds R,W`: two open pipe file descriptors this process inherited."""
    import stat

    parts = text.split(",")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise UsageError(f"--control-fds takes R,W: two file descriptor numbers, got {text!r}")
    fds = tuple(int(p) for p in parts)
    for fd, end in zip(fds, ("R", "W")):
        try:
            mode = os.fstat(fd).st_mode
        except OSError:
            raise UsageError(f"--control-fds: {end} = {fd} is not an open file descriptor "
                             f"(run --processes hands the robots it starts a pair of pipes)") from None
        if not stat.S_ISFIFO(mode):
            raise UsageError(f"--control-fds: {end} = {fd} is not a pipe")
    if fds[0] == fds[1]:
        raise UsageError("--control-fds: R and W must be two pipes")
    return fds


def _linked_robot(argv: list[str]) -> int:
    """`rescuemesh robot --link zenoh ...`: a robot on a real network, its frames over Zenoh with no
    simulated channel (runtime/onboard/linked_robot.py, docs/networks.md). Ends the process itself: a Zenoh
    session still closing must not meet a finalising interpreter."""
    rest, link = [], None
    for i, arg in enumerate(argv):
        if arg.startswith("--link="):
            link = arg.partition("=")[2]
        elif arg == "--link":
            link = argv[i + 1] if i + 1 < len(argv) else ""
        elif i == 0 or argv[i - 1] != "--link":
            rest.append(arg)
    if link not in ("zenoh", "ble"):
        print(f"rescuemesh: error: --link takes zenoh (frames over Zenoh on a real network) or ble (over a "
              f"Bluetooth LE controller, --hci SPEC), got {link!r}", file=sys.stderr)
        return EXIT_USAGE
    from rescuemesh.runtime.onboard.linked_robot import exit_process, main as linked_main

    exit_process(linked_main(["--link", link, *rest]))  # first: what follows --ros-args is rclpy's


class _Progress:
    """Simulated time against the limit: a live line on a terminal, a line every 10 s otherwise."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.tty = sys.stderr.isatty()
        self._last_line = -10.0

    def __call__(self, sim_s: float, limit_s: float) -> None:
        if self.tty:
            done = int(30 * min(1.0, sim_s / limit_s))
            sys.stderr.write(f"\r{self.name}: [{'#' * done}{'.' * (30 - done)}] {sim_s:5.1f} / {limit_s:.0f} s sim")
            sys.stderr.flush()
        elif sim_s - self._last_line >= 10.0:
            print(f"{self.name}: {sim_s:5.1f} / {limit_s:.0f} s simulated", file=sys.stderr)
            self._last_line = sim_s

    def clear(self) -> None:
        if self.tty:
            sys.stderr.write("\r" + " " * 70 + "\r")


def _team_key(args) -> tuple[bytes | None, str]:
    if args.insecure and args.key is not None:
        raise UsageError("--key and --insecure contradict each other: an insecure run uses no key")
    if args.insecure:
        return None, "none (--insecure)"
    if args.key is None:
        return None, "derived from the seed (simulation only)"
    from rescuemesh.mesh.keys import KeyFileError, load_team_key

    try:
        return load_team_key(args.key), f"from {args.key}"
    except KeyFileError as error:
        raise UsageError(str(error)) from None


def _keys_new(path: Path) -> int:
    from rescuemesh.mesh.keys import KeyFileError, write_team_key

    try:
        write_team_key(path)
    except KeyFileError as error:
        raise UsageError(str(error)) from None
    print(f"wrote a new 128-bit team key to {path} (mode 600): give it to every robot of the team, "
          f"and use it with --key {path}")
    return EXIT_OK


def _summary(outcome) -> None:
    r = outcome.result
    p, n = r["protocol"], r["network"]
    radio = r["settings"]["radio"] + ("" if r["settings"]["relay"] else ", no relay")
    radio += ", authenticated" if r["settings"]["security"]["authenticated"] else ", INSECURE: CRC frames, no authentication"
    print(f"{r['scenario']}: {'SUCCESS' if r['success'] else 'FAILED'}  (seed {r['seed']}, radio {radio}, "
          f"loss {r['settings']['loss']:g}, {r['sim_time_s']:.1f} s simulated in {r['wall_time_s']:.1f} s, "
          f"{r['real_time_factor']}x real time)")
    for check in r["criteria"]:
        print(f"  [{'x' if check['ok'] else ' '}] {check['check']}")
    metrics = ", ".join(f"{k}={v}" for k, v in r["metrics"].items() if not isinstance(v, (list, dict)))
    skipped = r["metrics"].get("waypoints_skipped")
    print(f"  metrics: {metrics}")
    error = r["metrics"].get("following_error_m")
    if isinstance(error, dict):
        print(f"  following error against {error['set_distance_m']:g} m: mean {error['mean_m']:+.2f} m, "
              f"RMS {error['rms_m']:.2f} m, largest {error['max_m']:+.2f} m")
    if skipped:
        print(f"  waypoints skipped (inside obstacles): {', '.join(skipped)}")
    ratio = "n/a" if p["delivery_ratio"] is None else f"{100 * p['delivery_ratio']:.0f} %"
    stops = p["automatic_stops"]
    automatic = (f"; automatic Stops {stops['sent']} ({stops['confirmed']} confirmed, {stops['failed']} failed, "
                 f"{stops['pending']} pending)") if stops["sent"] else ""
    print(f"  protocol: {p['unicast_frames_sent']} unicast + {p['broadcast_frames_sent']} broadcast frames sent "
          f"({p['bytes_sent']} B), {p['retries']} retries, {p['confirms']} confirms; unicast sends delivered "
          f"end to end {p['unicast_sends_delivered']}/{p['unicast_sends']} ({ratio}); commands "
          f"{p['commands_confirmed']}/{p['commands_sent']} confirmed, {p['commands_failed']} failed, "
          f"{p['commands_pending']} pending{automatic}")
    hops = ", ".join(f"{k} hop{'s' if k != '1' else ''}: {v}" for k, v in n["hops_histogram"].items())
    print(f"  network: {n['transmissions']} transmissions ({n['relayed_frames']} relayed, "
          f"{n['segment_transmissions']} segments, largest {p['max_frame_bytes']} B), airtime {n['airtime_s']:.2f} s, "
          f"{n['collisions']} collisions; delivered by hops: {hops or 'none'}")
    for path in outcome.files:
        print(f"  wrote {path}")
