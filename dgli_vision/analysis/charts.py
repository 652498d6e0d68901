"""The reports' charts, drawn with Matplotlib: the confusion matrix, distance heatmaps,
state timelines and the risk-coverage curve.

Each ``*_figure`` function returns a Matplotlib :class:`~matplotlib.figure.Figure` (no
pyplot, no global state: the Agg canvas renders it); :func:`figure_bgr` turns it into the
BGR array the report writers save as PNG, :func:`figure_svg` into SVG text for the HTML
pages. Matplotlib is imported here only when a chart is drawn.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "chart_files",
    "confusion_figure",
    "figure_bgr",
    "figure_svg",
    "heatmap_figure",
    "outcomes_figure",
    "risk_coverage_figure",
    "timeline_figure",
]

#: Pixels per inch of the PNG pictures.
DPI = 100

_RC = {
    "font.size": 10,
    "axes.titlesize": 11,
    "svg.fonttype": "none",  # text stays text in the SVG: smaller, and searchable
    "svg.hashsalt": "dgli",  # the same SVG for the same chart
    "image.cmap": "viridis",
}


def _figure(width_in: float, height_in: float) -> Any:
    """A new constrained-layout figure on an Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _style() -> Any:
    import matplotlib

    return matplotlib.rc_context(_RC)


def figure_bgr(fig: Any) -> NDArray[np.uint8]:
    """The figure drawn at :data:`DPI` as a BGR image (uint8, shape (h, w, 3))."""
    with _style():
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
    return np.ascontiguousarray(rgba[:, :, 2::-1])


def figure_svg(fig: Any) -> str:
    """The figure as SVG text (no date in it: the same chart gives the same file)."""
    buf = io.StringIO()
    with _style():
        fig.savefig(buf, format="svg", metadata={"Date": None})
    return buf.getvalue()


def _freeze_layout(fig: Any) -> None:
    """Keep the positions the last draw's constrained layout gave, and lay out no more.

    Matplotlib lays a constrained-layout figure out on every draw, and ``savefig`` draws
    such a figure twice (a layout pass, then the drawing). Once drawn, the positions are
    final; later drawings (the SVG after the PNG) reuse them.
    """
    fig.set_layout_engine(None)  # not "none": savefig would still lay out a placeholder


def chart_files(stem: str, fig: Any) -> dict[str, Any]:
    """``{stem.png: BGR image, stem.svg: SVG text}`` of a figure: the HTML pages show the
    SVG and link the PNG.

    The figure is laid out once, for the PNG; the SVG reuses that layout (the figure
    keeps it afterwards).
    """
    png = figure_bgr(fig)
    _freeze_layout(fig)
    return {f"{stem}.png": png, f"{stem}.svg": figure_svg(fig)}


def _group_runs(labels: Sequence[str]) -> list[tuple[int, int, str]]:
    """``(start, end, label)`` of every run of equal consecutive labels."""
    runs: list[tuple[int, int, str]] = []
    for k, lab in enumerate(labels):
        if runs and runs[-1][2] == lab:
            runs[-1] = (runs[-1][0], k + 1, lab)
        else:
            runs.append((k, k + 1, lab))
    return runs


def confusion_figure(
    confusion: NDArray,
    labels: Sequence[str],
    *,
    names: dict[str, str] | None = None,
    title: str = "",
) -> Any:
    """Two confusion-matrix panels, counts and row-normalised, one above the other.

    Parameters
    ----------
    confusion : array, shape (k, k + 1)
        Rows true class, columns predicted class, the last column "none" (not read or
        "cannot tell").
    labels : sequence of str
        The k class ids.
    names : dict, optional, keyword-only
        Class id -> name, shown on the row axis.
    title : str, keyword-only
    """
    conf = np.asarray(confusion, dtype=float)
    k = len(labels)
    cols = [*labels, "none"]
    rows_sum = conf.sum(axis=1, keepdims=True)
    norm = np.divide(conf, rows_sum, out=np.zeros_like(conf), where=rows_sum > 0)
    row_names = [f"{lab} {names.get(lab, '')}".strip() if names else lab for lab in labels]
    cell = 0.42  # inches a cell
    width = 3.4 + cell * (k + 1) + 1.4
    height = 2 * (1.3 + cell * max(k, 1))
    with _style():
        fig = _figure(max(width, 5.0), height)
        axes = fig.subplots(2, 1)
        panels = ((conf, "counts", "{:.0f}", "pairs"),
                  (norm, "row-normalised", "{:.2f}", "share of the true class"))
        for ax, (values, sub, fmt, unit) in zip(axes, panels):
            vmax = values.max() if values.max() > 0 else 1.0
            im = ax.imshow(values, vmin=0, vmax=vmax, aspect="auto")
            for r in range(k):
                for c in range(k + 1):
                    if values[r, c] > 0:
                        ink = "black" if values[r, c] > 0.6 * vmax else "white"
                        ax.text(c, r, fmt.format(values[r, c]), ha="center", va="center",
                                color=ink, fontsize=8)
            ax.set_xticks(range(k + 1), cols, rotation=90 if k > 12 else 0)
            ax.set_yticks(range(k), row_names)
            ax.set_xlabel("predicted class")
            ax.set_ylabel("true class")
            ax.set_title(f"{title} ({sub})" if title else sub)
            fig.colorbar(im, ax=ax, label=unit, shrink=0.9)
    return fig


