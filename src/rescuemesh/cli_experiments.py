"""The `rescuemesh sweep` and `rescuemesh report` commands: arguments, progress line, summaries.

Owns: these two commands' options and what they print. Must not know: how runs execute or how
intervals are computed (rescuemesh.experiments). Errors in the user's input raise SweepError, which
cli.py prints as one line with exit 2.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

EXIT_OK, EXIT_FAILED, EXIT_INTERRUPTED = 0, 1, 130


def add_parsers(sub) -> None:
    sweep = sub.add_parser("sweep", help="run a sweep file: every combination of its axes for every seed")
    sweep.add_argument("file", type=Path, help="the sweep file (YAML; docs/sweeps.md)")
    sweep.add_argument("--out", type=Path, default=None, help="the sweep's folder (default out/sweeps/NAME); "
                       "running again with the same folder resumes")
    sweep.add_argument("--workers", type=int, default=None, metavar="N",
                       help="local worker processes (default: every core)")
    sweep.add_argument("--ray", default=None, metavar="ADDRESS",
                       help="run on a Ray cluster instead: its address, 'auto', or 'local' for a new one here")
    sweep.add_argument("--keep-artifacts", action="store_true",
                       help="keep each run's result.json, plots and run.mcap under DIR/artifacts/KEY")
    sweep.add_argument("--dry-run", action="store_true", help="validate and count the runs; run nothing")
    sweep.add_argument("--quiet", action="store_true", help="no progress line")
    check = sub.add_parser("check", help="validate a mission or sweep file against its map; run nothing")
    check.add_argument("file", type=Path, help="a mission file (docs/missions.md) or a sweep file (docs/sweeps.md)")
    report = sub.add_parser("report", help="a sweep's success rates and metric means with 95 %% intervals, and plots")
    report.add_argument("folder", type=Path, help="the sweep's folder (--out of `rescuemesh sweep`)")
    report.add_argument("--plots", type=Path, default=None, help="folder for the plots (default FOLDER/report)")


def main_sweep(args) -> int:
    from rescuemesh.experiments import ExecutorError, LocalPool, RayExecutor, SweepError, load_sweep, run_sweep

    sweep = load_sweep(args.file)
    if args.workers is not None and args.workers < 1:
        raise SweepError(f"--workers must be at least 1, got {args.workers}")
    out = args.out or Path("out") / "sweeps" / sweep.name
    if args.dry_run:
        axes = ", ".join(f"{k} ({len(v)})" for k, v in sweep.axes.items())
        print(f"sweep {sweep.name}: scenario {sweep.scenario}, axes {axes}, {len(sweep.seeds)} seeds: "
              f"{sweep.size} runs -> {out}")
        return EXIT_OK
    try:
        executor = RayExecutor(args.ray, args.workers) if args.ray else LocalPool(args.workers)
    except ExecutorError as error:
        raise SweepError(str(error)) from None
    where = f"Ray ({executor.workers} CPUs)" if args.ray else f"{executor.workers} local workers"
    print(f"sweep {sweep.name}: {sweep.size} runs of {sweep.scenario} on {where} -> {out}", file=sys.stderr)
    line = None if args.quiet else _ProgressLine(sweep.name)
    summary = run_sweep(sweep, out, executor, keep_artifacts=args.keep_artifacts, progress=line)
    if line:
        line.clear()
    counts = ", ".join(f"{n} {status}" for status, n in summary.by_status.items() if n)
    print(f"sweep {sweep.name}: {summary.skipped} already done, {summary.ran} run now ({counts or 'none'}) "
          f"in {summary.wall_s:.1f} s; rows in {out}/results.parquet and results.csv")
    if summary.interrupted:
        print(f"sweep {sweep.name}: interrupted: {summary.skipped + summary.ran} of {summary.total} done; "
              f"run the same command again to resume", file=sys.stderr)
        return EXIT_INTERRUPTED
    broken = summary.by_status.get("error", 0) + summary.by_status.get("crashed", 0)
    if broken:
        print(f"sweep {sweep.name}: {broken} runs ended in an error (the `error` column says why; "
              f"they are redone only if their rows are deleted)", file=sys.stderr)
    return EXIT_FAILED if broken else EXIT_OK


def main_report(args) -> int:
    from rescuemesh.experiments import SweepError, load_rows, load_sweep
    from rescuemesh.experiments.report import (default_metrics, default_plots, draw_plot, format_table,
                                               plot_file_name, summarise)

    folder = args.folder
    if not (folder / "sweep.yaml").is_file():
        raise SweepError(f"{folder} is not a sweep folder (no sweep.yaml): give the --out of `rescuemesh sweep`")
    sweep = load_sweep(folder / "sweep.yaml")
    rows = load_rows(folder)
    if not rows:
        raise SweepError(f"{folder} holds no finished runs yet")
    metrics = default_metrics(sweep, rows)
    print(format_table(sweep, summarise(sweep, rows, metrics), metrics))
    plots_dir = args.plots or folder / "report"
    for plot in sweep.plots or default_plots(sweep, metrics):
        path = draw_plot(sweep, rows, plot, plots_dir / plot_file_name(plot))
        print(f"plot: {path}")
    return EXIT_OK


class _ProgressLine:
    """`sweep NAME: 37/120 done, 2 failed, 0 errors, about 1m20s left` on one rewritten line."""

    def __init__(self, name: str) -> None:
        self.name, self._last = name, 0.0
        self.tty = sys.stderr.isatty()

    def __call__(self, done: int, total: int, counts: dict[str, int], left_s: float | None) -> None:
        now = time.monotonic()
        if not self.tty and done < total and now - self._last < 10.0:
            return
        self._last = now
        left = "" if left_s is None else f", about {int(left_s // 60)}m{int(left_s % 60):02d}s left"
        text = (f"sweep {self.name}: {done}/{total} done, {counts.get('failed', 0)} failed, "
                f"{counts.get('error', 0) + counts.get('crashed', 0)} errors{left}")
        print(("\r" + text + "\x1b[K") if self.tty else text, end="" if self.tty else "\n", file=sys.stderr,
              flush=True)

    def clear(self) -> None:
        if self.tty:
            print("\r\x1b[K", end="", file=sys.stderr, flush=True)


def _is_sweep(path: Path) -> bool:
    import yaml

    try:
        head = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError, RecursionError):
        return False
    return isinstance(head, dict) and ("sweep" in head or "axes" in head)


def mission_scenario(args, options):
    """`rescuemesh run FILE.yaml`: the mission's options (its settings; --seed, --key and --time-limit,
    and --loss, --radio, --no-relay or --insecure given with other than their defaults, override
    them) and its scenario, built on its map. SweepError for anything the user must fix."""
    from rescuemesh.experiments import SweepError
    from rescuemesh.experiments.mission import MissionScenario
    from rescuemesh.experiments.mission_spec import MissionError, load_mission
    from rescuemesh.maps import MapError, load_map, office_map_path
    from rescuemesh.scenarios import ScenarioError

    not_for_missions = [flag for flag, given in (("--map", args.map is not None), ("--robots", args.robots is not None),
                                                 ("--start", bool(args.start)), ("--goal", args.goal is not None),
                                                 ("--outage", args.outage is not None)) if given]
    if not_for_missions:
        raise SweepError(f"{', '.join(not_for_missions)}: set this in the mission file, not on the command line")
    try:
        mission = load_mission(Path(args.scenario))
        overrides = {"time_limit_s": args.time_limit, "team_key": options.team_key, "key_source": options.key_source}
        if args.loss != 0.0:
            overrides["loss"] = args.loss
        if args.radio != "ble":
            overrides["radio"] = options.radio
        if args.no_relay:
            overrides["relay"] = False
        if args.insecure:
            overrides["secure"] = False
        options = MissionScenario.options_for(mission, args.seed, **overrides)
        return options, MissionScenario(mission, options, load_map(mission.map_path or office_map_path()))
    except (MissionError, MapError, ScenarioError) as error:
        raise SweepError(str(error)) from None


def main_check(args) -> int:
    """Validate a mission file (and its team and steps against its map) or a sweep file."""
    from rescuemesh.experiments import SweepError, load_sweep
    from rescuemesh.experiments.mission import MissionScenario
    from rescuemesh.experiments.mission_spec import MissionError, load_mission
    from rescuemesh.maps import MapError, load_map, office_map_path
    from rescuemesh.scenarios import ScenarioError

    path = args.file
    if _is_sweep(path):
        sweep = load_sweep(path)
        print(f"{path}: sweep {sweep.name}: scenario {sweep.scenario}, {sweep.size} runs: OK")
        return EXIT_OK
    try:
        mission = load_mission(path)
        scenario = MissionScenario(mission, MissionScenario.options_for(mission),
                                   load_map(mission.map_path or office_map_path()))
        scenario.starts()
    except (MissionError, MapError, ScenarioError) as error:
        raise SweepError(str(error)) from None
    print(f"{path}: mission {mission.name}: {len(mission.team)} robots, {len(mission.steps)} steps, "
          f"{len(mission.criteria)} criteria, {len(mission.metrics)} metrics: OK")
    return EXIT_OK
