"""radio_validation.png: the BLE model against measured data (`rescuemesh radio-validate`).

Owns: the matplotlib figure (Agg, no screen). Must not know: how the figures were computed
(radio/validation.py does), the CLI.
Three panels: the Kolakowski flat's held-out local means, measured against predicted, coloured by
walls crossed (the diagonal and +-3 dB); the residuals' correlation against separation beside the
model's shadow field; the Danis office's place means against distance with the model's slope and
the data's own fit.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rescuemesh.radio.shadowing import ShadowField  # noqa: E402
from rescuemesh.radio.validation import DanisResult, KolakowskiResult  # noqa: E402

_WALL_COLOURS = ("tab:green", "tab:blue", "tab:orange", "tab:red", "tab:purple")


def field_correlation(decorrelation_m: float, separations: np.ndarray, samples: int = 4000) -> np.ndarray:
    """Correlation of the model's unit shadow field F at each separation (m), estimated on a fixed
    set of random place pairs (seeded: the same curve every time)."""
    rng = np.random.default_rng(1)
    field = ShadowField(7, 1.0, decorrelation_m)
    base = rng.uniform(0, 50, size=(samples, 2))
    angle = rng.uniform(0, 2 * np.pi, size=samples)
    f0 = field.unit_many(base)
    out = []
    for d in separations:
        other = base + d * np.c_[np.cos(angle), np.sin(angle)]
        out.append(float(np.mean(f0 * field.unit_many(other))))
    return np.array(out)


def write_validation_plot(out_path: Path, kolakowski: KolakowskiResult | None, danis: DanisResult | None,
                          *, decorrelation_m: float, exponent: float) -> Path:
    """Draw the panels for the results given (None: that data set was not run); write a PNG."""
    panels = (["k_scatter", "k_corr"] if kolakowski is not None else []) + (["danis"] if danis is not None else [])
    if not panels:
        raise ValueError("nothing to plot: no data set was validated")
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.6), squeeze=False)
    for ax, panel in zip(axes[0], panels):
        if panel == "k_scatter":
            s = kolakowski.scatter
            for w in sorted(set(s["walls"].tolist())):
                m = s["walls"] == w
                row = next(r for r in kolakowski.rows if r.walls == w)
                ax.scatter(s["predicted"][m], s["measured"][m], s=9, alpha=0.6, color=_WALL_COLOURS[w % 5],
                           label=f"{w} wall{'s' if w != 1 else ''}: mean {row.mean_db:+.1f}, RMS {row.rms_db:.1f} dB")
            lo = float(min(s["predicted"].min(), s["measured"].min())) - 2
            hi = float(max(s["predicted"].max(), s["measured"].max())) + 2
            ax.plot([lo, hi], [lo, hi], "k-", lw=1)
            ax.fill_between([lo, hi], [lo - 3, hi - 3], [lo + 3, hi + 3], color="0.85", zorder=0, label="+-3 dB")
            ax.set_xlabel("predicted local mean (dBm)")
            ax.set_ylabel("measured local mean (dBm)")
            ax.set_title("Kolakowski flat, held-out half (0.5 m cells)", fontsize=10)
            ax.legend(fontsize=7, loc="upper left")
        elif panel == "k_corr":
            d = np.array([c[0] for c in kolakowski.correlation])
            r = np.array([c[1] for c in kolakowski.correlation])
            ax.plot(d, r, "o", color="tab:blue", label="data: residuals' local means")
            xs = np.linspace(0, d.max(), 60)
            ax.plot(xs, np.exp(-xs / kolakowski.decorrelation_fit_m), "--", color="tab:blue",
                    label=f"fit exp(-d / {kolakowski.decorrelation_fit_m:.2f} m)")
            ax.plot(xs, field_correlation(decorrelation_m, xs), "-", color="tab:red",
                    label=f"model's shadow field ({decorrelation_m:g} m lattice)")
            ax.axhline(0, color="0.5", lw=0.8)
            ax.set_xlabel("separation (m)")
            ax.set_ylabel("correlation")
            ax.set_title("shadowing: correlation against separation", fontsize=10)
            ax.legend(fontsize=7)
        else:
            s = danis.scatter
            ax.scatter(s["distance"], s["measured"], s=6, alpha=0.35, color="0.4", label="place means (offsets removed)")
            xs = np.linspace(max(0.5, s["distance"].min()), s["distance"].max(), 60)
            centre = np.median(s["distance"])
            level = float(np.median(s["measured"][np.abs(s["distance"] - centre) < 1.0]))
            ax.plot(xs, level - 10 * exponent * np.log10(xs / centre), "r-", label=f"model slope n = {exponent:g}")
            ax.plot(xs, level - 10 * danis.exponent_fit * np.log10(xs / centre), "b--",
                    label=f"data's fit n = {danis.exponent_fit:.2f} "
                          f"({danis.exponent_ci[0]:.2f}..{danis.exponent_ci[1]:.2f})")
            ax.set_xscale("log")
            ax.set_xlabel("distance (m)")
            ax.set_ylabel("RSSI (dBm)")
            ax.set_title("Danis open-plan office (line of sight)", fontsize=10)
            ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    out_path = Path(out_path)
    fig.savefig(out_path, dpi=110)
    plt.close(fig)
    return out_path