def heatmap_figure(
    matrix: NDArray[np.float64],
    *,
    title: str,
    groups: Sequence[str] | None = None,
    value_label: str = "",
    ticks: Sequence[object] | None = None,
    tick_label: str = "frame",
    group_label: str = "group",
    missing: str = "no value",
) -> Any:
    """A matrix as a heatmap with a colour bar; NaN is grey, and said so under the
    colour bar (``missing``) when there is any.

    Parameters
    ----------
    matrix : ndarray, shape (n, k)
    title : str, keyword-only
    groups : sequence of str, optional, keyword-only
        Label of every row (and column, for square matrices), consecutive runs forming
        groups: white separators, and the group's label as the tick at its middle.
    value_label : str, keyword-only
        What the colour means (the colour bar's label).
    ticks : sequence, optional, keyword-only
        What every column is (e.g. its frame number): about ten of them are ticks of the
        horizontal axis, named ``tick_label``.
    tick_label : str, keyword-only
    group_label : str, keyword-only
        What the groups are (the axes' label: ``"true class"``).
    missing : str, keyword-only
        What a grey cell means (``"no distance: fewer than 3 coordinates measured in
        both"``).
    """
    import matplotlib

    m = np.asarray(matrix, dtype=np.float64)
    n_rows, n_cols = m.shape
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="#a0a0a0")
    with _style():
        fig = _figure(8.0, 7.0 if n_rows == n_cols else 6.0)
        ax = fig.subplots()
        im = ax.imshow(np.ma.masked_invalid(m), cmap=cmap, aspect="auto",
                       interpolation="nearest")
        ax.set_title(title)
        fig.colorbar(im, ax=ax, label=value_label)
        if np.isnan(m).any():  # what a grey cell is, under the title
            grey = int(np.isnan(m).sum())
            ax.text(0.5, 1.015, f"grey ({grey} of {m.size} cells): {missing}",
                    transform=ax.transAxes, ha="center", va="bottom", fontsize=8,
                    color="#555555")
            ax.set_title(title, pad=16)
        ax.set_xticks([])
        ax.set_yticks([])
        if groups is not None:
            runs = _group_runs(list(groups))
            for s, _e, _lab in runs[1:]:
                ax.axhline(s - 0.5, color="white", linewidth=0.8)
                if n_rows == n_cols:
                    ax.axvline(s - 0.5, color="white", linewidth=0.8)
            centres = [(s + e - 1) / 2 for s, e, _ in runs]
            names = [lab for _, _, lab in runs]
            step = max(1, int(np.ceil(len(runs) / 30)))
            ax.set_yticks(centres[::step], names[::step])
            ax.set_ylabel(f"{group_label} (each sample a row, in order)")
            if n_rows == n_cols and ticks is None:
                ax.set_xticks(centres[::step], names[::step], rotation=90)
                ax.set_xlabel(f"{group_label} (each sample a column)")
        if ticks is not None:
            values = list(ticks)
            step = max(1, int(np.ceil(len(values) / 10)))
            ax.set_xticks(range(0, len(values), step), [str(v) for v in values[::step]])
            ax.set_xlabel(tick_label)
    return fig


def timeline_figure(
    classes: Sequence[str],
    smoothed: Sequence[str],
    raw: Sequence[str | None],
    *,
    truth: Sequence[str] | None = None,
    names: dict[str, str] | None = None,
    title: str = "",
) -> Any:
    """A state timeline: frames across, states down; the true state (when given) a pale
    green band, each frame's own answer a dot (a red ring where it gave none), the
    smoothed state a line; a legend says which is which.

    Parameters
    ----------
    classes : sequence of str
        The rows, top to bottom (class ids).
    smoothed : sequence of str
        Smoothed class of every frame.
    raw : sequence of str or None
        Each frame's own class (None: no answer).
    truth : sequence of str, optional, keyword-only
    names : dict, optional, keyword-only
        Class id -> name for the row labels.
    title : str, keyword-only
    """
    from matplotlib.ticker import MaxNLocator

    n = len(smoothed)
    row_of = {c: k for k, c in enumerate(classes)}
    row_names = [f"{c} {names.get(c, '')}".strip() if names else c for c in classes]
    frames = np.arange(n)
    with _style():
        fig = _figure(float(np.clip(4 + 0.04 * n, 9, 16)), 2.2 + 0.28 * len(classes))
        ax = fig.subplots()
        if truth is not None:
            rows = [(t, row_of[c]) for t, c in enumerate(truth) if c in row_of]
            if rows:
                t, r = np.array(rows).T
                ax.bar(t, 0.8, bottom=r - 0.4, width=1.0, color="#c8e6c8", linewidth=0,
                       label="true state")
        keep = [t for t, c in enumerate(smoothed) if c in row_of]
        ax.plot(frames[keep], [row_of[smoothed[t]] for t in keep], color="#1f77b4",
                linewidth=2, drawstyle="steps-mid", label="smoothed state")
        answered = [t for t, c in enumerate(raw) if c is not None and c in row_of]
        ax.plot(frames[answered], [row_of[raw[t]] for t in answered], "o", color="black",
                markersize=3.5, label="frame's own answer")
        silent = [t for t, c in enumerate(raw) if c is None and smoothed[t] in row_of]
        if silent:
            ax.plot(frames[silent], [row_of[smoothed[t]] for t in silent], "o",
                    markerfacecolor="none", markeredgecolor="#c0392b", markersize=6,
                    label="no answer (cannot tell, not read)")
        ax.set_yticks(range(len(classes)), row_names)
        ax.set_ylim(len(classes) - 0.5, -0.5)
        ax.set_xlim(-0.5, max(n, 1) - 0.5)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("frame")
        ax.set_ylabel("state")
        ax.grid(axis="y", color="#eeeeee")
        if title:
            ax.set_title(title)
        fig.legend(loc="outside lower center", ncol=2, frameon=False)
    return fig


