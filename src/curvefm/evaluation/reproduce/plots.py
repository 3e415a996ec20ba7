"""PNG figures of the reproduction (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

from curvefm.errors import InvalidInput
from curvefm.evaluation.metrics import CURVE_RADII
from curvefm.evaluation.reproduce.accuracy import VARIANTS

if TYPE_CHECKING:
    from matplotlib.axes import Axes

LABELS = {v.key: v.label for v in VARIANTS}
STYLES = {
    "curves-traced": "-",
    "curves-exact": "--",
    "combined-traced": "-",
    "obcs12-wks": (0, (1, 3)),
    "obcs12": ":",
    "no17": "-.",
    "no17-curves": (0, (5, 1, 1, 1)),
}
COLOURS = {
    "curves-traced": "C0",
    "curves-exact": "C9",
    "combined-traced": "C4",
    "obcs12-wks": "C7",
    "obcs12": "C3",
    "no17": "C1",
    "no17-curves": "C2",
}
SOLVERS = {
    "ours": "ours (exact per column)",
    "cg": "conjugate gradients (paper, Alg. 2)",
    "quasi_newton": "quasi-Newton (L-BFGS)",
}


def require_matplotlib() -> None:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise InvalidInput("plots need matplotlib: pip install 'curvefm[reproduce]'") from None


def _pyplot() -> ModuleType:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_accuracy(dataset: str, title: str, summary: dict[str, Any], path: Path) -> Path:
    """2 x 2 panels: cumulative curves of ours by curve count, all methods at one count, and the mean
    error against the number of curves, by geodesic diameter and by sqrt(area)."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    counts = sorted({int(c) for variant in summary.values() for c in variant})
    shown = 10 if 10 in counts else counts[-1]
    ax = axes[0, 0]
    for i, count in enumerate(counts):
        colour = plt.cm.viridis(i / max(len(counts) - 1, 1))
        for key in ("curves-traced", "curves-exact"):
            if str(count) in summary.get(key, {}):
                label = f"{count} curve{'s' if count > 1 else ''}" + (", exact" if key == "curves-exact" else "")
                ax.plot(CURVE_RADII, summary[key][str(count)]["curve"], STYLES[key], color=colour, label=label)
    has_exact = "curves-exact" in summary
    _cumulative_axes(ax, "Curves (ours): traced (solid) vs exact (dashed)" if has_exact else "Curves (ours), traced")
    ax = axes[0, 1]
    for key, by_count in summary.items():
        if str(shown) in by_count:
            ax.plot(
                CURVE_RADII, by_count[str(shown)]["curve"], linestyle=STYLES[key], color=COLOURS[key], label=LABELS[key]
            )
    _cumulative_axes(ax, f"All methods, {shown} curves")
    for ax, field, unit in ((axes[1, 0], "mean", "geodesic diameter"), (axes[1, 1], "mean_area", "sqrt(area)")):
        for key, by_count in summary.items():
            xs = sorted(int(c) for c in by_count)
            ax.plot(
                xs,
                [by_count[str(c)][field] for c in xs],
                marker="o",
                linestyle=STYLES[key],
                color=COLOURS[key],
                label=LABELS[key],
            )
        ax.set_xscale("log")
        ax.set_xticks(counts, [str(c) for c in counts])
        ax.set_yscale("log")
        ax.set_xlabel("number of curves (landmarks: their 2 endpoints each)")
        ax.set_ylabel(f"mean geodesic error / {unit}")
        ax.set_title(f"Mean error, normalised by {unit}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _cumulative_axes(ax: Axes, title: str) -> None:
    ax.set_xlim(0, CURVE_RADII[-1])
    ax.set_ylim(0, 1)
    ax.set_xlabel("geodesic error / geodesic diameter of the target")
    ax.set_ylabel("fraction of correspondences within the error")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")


def plot_timing(timing: dict[str, Any], path: Path) -> Path:
    """1 x 3 panels: update time against curve count and against k (log scale), and accuracy against k."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    for ax, rows, x, xlabel in (
        (axes[0], timing["by_count"], "curves", "number of curves (k = 120)"),
        (axes[1], timing["by_k"], "k", "basis size k (10 curves)"),
    ):
        xs = [r[x] for r in rows]
        for solver, label in SOLVERS.items():
            ax.plot(xs, [r[solver]["ms"] for r in rows], marker="o", label=label)
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("time per update, both maps [ms]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title("Update time after adding the n-th curve")
    axes[1].set_title("Update time against basis size")
    ax = axes[2]
    ks = [r["k"] for r in timing["by_k"]]
    ax.plot(ks, [r["mean"] for r in timing["by_k"]], marker="o", color="C0", label="by geodesic diameter")
    ax.set_xlabel("basis size k (10 traced curves)")
    ax.set_ylabel("mean geodesic error / geodesic diameter", color="C0")
    twin = ax.twinx()
    twin.plot(
        ks, [r["mean_area"] for r in timing["by_k"]], marker="s", color="C1", linestyle="--", label="by sqrt(area)"
    )
    twin.set_ylabel("mean geodesic error / sqrt(area)", color="C1")
    handles = ax.get_legend_handles_labels()[0] + twin.get_legend_handles_labels()[0]
    ax.legend(handles, [h.get_label() for h in handles], fontsize=8)
    ax.set_title("Accuracy against basis size (ours)")
    ax.grid(True, alpha=0.3)
    fig.suptitle(f"Solver timing and basis size, {timing['pair']}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
