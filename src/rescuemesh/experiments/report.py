"""`rescuemesh report DIR`: a sweep's rows summarised per parameter point, with intervals and plots.

Owns: grouping rows by the sweep's axes, the success rate with its Wilson 95 % interval
(scipy.stats.binomtest), each metric's mean with a bootstrap 95 % interval (scipy.stats.bootstrap,
percentile method, 2,000 resamples, fixed seed so that a report is reproducible), the printed table
and the plots (one line per value of a second axis, with interval bands). Must not know: how runs ran.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rescuemesh.experiments.spec import PlotSpec, Sweep

CONFIDENCE = 0.95
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 0


@dataclass(frozen=True)
class Interval:
    """An estimate with its 95 % interval; low == high when every sample was the same."""

    estimate: float
    low: float
    high: float
    n: int

    def text(self, digits: int = 3) -> str:
        if math.isnan(self.estimate):
            return "n/a"
        return f"{self.estimate:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"


def wilson(successes: int, n: int) -> Interval:
    """The success rate with its Wilson score 95 % interval."""
    from scipy.stats import binomtest

    if n == 0:
        return Interval(math.nan, math.nan, math.nan, 0)
    ci = binomtest(successes, n).proportion_ci(confidence_level=CONFIDENCE, method="wilson")
    return Interval(successes / n, float(ci.low), float(ci.high), n)


def bootstrap_mean(values: list[float]) -> Interval:
    """The mean with a percentile bootstrap 95 % interval (NaN interval for fewer than 2 values)."""
    from scipy.stats import bootstrap

    data = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if data.size == 0:
        return Interval(math.nan, math.nan, math.nan, 0)
    if np.all(data == data[0]):  # no spread to resample (or one value: no interval at all)
        edge = float(data[0]) if data.size > 1 else math.nan
        return Interval(float(data[0]), edge, edge, int(data.size))
    mean = float(data.mean())
    result = bootstrap((data,), np.mean, confidence_level=CONFIDENCE, n_resamples=BOOTSTRAP_RESAMPLES,
                       method="percentile", rng=np.random.default_rng(BOOTSTRAP_SEED))
    ci = result.confidence_interval
    return Interval(mean, float(ci.low), float(ci.high), int(data.size))


@dataclass
class PointSummary:
    """One parameter point (a value for every axis): its runs, success rate and metric means."""

    point: tuple[tuple[str, Any], ...]
    runs: int
    errors: int
    success: Interval
    metrics: dict[str, Interval]


def _axis_value(value: Any) -> Any:
    return ",".join(f"{v:g}" for v in value) if isinstance(value, list) else value


def summarise(sweep: Sweep, rows: list[dict[str, Any]], metrics: list[str]) -> list[PointSummary]:
    """Per point of the grid (in the sweep file's order), over its finished rows."""
    axes = list(sweep.axes)
    by_point: dict[tuple, list[dict[str, Any]]] = {}
    for row in rows:
        by_point.setdefault(tuple(row.get(a) for a in axes), []).append(row)
    out = []
    for values in itertools.product(*(sweep.axes[a] for a in axes)):
        key = tuple(_axis_value(v) for v in values)
        group = by_point.get(key, [])
        ran = [r for r in group if r.get("status") in ("success", "failed")]
        out.append(PointSummary(tuple(zip(axes, key)), len(group), len(group) - len(ran),
                                wilson(sum(1 for r in ran if r.get("success")), len(ran)),
                                {m: bootstrap_mean([_number(r.get(m)) for r in ran]) for m in metrics}))
    return out


def _number(value: Any) -> float | None:
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, (int, float)):
        return float(value)
    return None


def default_metrics(sweep: Sweep, rows: list[dict[str, Any]]) -> list[str]:
    """The sweep file's `report.metrics`, else every numeric `metrics.*` column the rows have."""
    if sweep.metrics:
        return list(sweep.metrics)
    seen: list[str] = []
    for row in rows:
        for key, value in row.items():
            if key.startswith("metrics.") and _number(value) is not None and key not in seen:
                seen.append(key)
    return sorted(seen)


def format_table(sweep: Sweep, summaries: list[PointSummary], metrics: list[str]) -> str:
    lines = [f"sweep {sweep.name}: scenario {sweep.scenario}, {len(summaries)} points x {len(sweep.seeds)} seeds "
             f"(95 % intervals: Wilson for success, bootstrap for means)"]
    for s in summaries:
        point = ", ".join(f"{k}={v}" for k, v in s.point)
        errors = f", {s.errors} error/crashed" if s.errors else ""
        lines.append(f"{point}: {s.runs} runs{errors}; success {s.success.text(2)}")
        for m in metrics:
            lines.append(f"    {m}: {s.metrics[m].text()} (n={s.metrics[m].n})")
    return "\n".join(lines)


def default_plots(sweep: Sweep, metrics: list[str]) -> list[PlotSpec]:
    axes = list(sweep.axes)
    lines = axes[1] if len(axes) > 1 else None
    return [PlotSpec(y, axes[0], lines) for y in ["success", *metrics]]


def draw_plot(sweep: Sweep, rows: list[dict[str, Any]], plot: PlotSpec, path: Path) -> Path:
    """`plot.y` against axis `plot.x`, a line (with its 95 % band) per value of axis `plot.lines`;
    other axes are pooled. `y` = "success" plots the success rate with Wilson intervals."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=110)
    line_values = sweep.axes[plot.lines] if plot.lines else [None]
    xs_all = sweep.axes[plot.x]
    numeric_x = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in xs_all)
    for line_value in line_values:
        xs, est, low, high = [], [], [], []
        for i, x in enumerate(xs_all):
            group = [r for r in rows if r.get(plot.x) == _axis_value(x) and r.get("status") in ("success", "failed")
                     and (plot.lines is None or r.get(plot.lines) == _axis_value(line_value))]
            if not group:
                continue
            if plot.y == "success":
                iv = wilson(sum(1 for r in group if r.get("success")), len(group))
            else:
                iv = bootstrap_mean([_number(r.get(plot.y)) for r in group])
            if math.isnan(iv.estimate):
                continue
            xs.append(x if numeric_x else i)
            est.append(iv.estimate)
            low.append(iv.low if math.isfinite(iv.low) else iv.estimate)
            high.append(iv.high if math.isfinite(iv.high) else iv.estimate)
        if not xs:
            continue
        label = f"{plot.lines} = {line_value}" if plot.lines else None
        (line,) = ax.plot(xs, est, marker="o", label=label)
        ax.fill_between(xs, low, high, color=line.get_color(), alpha=0.2, linewidth=0)
    if not numeric_x:
        ax.set_xticks(range(len(xs_all)), [str(v) for v in xs_all])
    ax.set_xlabel(plot.x)
    ax.set_ylabel("success rate" if plot.y == "success" else plot.y)
    n_seeds = len(sweep.seeds)
    ax.set_title(f"{sweep.name}: {'success rate' if plot.y == 'success' else plot.y}\n"
                 f"mean and 95 % interval over {n_seeds} seeds per point", fontsize=10)
    if plot.lines:
        ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def plot_file_name(plot: PlotSpec) -> str:
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in plot.y)
    return f"{safe}_vs_{plot.x}" + (f"_by_{plot.lines}" if plot.lines else "") + ".png"