def risk_coverage_figure(
    points: Sequence[tuple[float, float, float]],
    ranked: Sequence[tuple[float, float, bool]] | None = None,
    read: int | None = None,
) -> Any:
    """The risk-coverage curve: for each confidence threshold, the share of the pairs
    read still answered (across) and the share of those answers that are right (up);
    with ``ranked``, also the answers added one at a time, most confident first (ties
    by their margin to the runner-up), so that a few distinct confidences still give
    a curve, not two points.

    Parameters
    ----------
    points : sequence of (threshold, coverage, accuracy)
        As :func:`dgli_vision.analysis.html_report.risk_coverage` gives them.
    ranked : sequence of (confidence, margin, right), optional
        Every answer given (its confidence, the runner-up's distance less its own, and
        whether it is right).
    read : int, optional
        The pairs read (the coverage's denominator); needed with ``ranked``.
    """
    pts = sorted(points, key=lambda p: p[1])
    with _style():
        fig = _figure(6.4, 4.2)
        ax = fig.subplots()
        low = 1.0
        if ranked and read:
            order = sorted(ranked, key=lambda r: (-r[0], -r[1]))
            right = np.cumsum([bool(r[2]) for r in order])
            k = np.arange(1, len(order) + 1)
            ax.plot(k / read, right / k, "-", color="#9ecae1", linewidth=1.5, marker=".",
                    markersize=5, label="answers one at a time, most confident first")
            low = min(low, float((right / k).min()))
        if pts:
            cov = [p[1] for p in pts]
            acc = [p[2] for p in pts]
            ax.plot(cov, acc, "o", color="#1f77b4", markersize=6,
                    label="answers at or above a confidence threshold")
            low = min(low, *acc)
            shown = pts if len(pts) <= 6 else [pts[int(i)] for i in
                                               np.linspace(0, len(pts) - 1, 6).round()]
            for t, c, a in shown:
                ax.annotate(f"{t:.2f}", (c, a), textcoords="offset points",
                            xytext=(0, -14), ha="center", fontsize=8)
            ax.set_ylim(max(0.0, low - 0.1) if low < 1 else 0.8, 1.02)
            ax.legend(loc="lower left", fontsize=8, title="label: the threshold",
                      title_fontsize=8)
        else:
            ax.text(0.5, 0.5, "no answers to draw", ha="center", va="center",
                    transform=ax.transAxes)
            ax.set_ylim(0, 1.02)
        ax.set_xlim(0, 1.02)
        ax.set_xlabel("coverage: share of the pairs read that get a class")
        ax.set_ylabel("share of the answers that are right")
        ax.set_title("Risk and coverage")
        ax.grid(color="#e6e6e6")
    return fig


def outcomes_figure(rows: Sequence[tuple[str, int, int, int]]) -> Any:
    """Right, "cannot tell" and wrong under each condition, as stacked horizontal bars of
    shares of its pairs.

    Parameters
    ----------
    rows : sequence of (condition, right, cannot_tell, wrong)
    """
    names = [r[0] for r in rows]
    counts = np.array([r[1:] for r in rows], dtype=float).reshape(len(rows), 3)
    totals = counts.sum(axis=1, keepdims=True)
    shares = np.divide(counts, totals, out=np.zeros_like(counts), where=totals > 0)
    with _style():
        fig = _figure(8.0, 1.6 + 0.32 * max(len(rows), 1))
        ax = fig.subplots()
        left = np.zeros(len(rows))
        for k, (label, colour) in enumerate((("right", "#2e8b57"),
                                              ("cannot tell", "#f0ad4e"),
                                              ("wrong", "#c0392b"))):
            ax.barh(range(len(rows)), shares[:, k], left=left, color=colour, label=label)
            left += shares[:, k]
        ax.set_yticks(range(len(rows)), names)
        ax.set_ylim(len(rows) - 0.5, -0.5)
        ax.set_xlim(0, 1)
        ax.set_xlabel("share of the condition's pairs")
        ax.set_title("Answers under each condition")
        fig.legend(loc="outside lower center", ncol=3, frameon=False)
    return fig
